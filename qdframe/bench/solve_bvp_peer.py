"""The solve_bvp peer (:class:`SolveBVP`, registered as ``solve_bvp``): scipy.integrate.solve_bvp
on the regularized ODE a user would write for each model.

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

The statements are the models' forms x' ∈ f(x) + Σ_j a_j(x)·Sgn(c_j(x)) of
:mod:`.sign_forms` (the ones nosnoc gets too; :mod:`.problems` says which model has which) with every Sgn(c) replaced by sat(c/ε): e.g.
block-stop-stick p' = v, v' = −3·sat(v/ε) + 1; sliding-mode x2' = x1 − a·(|x1| + |x2|)·
sat((2·x1 + x2)/ε); stick-slip-oscillator v' = −p − 0.1·sat(v/ε). Boundary
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
from ..model import InclusionModel
from ..status import Status
from . import problems
from .peer import Peer, PeerRun, package_version

INITIAL_NODES = 11


class SolveBVP(Peer):
    """scipy's solve_bvp on each model's regularized ODE, one run per tolerance (ε = tol)."""

    name = "solve_bvp"
    inner = "scipy"
    line = "solve_bvp"
    knob = "tol"
    description = "scipy.integrate.solve_bvp on the regularized ODE sat(s/ε) in place of Sgn(s)"

    def states(self, model: InclusionModel) -> bool:
        return problems.sign_form(model) is not None and not model.n_controls

    def run(self, model: InclusionModel, setting: float) -> PeerRun:
        return run_solve_bvp(model, float(setting))


def sat(s: np.ndarray, epsilon: float) -> np.ndarray:
    """The regularized sign clip(s/ε, −1, 1)."""
    return np.clip(s / epsilon, -1.0, 1.0)


def statement(name: str, epsilon: float, model=None) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """fun(t, y) of model `name` regularized with ε, vectorized as solve_bvp wants: y (n, m) -> (n, m):
    its :class:`~.statements.SignForm` f(y) + Σ_j a_j(y)·sat(c_j(y)/ε). `model`: the instance, needed
    where the constants are its attributes (coulomb-block, sliding-mode)."""
    entry = problems.problem(name)
    if entry is None or entry.sign_form is None:
        raise InputError("model", f"one of {', '.join(problems.with_sign_form())} (solve_bvp statements)", name)
    if not (np.isfinite(epsilon) and epsilon > 0):
        raise InputError("epsilon", "a positive finite number", epsilon)
    form = entry.sign_form(model)
    eps = float(epsilon)

    def fun(t: np.ndarray, y: np.ndarray) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        x = list(y)
        out = [np.broadcast_to(np.asarray(f, dtype=float), y.shape[1:]).copy() for f in form.base(x)]
        for a, c in form.terms(x):
            s = sat(c, eps)
            for i, gain in enumerate(a):
                out[i] = out[i] + gain * s
        return np.stack(out)

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
    return PeerRun(Status.SOLVED if sol.success else Status.FAILED, message, int(sol.niter), wall, 0.0,
                   x=sol.y.T, z=sol.yp.T, t=sol.x)


def run_solve_bvp(model, tol: float, epsilon: float | None = None, max_nodes: int = 100000) -> PeerRun:
    """Solve `model` (one with a sign form in :mod:`.problems`) with scipy's solve_bvp on its regularized statement.

    Initial mesh: 11 uniform nodes on [0, T]; initial guess: the model's ``initial_guess``
    (x0 held constant unless the model says otherwise); ε defaults to `tol` (one knob: a
    tighter tol also tightens the regularization). The result's x = sol.y.T and
    z = sol.yp.T live on solve_bvp's own final mesh, returned as `t` (not qdframe's grid);
    wall_time_s is the whole call, setup_time_s 0, iterations solve_bvp's Newton iterations.
    """
    start = time.perf_counter()
    if problems.sign_form(model) is None:
        raise InputError("model", f"one of {', '.join(problems.with_sign_form())} (solve_bvp statements)", model.name)
    if model.n_controls:
        raise InputError("model", "a model without unknown controls (solve_bvp statements)", model.name)
    run = solve_statement(model.name, model.T, model.x0, tol, epsilon, max_nodes, model.end_indices,
                          model.end_values, model.periodic, guess=lambda t: model.initial_guess(t)[0], model=model)
    run.wall_time_s = time.perf_counter() - start
    return run

