"""Peer: scipy.integrate.solve_bvp on the regularized ODE a user would write for each model.

solve_bvp (4th-order Lobatto IIIA collocation, Kierzenka & Shampine 2001) solves smooth
two-point problems y' = f(t, y), bc(y(0), y(T)) = 0. It cannot take a set-valued right
side: Newton's method on its collocation equations needs f and a (finite-difference)
Jacobian, and its residual control assumes a smooth f. So a user facing a Filippov
inclusion with a sign term a·Sgn(s) replaces Sgn by the usual regularization

    sat(s/ε) = clip(s/ε, −1, 1),

which is sign(s) for |s| ≥ ε and linear in between: a Lipschitz f (with a steep slope
a/ε across the layer |s| < ε) whose solutions tend to the Filippov solution as ε → 0.
The price is O(ε) where the exact motion sticks or slides: in a stick phase the
regularized friction balances the load with v = ε·f/μ instead of v = 0, so the position
creeps by ε·f/μ per unit time; in a sliding phase the motion runs at s = O(ε) off the
surface. A smaller ε also makes f stiffer (slope a/ε) and the layer thinner, so the
mesh has to resolve a boundary layer of width O(ε) in time where the motion enters a
stick or sliding phase.

The statements (exactly these, written the way the models' docstrings write the
physics: friction −μ·sat(v/ε); qdframe codes it as μ·Sgn(−v), the same set):

=======================  ================================================================
block-stop-stick(-bvp)   p' = v,  v' = −3·sat(v/ε) + 1
block-breakaway          p' = v,  v' = −1·sat(v/ε) + 1·c,  c' = 1
slide-on-line,           x1' = x2,  x2' = −2·sat((x1 + x2)/ε)
slide-after-reaching
two-surface-sliding      x1' = 0.25 − sat(x1/ε) − 0.5·sat(x2/ε),  x2' = −0.25 − sat(x2/ε)
coulomb-block            p' = v,  v' = (−μ·F_N·sat(v/ε) + g)/m   (μ = 0.5, F_N = 10, g = 3.5, m = 1)
sliding-mode             x1' = x2,  x2' = x1 − a·(|x1| + |x2|)·sat((2·x1 + x2)/ε)   (a = 2)
stick-slip-oscillator    p' = v,  v' = −p − 0.1·sat(v/ε)   (p(0) = 5, v(0) = 0, T = 100)
=======================  ================================================================

Constants come from the models' modules (qdframe.models.friction) or from the model
instance's attributes (the qdframe-mechanics plugin's coulomb-block and sliding-mode);
the stick-slip oscillator's friction 0.1 is :data:`STICK_SLIP_FRICTION` here. Boundary
conditions are the model's: y_i(0) = x0_i where x0_i is given (NaN: free), y_j(T) = xT_j
for j in ``end_indices``, y_i(T) = y_i(0) for ``periodic``; solve_bvp needs exactly n of
them. sliding-mode's surface equation 2·x1 + x2 = 0 is not imposed (an ODE statement has
no place for it; the regularized flow keeps s = O(ε) by itself).

Left out: models with set-valued inputs (bounded controls, intervals, hulls, balls:
coulomb-rest-to-rest, sliding-mode-terminal, double-pendulum, velocity-range,
disturbed-control, intersecting-balls, paper-7.x). Their trajectories are not fixed by an
ODE; they are optimal-control or feasibility problems, nosnoc's side of the comparison.

What a user would do, and what :func:`run_solve_bvp` does: an initial mesh of 11 uniform
nodes on [0, T], the model's ``initial_guess`` on it (qdframe's default is x0 held
constant, 0 where x0 is free), no analytic Jacobian (solve_bvp's finite differences),
and one accuracy knob: ε defaults to ``tol``, so asking solve_bvp for a tighter residual
also tightens the regularization (a tol far below ε would only resolve the wrong,
regularized problem more finely). Pass ``epsilon`` to decouple them.

Why solve_bvp struggles here (docs/benchmark-results.md has the runs): as ε = tol
shrinks its mesh outgrows max_nodes ("maximum number of mesh nodes exceeded"). The nodes
pile up across whole stick and sliding phases: there f has slope a/ε across the layer,
and Lobatto IIIA collocation (A-stable, not L-stable) leaves that stiff component
undamped unless h ≲ ε, so v oscillates about the layer instead of settling in it.
Continuation in ε (each solution the next start) does not get past that, and a tighter
tol at fixed ε solves but keeps the O(ε) error of the regularization, which bounds its
accuracy on these problems. A failed run still returns its last x, z and mesh.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np
from scipy.integrate import solve_bvp

from ..errors import InputError
from ..models import friction
from .peers import PeerRun, package_version

STICK_SLIP_NAME = "stick-slip-oscillator"
STICK_SLIP_FRICTION = 0.1  # p' = v, v' ∈ −p − 0.1·Sgn(v)
INITIAL_NODES = 11

Rhs = Callable[[np.ndarray, float], np.ndarray]  # y (n, m), ε -> y' (n, m)


def sat(s: np.ndarray, epsilon: float) -> np.ndarray:
    """The regularized sign clip(s/ε, −1, 1)."""
    return np.clip(s / epsilon, -1.0, 1.0)


# ------------------------------------------------------------------- the statements
def _block_stop_stick(model) -> Rhs:
    mu, pull = friction.STOP_FRICTION, friction.STOP_PULL

    def rhs(y, eps):
        p, v = y
        return np.vstack([v, -mu * sat(v, eps) + pull])

    return rhs


def _block_breakaway(model) -> Rhs:
    mu, ramp = friction.BREAK_FRICTION, friction.BREAK_RAMP

    def rhs(y, eps):
        p, v, c = y
        return np.vstack([v, -mu * sat(v, eps) + ramp * c, np.ones_like(c)])

    return rhs


def _slide_on_line(model) -> Rhs:
    gain = friction.LINE_GAIN

    def rhs(y, eps):
        x1, x2 = y
        return np.vstack([x2, -gain * sat(x1 + x2, eps)])

    return rhs


def _two_surface(model) -> Rhs:
    a1, a2, b = friction.TWO_A1, friction.TWO_A2, friction.TWO_B

    def rhs(y, eps):
        x1, x2 = y
        return np.vstack([a1 - sat(x1, eps) - b * sat(x2, eps), a2 - sat(x2, eps)])

    return rhs


def _coulomb_block(model) -> Rhs:
    _need(model, "coulomb-block")
    mass, mu, normal, pull = model.mass, model.mu, model.normal_force, model.pull

    def rhs(y, eps):
        p, v = y
        return np.vstack([v, (-mu * normal * sat(v, eps) + pull) / mass])

    return rhs


def _sliding_mode(model) -> Rhs:
    _need(model, "sliding-mode")
    gain, slope = model.gain, model.slope

    def rhs(y, eps):
        x1, x2 = y
        return np.vstack([x2, x1 - gain * (np.abs(x1) + np.abs(x2)) * sat(slope * x1 + x2, eps)])

    return rhs


def _stick_slip(model) -> Rhs:
    mu = STICK_SLIP_FRICTION

    def rhs(y, eps):
        p, v = y
        return np.vstack([v, -p - mu * sat(v, eps)])

    return rhs


def _need(model, name: str) -> None:
    if model is None:
        raise InputError("model", f"the {name} model instance (its constants are its attributes)", None)


STATEMENTS: dict[str, Callable[[object], Rhs]] = {
    "block-stop-stick": _block_stop_stick,
    "block-stop-stick-bvp": _block_stop_stick,
    "block-breakaway": _block_breakaway,
    "slide-on-line": _slide_on_line,
    "slide-after-reaching": _slide_on_line,
    "two-surface-sliding": _two_surface,
    "coulomb-block": _coulomb_block,
    "sliding-mode": _sliding_mode,
    STICK_SLIP_NAME: _stick_slip,
}
BVP_MODELS: tuple[str, ...] = tuple(STATEMENTS)


def statement(name: str, epsilon: float, model=None) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """fun(t, y) of model `name` regularized with ε, vectorized as solve_bvp wants: y (n, m) -> (n, m).
    `model`: the instance, needed where the constants are its attributes (coulomb-block, sliding-mode)."""
    if name not in STATEMENTS:
        raise InputError("model", f"one of {', '.join(BVP_MODELS)} (solve_bvp statements)", name)
    if not (np.isfinite(epsilon) and epsilon > 0):
        raise InputError("epsilon", "a positive finite number", epsilon)
    rhs = STATEMENTS[name](model)
    eps = float(epsilon)

    def fun(t: np.ndarray, y: np.ndarray) -> np.ndarray:
        return rhs(np.asarray(y, dtype=float), eps)

    return fun


def boundary_conditions(x0: Sequence[float], end_indices: Sequence[int] = (), end_values: Sequence[float] = (),
                        periodic: Sequence[int] = ()) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """bc(ya, yb): y_i(0) − x0_i for given x0_i (NaN: free), y_j(T) − xT_j, y_i(T) − y_i(0) (periodic)."""
    x0 = np.asarray(x0, dtype=float)
    given = np.flatnonzero(np.isfinite(x0))
    end = np.asarray(end_indices, dtype=int)
    values = np.asarray(end_values, dtype=float)
    loop = np.asarray(periodic, dtype=int)
    count = given.size + end.size + loop.size
    if count != x0.size:
        raise InputError("boundary conditions", f"exactly {x0.size} for solve_bvp (n states, no parameters)",
                         f"{given.size} initial + {end.size} end + {loop.size} periodic")

    def bc(ya: np.ndarray, yb: np.ndarray) -> np.ndarray:
        return np.concatenate([ya[given] - x0[given], yb[end] - values, yb[loop] - ya[loop]])

    return bc


def solve_statement(name: str, T: float, x0: Sequence[float], tol: float, epsilon: float | None = None,
                    max_nodes: int = 100000, end_indices: Sequence[int] = (), end_values: Sequence[float] = (),
                    periodic: Sequence[int] = (), guess: Callable[[np.ndarray], np.ndarray] | None = None,
                    model=None) -> PeerRun:
    """solve_bvp on the statement of `name` with these boundary data (see :func:`run_solve_bvp`).
    `guess(t)` -> x (len(t), n); default x0 held constant (0 where free)."""
    start = time.perf_counter()
    if not (np.isfinite(tol) and tol > 0):
        raise InputError("tol", "a positive finite number", tol)
    eps = float(tol) if epsilon is None else float(epsilon)
    fun = statement(name, eps, model)
    bc = boundary_conditions(x0, end_indices, end_values, periodic)
    mesh = np.linspace(0.0, float(T), INITIAL_NODES)
    y0 = np.tile(np.nan_to_num(np.asarray(x0, dtype=float)), (mesh.size, 1)) if guess is None else guess(mesh)
    sol = solve_bvp(fun, bc, mesh, np.asarray(y0, dtype=float).T, tol=tol, max_nodes=max_nodes)
    wall = time.perf_counter() - start
    rms = float(np.max(sol.rms_residuals)) if sol.rms_residuals is not None and sol.rms_residuals.size else float("nan")
    message = (f"scipy {package_version('scipy')} solve_bvp: {sol.message} (status {sol.status}) after {sol.niter} "
               f"iterations; {sol.x.size} mesh nodes, max rms residual {rms:.1e}; sat(s/ε) with ε = {eps:.1e}, tol {tol:.1e}")
    return PeerRun("solved" if sol.success else "failed", message, int(sol.niter), wall, 0.0,
                   x=sol.y.T, z=sol.yp.T, t=sol.x)


def run_solve_bvp(model, tol: float, epsilon: float | None = None, max_nodes: int = 100000) -> PeerRun:
    """Solve `model` (one of :data:`BVP_MODELS`) with scipy's solve_bvp on its regularized statement.

    Initial mesh: 11 uniform nodes on [0, T]; initial guess: the model's ``initial_guess``
    (x0 held constant unless the model says otherwise); ε defaults to `tol` (one knob: a
    tighter tol also tightens the regularization). The result's x = sol.y.T and
    z = sol.yp.T live on solve_bvp's own final mesh, returned as `t` (not qdframe's grid);
    wall_time_s is the whole call, setup_time_s 0, iterations solve_bvp's Newton iterations.
    """
    start = time.perf_counter()
    if model.name not in STATEMENTS:
        raise InputError("model", f"one of {', '.join(BVP_MODELS)} (solve_bvp statements)", model.name)
    if model.n_controls:
        raise InputError("model", "a model without unknown controls (solve_bvp statements)", model.name)
    run = solve_statement(model.name, model.T, model.x0, tol, epsilon, max_nodes, model.end_indices,
                          model.end_values, model.periodic, guess=lambda t: model.initial_guess(t)[0], model=model)
    run.wall_time_s = time.perf_counter() - start
    return run

