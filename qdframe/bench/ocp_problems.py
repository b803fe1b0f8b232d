"""The problems of `qdframe bench run --suite ocp`, each stated once for every tool that runs it.

An :class:`OcpProblem` is an optimal-control problem with at most one Coulomb contact:

    min ∫_0^T c(x, u) dt + M(x(T))   s.t.   x' ∈ g(x, u) − b(x)·Sgn(x_j),   x(0) = x0,
    x_i(T) = xT_i (i in `end`),   lo ≤ u ≤ hi,   lo_i ≤ x_i ≤ hi_i (i in `x_bounds`),

b = a·e_j for a force on x_j' alone (a friction on a velocity); g, b, c and M written with
arithmetic (and :func:`_cos`, :func:`_sin`), so that one formula serves NumPy (the replay that
judges every run, :mod:`.two_modes`) and CasADi (nosnoc's statement, :mod:`.nosnoc_ocp`);
qdframe states it as its model (`model`). J* is exact where known (`best`), else the least
cost of the runs that met the conditions (the report says which).

- ``least-effort-block``, ``least-effort-bounded``, ``lq-terminal``: qdframe's models of
  :mod:`qdframe.models.optimal_control`, with their exact optima.
- ``nosnoc-cart-pole``: nosnoc's ``examples/cart_pole_with_friction/cart_pole_with_friction.py``:
  the swing-up of a link on a cart with friction 2 on the cart (its force moves both
  accelerations through M(θ)⁻¹), tracking cost and terminal cost, |u| ≤ 30, |px| ≤ 5, T = 5.
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
from ..sets import Modes, SetModel, Sgn


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
    friction: tuple[int, float | Callable[[object], list]] | None = None  # (j, a): −a·Sgn(x_j) on x_j', or (j, b):
    # −b(x)·Sgn(x_j) on every state, b(x) a list of n formulas (a contact whose force moves several states)
    u_bounds: tuple[float, float] | None = None
    x_bounds: dict[int, tuple[float, float]] = field(default_factory=dict)  # state j: (lo, hi) along the motion
    best: float | None = None  # J*, where it is known exactly
    source: str = ""  # where J* comes from

    @property
    def n(self) -> int:
        return len(self.x0)

    def numeric_field(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.array(self.field(x, u), dtype=float)

    def push(self, x) -> list:
        """b(x) of the contact's term −b(x)·Sgn(x_j), n formulas (a·e_j for a constant a)."""
        j, amplitude = self.friction
        if callable(amplitude):
            return list(amplitude(x))
        return [amplitude if i == j else 0 * x[0] for i in range(self.n)]


def _cos(z):
    """cos of a NumPy value or a CasADi expression (the one formula serves both)."""
    return z.cos() if hasattr(z, "cos") and not isinstance(z, (float, np.floating, np.ndarray)) else np.cos(z)


def _sin(z):
    return z.sin() if hasattr(z, "sin") and not isinstance(z, (float, np.floating, np.ndarray)) else np.sin(z)


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


# nosnoc's cart-pole (examples/cart_pole_with_friction/cart_pole_with_friction.py)
CART, LINK, LENGTH, GRAVITY, CART_FRICTION = 1.0, 0.1, 1.0, 9.81, 2.0


def _cart_pole_accelerations(x, u, friction):
    """M(θ)⁻¹·(u + m2·l·ω²·sin θ − friction, −m2·g·l·sin θ): the cart's and the link's accelerations."""
    theta, omega = x[1], x[3]
    c, s = _cos(theta), _sin(theta)
    first, second = u[0] + LINK * LENGTH * omega**2 * s - friction, -LINK * GRAVITY * LENGTH * s
    det = (CART + LINK) * LINK * LENGTH**2 - (LINK * LENGTH * c) ** 2
    return [(LINK * LENGTH**2 * first - LINK * LENGTH * c * second) / det,
            (-LINK * LENGTH * c * first + (CART + LINK) * second) / det]


def _cart_pole(x, u) -> list:
    return [x[2], x[3], *_cart_pole_accelerations(x, u, 0.0)]


def _cart_pole_push(x) -> list:
    """b(x) of −b(x)·Sgn(v): the friction force F on the cart through M(θ)⁻¹ (the accelerations' change per unit F·Sgn(v))."""
    theta = x[1]
    c = _cos(theta)
    det = (CART + LINK) * LINK * LENGTH**2 - (LINK * LENGTH * c) ** 2
    return [0 * theta, 0 * theta, CART_FRICTION * LINK * LENGTH**2 / det, -CART_FRICTION * LINK * LENGTH * c / det]


def _cart_pole_cost(x, u):
    return 10 * x[0] ** 2 + 100 * (x[1] - np.pi) ** 2 + x[2] ** 2 + x[3] ** 2 + u[0] ** 2


def _cart_pole_terminal(x):
    return 500 * x[0] ** 2 + 100 * (x[1] - np.pi) ** 2 + 10 * x[2] ** 2 + 10 * x[3] ** 2


class NosnocCartPole(SetModel):
    """nosnoc's cart-pole swing-up with friction on the cart, as its example states it: from the
    cart at 1 with the link down, tracking (0, π, 0, 0) with Q = diag(10, 100, 1, 1), R = 1 and
    the terminal Q_T = diag(500, 100, 10, 10), |u| ≤ 30, |px| ≤ 5, T = 5; the friction
    (2 N on the cart) written with :func:`qdframe.sets.Modes`, its modes as nosnoc's."""

    name = "nosnoc-cart-pole"
    description = "nosnoc's cart-pole swing-up with friction 2 on the cart: tracking cost, |u| ≤ 30, |px| ≤ 5, T = 5"
    state_names = "px theta v omega"
    control_names = "u"
    default_x0 = (1.0, 0.0, 0.0, 0.0)
    default_T = 5.0
    control_bounds = {"u": (-30.0, 30.0)}
    state_bounds = {"px": (-5.0, 5.0)}

    def sets(self, px, theta, v, omega, u):
        from sympy import cos, sin

        def accelerations(friction):
            first, second = u + LINK * LENGTH * omega**2 * sin(theta) - friction, -LINK * GRAVITY * LENGTH * sin(theta)
            det = (CART + LINK) * LINK * LENGTH**2 - (LINK * LENGTH * cos(theta)) ** 2
            return ((LINK * LENGTH**2 * first - LINK * LENGTH * cos(theta) * second) / det,
                    (-LINK * LENGTH * cos(theta) * first + (CART + LINK) * second) / det)

        plus, minus = accelerations(CART_FRICTION), accelerations(-CART_FRICTION)
        return Modes(v, positive={px: v, theta: omega, v: plus[0], omega: plus[1]},
                     negative={px: v, theta: omega, v: minus[0], omega: minus[1]})

    def running_cost(self, px, theta, v, omega, u):
        from sympy import pi

        return 10 * px**2 + 100 * (theta - pi) ** 2 + v**2 + omega**2 + u**2

    def terminal_cost(self, px, theta, v, omega):
        from sympy import pi

        return 500 * px**2 + 100 * (theta - pi) ** 2 + 10 * v**2 + 10 * omega**2


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
    OcpProblem("nosnoc-cart-pole", NosnocCartPole, _cart_pole, _cart_pole_cost, NosnocCartPole.default_x0,
               NosnocCartPole.default_T, terminal=_cart_pole_terminal, friction=(2, _cart_pole_push),
               u_bounds=(-30.0, 30.0), x_bounds={0: (-5.0, 5.0)},
               source="the least replayed cost of the runs that met the conditions"),
)}
