"""Optimal control with friction: costs whose least value is not 0, with their exact optima.

A block, p' = v, v' = u − μ·Sgn(v), steered by a control u (paper Example 7.1's J(x) + λ·I
with a cost that the solutions cannot bring to 0; solved by the method of multipliers,
:mod:`qdframe.descent.multipliers`):

* ``least-effort-block``: from rest at 0 to rest at D = 1 in T = 2, μ = 0.5, cost ∫u² dt.
  While v > 0 the friction is the constant −μ, so u* = μ + w, w the double integrator's
  least-energy control: u* = 2 − 1.5·t, J* = 12D²/T³ + μ²T = 2.
* ``least-effort-bounded``: the same with |u| ≤ 1.5 (``control_bounds``): the bound binds on
  [0, 1/2], then u* = 3/2 − (16/9)(t − 1/2); J* = 37/18.
* ``lq-terminal``: the double integrator from rest, cost ∫u² dt + 50·((p(1) − 2)² + v(1)²)
  (``terminal_cost``), no end values: J* = 850/23.

The exact optima (Pontryagin's principle; the problems are convex, so its conditions are
sufficient) are in :mod:`.optimal_references`, each checked there against an integration of
its control.
"""

from __future__ import annotations

import numpy as np

from ..sets import SetModel, Sgn
from . import optimal_references as references


class _Optimal(SetModel):
    """A model with an exact optimum `reference()` for its default data."""

    def reference(self) -> references.OptimalReference:
        raise NotImplementedError

    def _default(self) -> bool:
        return (np.array_equal(self.x0, self.default_x0) and np.array_equal(self.end_values, self.default_end_values)
                and self.T == self.default_T)

    def exact_solution(self, t: np.ndarray) -> np.ndarray | None:
        return self.reference().states(np.asarray(t, dtype=float)) if self._default() else None


class LeastEffortBlock(_Optimal):
    """A Coulomb block moved from rest at 0 to rest at 1 in T = 2 with the least ∫u² dt: J* = 2."""

    name = "least-effort-block"
    description = "Least effort ∫u² to move a Coulomb block (μ = 0.5) from rest at 0 to rest at 1 in T = 2: J* = 2"
    state_names = "p v"
    control_names = "u"
    default_x0 = (0.0, 0.0)
    default_xT = {"p": 1.0, "v": 0.0}
    default_T = 2.0
    friction = 0.5
    exact_cost = 2.0

    def sets(self, p, v, u):
        return {p: v, v: u - self.friction * Sgn(v)}

    def running_cost(self, p, v, u):
        return u**2

    def reference(self) -> references.OptimalReference:
        return references.least_effort(1.0, self.default_T, self.friction)


class LeastEffortBounded(LeastEffortBlock):
    """The least-effort move with |u| ≤ 1.5, which binds on [0, 1/2]: J* = 37/18."""

    name = "least-effort-bounded"
    description = "The least-effort block move with |u| ≤ 1.5 (binds on [0, 0.5]): J* = 37/18"
    control_bounds = {"u": (-1.5, 1.5)}
    exact_cost = 37 / 18

    def reference(self) -> references.OptimalReference:
        return references.least_effort_bounded(1.0, self.default_T, self.friction, 1.5)


class LQTerminal(_Optimal):
    """The double integrator from rest with ∫u² dt + 50·((p(1) − 2)² + v(1)²): J* = 850/23."""

    name = "lq-terminal"
    description = "Double integrator from rest, ∫u² + 50((p(1) − 2)² + v(1)²), no end values: J* = 850/23"
    state_names = "p v"
    control_names = "u"
    default_x0 = (0.0, 0.0)
    default_T = 1.0
    exact_cost = 850 / 23

    def sets(self, p, v, u):
        return {p: v, v: u}

    def running_cost(self, p, v, u):
        return u**2

    def terminal_cost(self, p, v):
        return 50 * ((p - 2) ** 2 + v**2)

    def reference(self) -> references.OptimalReference:
        return references.lq_terminal(self.default_T, 50.0, (2.0, 0.0))
