"""Friction models as users bring them, written in the set language, with reference motions.

They have no closed form. Each one's reference is its equations written out by hand here
(not compiled from its sets) in the separable form x' ∈ g(x) + B·Sgn(s(x)) and integrated
by the event-driven Filippov integrator (:func:`qdframe.certificates.filippov.integrate`: DOP853, rtol =
atol = 1e-12, stick and slide by the equivalent control): a second, independent reading
of the model against which its solves are judged (``exact_solution``).

=========================  ==================================================================
model                      what it does
=========================  ==================================================================
pivot-friction-pendulum    θ' = ω, ω' ∈ −9.81 sin θ − 0.05 ω − 2 Sgn(ω), released at θ = 1.2,
                           T = 6: swings, reverses twice, sticks at θ ≈ 0.18 (gravity's pull
                           below the pivot's friction)
two-block-chain            a block on a wall spring, a second block on a spring to the first,
                           pulled by a constant force, each with Coulomb friction, T = 6: five
                           stick/slip changes, then both stuck
relay-oscillator           x1' = x2, x2' ∈ −Sgn(x1) from (1, 0), T = 12: crosses x1 = 0 at
                           √2·(1, 3, 5, 7), no sliding
=========================  ==================================================================
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import sympy as sp

from ..certificates.filippov import Fields, FilippovSystem, integrate
from ..sets import SetModel, Sgn

REFERENCE_TOL = 1e-12


class _Referenced(SetModel):
    """A set-language model whose `exact_solution` is its hand-written equations integrated."""

    def equations(self) -> Callable[[float, np.ndarray], Fields]:
        """g, B, s and ∇s of x' ∈ g + B·Sgn(s), written by hand."""
        raise NotImplementedError

    def exact_solution(self, t: np.ndarray) -> np.ndarray | None:
        default = self.T == self.default_T and np.array_equal(self.x0, self.default_x0) and self.end_values.size == 0
        if not default:
            return None
        cache = type(self).__dict__.get("_reference")
        if cache is None:
            system = FilippovSystem(self.equations(), ("sgn",), self.name)
            cache = integrate(system, self.x0, self.T, REFERENCE_TOL, REFERENCE_TOL)
            type(self)._reference = cache  # type: ignore[attr-defined]
        return cache(np.asarray(t, dtype=float))


PENDULUM_GRAVITY, PENDULUM_DAMPING, PENDULUM_FRICTION = 9.81, 0.05, 2.0


class PivotFrictionPendulum(_Referenced):
    """Pendulum with Coulomb friction at the pivot, released from rest at θ = 1.2: swings,
    reverses, sticks (θ' = ω, ω' ∈ −9.81 sin θ − 0.05 ω − 2 Sgn(ω), T = 6)."""

    name = "pivot-friction-pendulum"
    description = "Pendulum θ' = ω, ω' ∈ −9.81·sin θ − 0.05·ω − 2·Sgn(ω) from rest at θ = 1.2: swings, reverses, sticks"
    state_names = "theta omega"
    default_x0 = (1.2, 0.0)
    default_T = 6.0

    def sets(self, theta, omega):
        return {theta: omega,
                omega: -PENDULUM_GRAVITY * sp.sin(theta) - PENDULUM_DAMPING * omega - PENDULUM_FRICTION * Sgn(omega)}

    def equations(self):
        def fields(t: float, x: np.ndarray) -> Fields:
            theta, omega = x
            return Fields(np.array([omega, -PENDULUM_GRAVITY * np.sin(theta) - PENDULUM_DAMPING * omega]),
                          np.array([[0.0], [-PENDULUM_FRICTION]]), np.array([omega]), np.array([[0.0, 1.0]]))
        return fields


CHAIN_WALL, CHAIN_LINK, CHAIN_PULL, CHAIN_FRICTION = 1.0, 3.0, 1.5, (1.0, 0.5)


class TwoBlockChain(_Referenced):
    """Two blocks in series: the first on a spring to a wall, the second on a spring to the
    first and pulled by a constant force, each with Coulomb friction; five stick/slip changes
    in T = 6, then both stuck."""

    name = "two-block-chain"
    description = "Two blocks on springs in series, Coulomb friction on each, the second pulled: 5 stick/slip changes in T = 6"
    state_names = "p1 v1 p2 v2"
    default_x0 = (0.0, 0.0, 0.0, 0.0)
    default_T = 6.0

    def sets(self, p1, v1, p2, v2):
        link = CHAIN_LINK * (p2 - p1)
        mu1, mu2 = CHAIN_FRICTION
        return {p1: v1, v1: -CHAIN_WALL * p1 + link - mu1 * Sgn(v1),
                p2: v2, v2: CHAIN_PULL - link - mu2 * Sgn(v2)}

    def equations(self):
        mu1, mu2 = CHAIN_FRICTION

        def fields(t: float, x: np.ndarray) -> Fields:
            p1, v1, p2, v2 = x
            link = CHAIN_LINK * (p2 - p1)
            return Fields(np.array([v1, -CHAIN_WALL * p1 + link, v2, CHAIN_PULL - link]),
                          np.array([[0.0, 0.0], [-mu1, 0.0], [0.0, 0.0], [0.0, -mu2]]), np.array([v1, v2]),
                          np.array([[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]))
        return fields


class RelayOscillator(_Referenced):
    """The relay oscillator x1' = x2, x2' ∈ −Sgn(x1) from (1, 0): crosses x1 = 0 at
    √2·(1, 3, 5, 7) in T = 12, no sliding."""

    name = "relay-oscillator"
    description = "Relay oscillator x1' = x2, x2' ∈ −Sgn(x1) from (1, 0): crosses x1 = 0 at √2·(1, 3, 5, 7), no sliding"
    state_names = "x1 x2"
    default_x0 = (1.0, 0.0)
    default_T = 12.0
    switch_times = tuple(float(np.sqrt(2.0) * k) for k in (1, 3, 5, 7))

    def sets(self, x1, x2):
        return {x1: x2, x2: -Sgn(x1)}

    def equations(self):
        def fields(t: float, x: np.ndarray) -> Fields:
            return Fields(np.array([x[1], 0.0]), np.array([[0.0], [-1.0]]), np.array([x[0]]), np.array([[1.0, 0.0]]))
        return fields
