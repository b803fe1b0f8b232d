"""The nosnoc peer (:class:`Nosnoc`, registered as ``nosnoc``), run on every catalogue problem it
can state.

nosnoc (PyPI ``nosnoc``, FESD + homotopy + IPOPT through CasADi) states a Filippov system
in Stewart's form: subsystems i with modes F_i = [f_i1, f_i2], x' = Σ_i F_i θ_i, each θ_i in
the simplex, the mode chosen by the sign of a switching function c_i (S_i = [[1], [−1]]).

- **The friction and sliding models** (a sign form in :mod:`.problems`): x' ∈ f(x) +
  Σ_j a_j(x)·Sgn(c_j(x)) is one subsystem per sign term with modes f + a_j and f − a_j for
  the first and ±a_j for the others (the subsystems' fields add, so f enters once), the
  statement of :mod:`.sign_forms`. There is no control and no cost: nosnoc's OCP with the
  model's end conditions as terminal equality constraints. A free start value x_i(0) is a
  global variable p_i of the OCP (nosnoc fixes x(0)): the state is x − p_i·e_i from 0.
  One control stage, N − 1 finite elements: FESD may move every element boundary.
- **The two problems of :mod:`qdframe.models.bounded_input`** are optimal-control
  problems: the bounded input is a control with box bounds, the cost is nosnoc's example
  cost (∫u² for the block, ∫(v1² + v2²) for the sliding-mode problem) and the end state is a
  terminal equality constraint; 10 control stages × ⌈(N − 1)/10⌉ finite elements each.

Both: Radau IIA with n_s = 2 stage points, FESD step equilibration as nosnoc's defaults,
complementarity tolerance 1e-9. (The time-optimal block, T free, is stated with a speed of
time in :mod:`.nosnoc_time_optimal`, for ``qdframe bench time-optimal``; not in the sweep.)

How it is read. nosnoc's trajectory is, on each finite element [t_e, t_e + h_e], the
collocation polynomial of degree n_s through the element's start value and its stage
values at τ = (0, c_1, …, c_ns) — by the collocation equations its derivative at the stage
points is nosnoc's own velocity f(x, u, θ). It is judged at N uniform times and at every
one of its own points (element boundaries and stage points, :func:`own_times`): x from the
polynomial, z = its slope; at an element boundary, the mean of the slopes of the two
adjacent elements (see :func:`reconstruct`). A control, constant on each stage, is returned
as `inputs` (with the stage ends as `breaks`): the sweep judges such a run by the true
motion that control drives (:mod:`.references`), and shows qdframe's residual checks of
ξ = (x, z) beside it.
"""

from __future__ import annotations

import contextlib
import io
import math
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..functional import Functional
from ..schemes.grid import Grid
from ..model import InclusionModel
from ..models.bounded_input import SLIDING_A, SLIDING_B, CoulombRestToRest, SlidingModeTerminal
from ..status import Status
from . import problems
from .peer import Peer, PeerRun, package_version
from .sign_forms import SignForm

NOSNOC_STAGES = 10
CONTROL_PROBLEMS = (CoulombRestToRest, SlidingModeTerminal)  # stated here, not from a sign form
TWO_MODES = np.array([[1], [-1]])  # Stewart's S of one switching function: mode 1 where c > 0, mode 2 where c < 0
INSTALL_HINT = "pip install 'qdframe[peers]' (or pip install nosnoc)"


class Nosnoc(Peer):
    """nosnoc (FESD + homotopy + IPOPT through CasADi): N − 1 finite elements per run."""

    name = "nosnoc"
    inner = "ipopt"
    line = "nosnoc / ipopt"
    knob = "nodes"
    description = "nosnoc: FESD, Stewart's form, IPOPT (pip install 'qdframe[peers]')"

    def unavailable(self) -> str | None:
        return nosnoc_available()

    def states(self, model: InclusionModel) -> bool:
        return isinstance(model, CONTROL_PROBLEMS) or problems.sign_form(model) is not None

    def run(self, model: InclusionModel, setting: float) -> PeerRun:
        return run_nosnoc(model, int(setting))


def nosnoc_available() -> str | None:
    """None if nosnoc imports, else the reason (with the pip command)."""
    try:
        with warnings.catch_warnings():  # nosnoc sets warnings.simplefilter("always") on import
            import casadi  # noqa: F401
            import nosnoc  # noqa: F401
    except Exception as exc:  # ImportError, or a broken CasADi binary
        return f"nosnoc is not usable here ({type(exc).__name__}: {exc}); {INSTALL_HINT}"
    return None


