"""The problems of `qdframe bench ocp`, each stated once for every tool that runs it.

An :class:`OcpProblem` is an optimal-control problem with at most one Coulomb contact:

    min ∫_0^T c(x, u) dt + M(x(T))   s.t.   x' ∈ g(x, u) − a·e_j·Sgn(x_j),   x(0) = x0,
    x_i(T) = xT_i (i in `end`),   lo ≤ u ≤ hi,

g, c and M written with arithmetic alone, so that one formula serves NumPy (the replay that
judges every run, :mod:`.two_modes`) and CasADi (nosnoc's statement, :mod:`.nosnoc_ocp`);
qdframe states it as its model (`model`). J* is exact where known (`best`), else the least
cost of the runs that met the conditions (the report says which).

- ``least-effort-block``, ``least-effort-bounded``, ``lq-terminal``: qdframe's models of
  :mod:`qdframe.models.optimal_control`, with their exact optima.
- ``nosnoc-motor``: nosnoc's own example ``examples/motor_with_friction/motor_with_friction_ocp.py``
  (nosnoc_py): a linear motor (slide x1, v1, load x2, v2, current I) with guide friction
  F_R = 2.1 N on the slide, voltage |u| ≤ 5, ∫u² dt from rest to x1 = x2 = 0.01 at rest
  with I = 0, T = 0.08.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..model import InclusionModel
from ..models.optimal_control import LeastEffortBlock, LeastEffortBounded, LQTerminal
from ..sets import SetModel, Sgn


@dataclass(frozen=True)
class OcpProblem:
    """One problem (module docstring); `field(x, u)` returns g as a list of n formulas."""

    name: str
    model: Callable[[], InclusionModel]
    field: Callable[[object, object], list]
    running: Callable[[object, object], object]
    x0: tuple[float, ...]
    T: float
    end: dict[int, float] = field(default_factory=dict)
    terminal: Callable[[object], object] | None = None
    friction: tuple[int, float] | None = None  # (j, a): −a·Sgn(x_j) on x_j'
    u_bounds: tuple[float, float] | None = None
    best: float | None = None  # J*, where it is known exactly
    source: str = ""  # where J* comes from

    @property
    def n(self) -> int:
        return len(self.x0)

    def numeric_field(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.array(self.field(x, u), dtype=float)


def _block(x, u) -> list:
    return [x[1], u[0]]


def _effort(x, u):
    return u[0] ** 2


# nosnoc's motor (examples/motor_with_friction/motor_with_friction_ocp.py)
M1, M2, SPRING, RESISTANCE, INDUCTANCE, FORCE_CONSTANT, BACK_EMF, GUIDE_FRICTION = 1.03, 0.56, 2.4e3, 2.0, 2e-3, 12.0, 12.0, 2.1
MOTOR_TARGET = (0.01, 0.0, 0.01, 0.0, 0.0)


def _motor(x, u) -> list:
    x1, v1, x2, v2, current = x[0], x[1], x[2], x[3], x[4]
    return [v1, (-SPRING * x1 + SPRING * x2 + FORCE_CONSTANT * current) / M1, v2, (SPRING * x1 - SPRING * x2) / M2,
            (-BACK_EMF * v1 - RESISTANCE * current + u[0]) / INDUCTANCE]


class NosnocMotor(SetModel):
    """nosnoc's motor with guide friction, as its example states it (module docstring)."""

    name = "nosnoc-motor"
    description = "nosnoc's linear motor with guide friction: least ∫u², |u| ≤ 5, T = 0.08"
    state_names = "x1 v1 x2 v2 I"
    control_names = "u"
    default_x0 = (0.0, 0.0, 0.0, 0.0, 0.0)
    default_xT = dict(zip(("x1", "v1", "x2", "v2", "I"), MOTOR_TARGET))
    default_T = 0.08
    control_bounds = {"u": (-5.0, 5.0)}

    def sets(self, x1, v1, x2, v2, I, u):
        g = _motor((x1, v1, x2, v2, I), (u,))
        return {x1: g[0], v1: g[1] - GUIDE_FRICTION / M1 * Sgn(v1), x2: g[2], v2: g[3], I: g[4]}

    def running_cost(self, x1, v1, x2, v2, I, u):
        return u**2


PROBLEMS: dict[str, OcpProblem] = {problem.name: problem for problem in (
    OcpProblem(LeastEffortBlock.name, LeastEffortBlock, _block, _effort, (0.0, 0.0), 2.0, {0: 1.0, 1: 0.0},
               friction=(1, LeastEffortBlock.friction), best=LeastEffortBlock.exact_cost, source="exact"),
    OcpProblem(LeastEffortBounded.name, LeastEffortBounded, _block, _effort, (0.0, 0.0), 2.0, {0: 1.0, 1: 0.0},
               friction=(1, LeastEffortBounded.friction), u_bounds=(-1.5, 1.5), best=LeastEffortBounded.exact_cost,
               source="exact"),
    OcpProblem(LQTerminal.name, LQTerminal, _block, _effort, (0.0, 0.0), 1.0,
               terminal=lambda x: 50 * ((x[0] - 2) ** 2 + x[1] ** 2), best=LQTerminal.exact_cost, source="exact"),
    OcpProblem("nosnoc-motor", NosnocMotor, _motor, _effort, NosnocMotor.default_x0, NosnocMotor.default_T,
               dict(enumerate(MOTOR_TARGET)), friction=(1, GUIDE_FRICTION / M1), u_bounds=(-5.0, 5.0),
               source="the least replayed cost of the runs that met the conditions"),
)}