def run_nosnoc(model: InclusionModel, nodes: int) -> PeerRun:
    """Solve `model` (one :meth:`Nosnoc.states`) with nosnoc and judge it at N = `nodes`
    uniform times and at its own points."""
    reason = nosnoc_available()
    if reason is not None:
        return PeerRun(Status.FAILED, reason, 0, float("nan"), float("nan"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import casadi as ca
        import nosnoc

    start = time.perf_counter()
    statement = _problem(model, ca, nosnoc)
    opts = settings(nosnoc, model.T, statement.stages, max(1, math.ceil((nodes - 1) / statement.stages)))
    solver, results, setup, wall, chatter = solve_quietly(nosnoc, opts, statement.model, statement.ocp, start)

    tau = _collocation_nodes(opts)
    t = own_times(results, tau, Grid(model.T, nodes).t)
    functional = Functional(model, Grid.from_mesh(t), signs="band")  # judged by Filippov's set, no selections
    x, z = statement.read(results, tau, t)
    history, elapsed = [], setup
    for step, w in enumerate(results["w_all"][1:], start=1):
        iterate = nosnoc.get_results_from_primal_vector(solver.problem, w)
        terms = functional.terms(functional.pack(*statement.read(iterate, tau, t)))
        elapsed += float(results["cpu_time_nlp"][step - 1] or 0.0)
        history.append({"iteration": step, "objective": terms.objective, "I": terms.I, "time_s": elapsed})
    success = results["status"] == nosnoc.Status.SUCCESS
    ipopt_iterations = int(sum(i for i in results["nlp_iter"] if i is not None))
    steps = sum(1 for i in results["nlp_iter"] if i is not None)
    complementarity = float(solver.problem.comp_res(results["w_sol"], solver.p_val).full()[0][0])
    outcome = "success" if success else f"IPOPT did not converge ({getattr(results['status'], 'name', results['status'])})"
    message = (
        f"nosnoc {package_version('nosnoc')}, CasADi {package_version('casadi')}: {outcome} after {steps} homotopy steps "
        f"({ipopt_iterations} IPOPT iterations), complementarity {complementarity:.1e}, own cost "
        f"{float(results['cost_val']):.4g}; {opts.N_stages} stage{'s' if opts.N_stages > 1 else ''} × "
        f"{opts.N_finite_elements} finite elements, Radau IIA n_s = 2; setup (CasADi/IPOPT build) {setup:.2f} s"
    )
    if "Warning" in chatter:
        message += "; " + chatter.strip().splitlines()[-1]
    inputs = None
    if statement.controls:
        controls = np.asarray(results["u_list"], dtype=float).reshape(opts.N_stages, -1)
        inputs = _stagewise(controls, model.T)
    return PeerRun(Status.SOLVED if success else Status.FAILED, message, ipopt_iterations, wall, setup, x, z, history,
                   t=t, inputs=inputs)


def settings(nosnoc, T: float, stages: int, elements: int):
    """nosnoc's options of every run here: `stages` control stages of `elements` finite elements
    on [0, T], Radau IIA with n_s = 2, FESD, complementarity tolerance 1e-9, silent."""
    opts = nosnoc.NosnocOpts()
    opts.terminal_time = T
    opts.N_stages = stages
    opts.N_finite_elements = elements
    opts.n_s = 2
    opts.comp_tol = 1e-9
    opts.print_level = 0
    return opts


def solve_quietly(nosnoc, opts, model, ocp, start: float) -> tuple[object, dict, float, float, str]:
    """nosnoc's solver built and run with its prints and warnings caught: the solver, its results,
    the seconds since `start` when it was built (setup) and when it finished, and what it printed."""
    chatter = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stdout(chatter):
        warnings.simplefilter("ignore")
        solver = nosnoc.NosnocSolver(opts, model, ocp)
        setup = time.perf_counter() - start
        results = solver.solve()
    return solver, results, setup, time.perf_counter() - start, chatter.getvalue()


@dataclass
class _Statement:
    """nosnoc's model and OCP of one problem, its control stages, and how to read x from a result
    (the start values that are global variables added back to their states)."""

    model: object
    ocp: object
    stages: int
    controls: bool
    free: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # states whose x(0) is a variable

    def read(self, results: dict, tau: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x, z = reconstruct(results, tau, t)
        if self.free.size:
            x[:, self.free] += np.asarray(results["v_global"], dtype=float).reshape(-1)
        return x, z


def _stagewise(controls: np.ndarray, T: float) -> Callable[[float], np.ndarray]:
    """nosnoc's control: constant on each of its equal control stages (`breaks`: their ends)."""
    def drive(s: float) -> np.ndarray:
        return controls[min(int(s / T * controls.shape[0]), controls.shape[0] - 1)]

    drive.breaks = tuple(T * np.arange(1, controls.shape[0]) / controls.shape[0])
    return drive


def _collocation_nodes(opts) -> np.ndarray:
    """τ = (0, c_1, …, c_ns) of nosnoc's integral IRK representation."""
    points = np.asarray(opts.irk_time_points, dtype=float)
    return points if np.isclose(points[0], 0.0) else np.concatenate([[0.0], points])


def reconstruct(results: dict, tau: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x and x' at times t from nosnoc's collocation polynomials (one per finite element).

    Inside an element, the polynomial and its slope. At an interior element boundary (within
    1e-3 of the shortest element; FESD moves boundaries by round-off), x from the element that
    ends there and x' the mean of the end slope of that element and the start slope of the
    next: each is a one-sided velocity, F(x) is convex, and the trapezoid rule then integrates
    a velocity that jumps there (e.g. a piecewise-constant control) without drift.
    """
    steps = np.asarray(results["time_steps"], dtype=float).reshape(-1)
    points = np.asarray(results["x_all_list"], dtype=float)  # x0, then n_s stage values per element
    stages = tau.size - 1
    if points.shape[0] != 1 + stages * steps.size:
        raise ValueError(f"nosnoc returned {points.shape[0]} state values for {steps.size} elements of {stages} stages")
    bounds = np.concatenate([[0.0], np.cumsum(steps)])  # element e is [bounds[e], bounds[e + 1]]
    last = steps.size - 1
    nearest = np.clip(np.searchsorted(bounds, t), 1, bounds.size - 1)
    nearest = np.where(np.abs(t - bounds[nearest - 1]) < np.abs(t - bounds[nearest]), nearest - 1, nearest)
    boundary = (np.abs(t - bounds[nearest]) <= 1e-3 * steps.min()) & (nearest > 0) & (nearest <= last)
    element = np.clip(np.searchsorted(bounds, t, side="right") - 1, 0, last)
    fraction = (t - bounds[element]) / steps[element]
    element = np.where(boundary, nearest - 1, element)
    fraction = np.where(boundary, 1.0, fraction)
    x, slope = _polynomial(points, steps, stages, tau, element, fraction)
    after = np.minimum(nearest, last)
    _, slope_after = _polynomial(points, steps, stages, tau, after, np.zeros_like(t))
    return x, np.where(boundary[:, None], 0.5 * (slope + slope_after), slope)


def _polynomial(points, steps, stages, tau, element, fraction) -> tuple[np.ndarray, np.ndarray]:
    """Value and slope of the collocation polynomials of `element` at τ = `fraction`."""
    values = np.stack([points[element * stages + j] for j in range(stages + 1)], axis=1)  # (K, n_s + 1, n)
    basis, slope = _lagrange(tau, fraction)
    return np.einsum("kj,kjn->kn", basis, values), np.einsum("kj,kjn->kn", slope, values) / steps[element][:, None]


def _lagrange(nodes: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lagrange basis ℓ_j(s) and ℓ_j'(s) on `nodes`, for every s: shapes (K, len(nodes))."""
    count = nodes.size
    basis, slope = np.ones((s.size, count)), np.zeros((s.size, count))
    for j in range(count):
        others = [r for r in range(count) if r != j]
        for r in others:
            basis[:, j] *= (s - nodes[r]) / (nodes[j] - nodes[r])
        for q in others:
            term = np.full(s.size, 1.0 / (nodes[j] - nodes[q]))
            for r in others:
                if r != q:
                    term *= (s - nodes[r]) / (nodes[j] - nodes[r])
            slope[:, j] += term
    return basis, slope


def own_times(results: dict, tau: np.ndarray, uniform: np.ndarray) -> np.ndarray:
    """The N uniform times and nosnoc's own points (its element boundaries and stage points
    t_e + c_j·h_e), sorted; points within 1e-12·T of another are one."""
    steps = np.asarray(results["time_steps"], dtype=float).reshape(-1)
    bounds = np.concatenate([[0.0], np.cumsum(steps)])
    stages = (bounds[:-1, None] + tau[None, 1:] * steps[:, None]).ravel()
    t = np.sort(np.concatenate([uniform, bounds, stages]))
    t = np.clip(t, 0.0, uniform[-1])
    keep = np.concatenate([[True], np.diff(t) > 1e-12 * uniform[-1]])
    t = t[keep]
    t[-1] = uniform[-1]
    return t


def _problem(model: InclusionModel, ca, nosnoc) -> _Statement:
    """nosnoc's statement of `model`: a friction or sliding model with a sign form
    (:mod:`.problems`), or one of the two bounded-input problems."""
    S = [TWO_MODES]
    form = problems.sign_form(model)
    if form is not None:
        return _sign_problem(model, form, ca, nosnoc)
    if isinstance(model, CoulombRestToRest):
        position, velocity, force = ca.SX.sym("p"), ca.SX.sym("v"), ca.SX.sym("u")
        x = ca.vertcat(position, velocity)
        friction = model.friction
        modes = ca.horzcat(ca.vertcat(velocity, force - friction), ca.vertcat(velocity, force + friction))
        nos_model = nosnoc.NosnocModel(x=x, F=[modes], c=[velocity], S=S, x0=np.array(model.x0), u=force)
        bound = model.force_bound * np.ones(1)
        end = np.zeros(2)
        end[list(model.end_indices)] = model.end_values
        ocp = nosnoc.NosnocOcp(lbu=-bound, ubu=bound, f_q=force**2, g_terminal=x - end)
        return _Statement(nos_model, ocp, NOSNOC_STAGES, controls=True)
    if isinstance(model, SlidingModeTerminal):
        x1, x2, v1, v2 = (ca.SX.sym(name) for name in ("x1", "x2", "v1", "v2"))
        u1, u2 = ca.SX.sym("u1"), ca.SX.sym("u2")
        x, u = ca.vertcat(x1, x2, v1, v2), ca.vertcat(u1, u2)
        first = ca.horzcat(ca.vertcat(-1 + v1, 0, u1, u2), ca.vertcat(1 + v1, 0, u1, u2))
        # FESD adds the subsystems' fields (x' = Σ_i F_i θ_i, Σ θ_i = 1 per subsystem), so the input
        # enters one subsystem only: in both it would drive v' = 2u (a box of ±20, not qdframe's ±10)
        second = ca.horzcat(ca.vertcat(0, -1 + v2, 0, 0), ca.vertcat(0, 1 + v2, 0, 0))
        switches = [x1 + SLIDING_A * x2**2, x2 + SLIDING_B * x1**3]
        nos_model = nosnoc.NosnocModel(x=x, F=[first, second], c=switches, S=S + S, x0=np.array(model.x0), u=u)
        bound = model.input_bound * np.ones(2)
        target = np.asarray(model.end_values)
        ocp = nosnoc.NosnocOcp(lbu=-bound, ubu=bound, f_q=v1**2 + v2**2, g_terminal=x[:2] - target)
        return _Statement(nos_model, ocp, NOSNOC_STAGES, controls=True)
    raise ValueError(f"nosnoc has no statement of model {model.name!r}; it runs the catalogue's problems with a "
                     "sign form and the bounded-input control problems")


def _sign_problem(model: InclusionModel, form: SignForm, ca, nosnoc) -> _Statement:
    """x' ∈ f(x) + Σ_j a_j(x)·Sgn(c_j(x)) in Stewart's form: subsystem j has the modes
    (f + a_j, f − a_j) for j = 0 and (a_j, −a_j) after; no control, no cost; the end conditions
    terminal constraints; a free x_i(0) a global variable p_i with x_i = state_i + p_i."""
    if model.periodic:
        raise ValueError(f"nosnoc's statement of {model.name!r} has no periodic conditions")
    count = len(model.x0)
    state = ca.SX.sym("x", count)
    x0 = np.asarray(model.x0, dtype=float)
    free = np.flatnonzero(~np.isfinite(x0))
    shift = ca.SX.sym("x0_free", free.size)
    x = [state[i] for i in range(count)]
    for k, i in enumerate(free):
        x[i] = state[i] + shift[k]
    base = ca.vertcat(*form.base(x))
    modes, switches = [], []
    for j, (a, c) in enumerate(form.terms(x)):
        lead, a = (base if j == 0 else ca.SX.zeros(count)), ca.vertcat(*a)
        modes.append(ca.horzcat(lead + a, lead - a))
        switches.append(c)
    nos_model = nosnoc.NosnocModel(x=state, F=modes, c=switches, S=[TWO_MODES] * len(modes),
                                   x0=np.where(np.isfinite(x0), x0, 0.0), v_global=shift)
    end = list(model.end_indices)
    terminal = ca.vertcat(*[x[i] for i in end]) - np.asarray(model.end_values, dtype=float) if end else ca.SX.zeros(0)
    unbounded = np.full(free.size, np.inf)
    guess = model.initial_guess(np.zeros(1))[0][0, free] if free.size else np.zeros(0)
    ocp = nosnoc.NosnocOcp(g_terminal=terminal, lbv_global=-unbounded, ubv_global=unbounded,
                           v_global_guess=np.asarray(guess, dtype=float))
    return _Statement(nos_model, ocp, 1, controls=False, free=free)
