"""The δ-quasidifferential descent loop (paper Section 6) and `qdframe.solve`."""

from __future__ import annotations

import dataclasses
import inspect
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from threadpoolctl import threadpool_limits

from . import adaptive, certify, estimates, switches, unknowns
from .directions.base import DirectionSolver
from .diagnosis import unmet_conditions
from .errors import BackendError, InputError, ModelOutputError
from .functional import Functional
from .grid import Grid, make_scheme
from .line_searches.base import LineSearch
from .model import InclusionModel
from .schemes import Scheme
from .estimates import CERTIFICATES
from .registry import load_model, lookup, make_direction, make_line_search, plugin_code
from .result import IterationRecord, SolveResult
from .start import MODEL, Starts
from .status import Status

ProgressCallback = Callable[[IterationRecord], None]


@dataclass(frozen=True)
class DescentOptions:
    """The method's parameters; the paper's defaults δ = 1e-3, ε = 1e-2, γ̄ = 1 (Section 7).

    eps_floor: where every node's deviation is ≤ ε but the iterate is not solved, ε and δ
    shrink together by EPS_SHRINK and the descent goes on, down to ε = eps_floor (the
    paper's method carried to convergence); eps_floor = eps keeps ε and δ fixed."""

    max_iter: int = 500
    tol: float = 1e-10
    delta: float = 1e-3
    eps: float = 1e-2
    gamma_max: float = 1.0
    residual_tol: float = 1e-8  # pointwise, scaled to the states: see :mod:`qdframe.certify`
    eps_floor: float = 1e-12  # EPS_FLOOR

    def __post_init__(self) -> None:
        if isinstance(self.max_iter, bool) or not isinstance(self.max_iter, (int, np.integer)) or self.max_iter < 0:
            raise InputError("max_iter", "an integer ≥ 0", self.max_iter)
        for field_name in ("tol", "delta", "eps", "gamma_max", "residual_tol", "eps_floor"):
            value = getattr(self, field_name)
            if not isinstance(value, (int, float, np.floating)) or not np.isfinite(value) or value <= 0:
                raise InputError(field_name, "a positive finite number", value)
        if self.eps_floor > self.eps:
            raise InputError("eps_floor", f"a number ≤ eps = {self.eps:g} (eps_floor = eps: ε and δ fixed)",
                             self.eps_floor)


def solve(
    model: str | InclusionModel,
    nodes: int | None = None,
    direction: str | DirectionSolver = "gauss-newton",
    line_search: str | LineSearch | None = None,
    *,
    max_iter: int | None = None,
    tol: float | None = None,
    delta: float = 1e-3,
    eps: float = 1e-2,
    gamma_max: float = 1.0,
    residual_tol: float = 1e-8,
    eps_floor: float | None = None,
    continuation: Sequence[int] | str | None = None,
    progress: ProgressCallback | None = None,
    scheme: str | Scheme | None = None,
    signs: str = "exact",
    selection_scale: float = 1.0,
    mesh: Sequence[float] | np.ndarray | None = None,
    estimate: bool = True,
    accuracy: float | None = None,
    max_nodes: int = 100_001,
    certificate: str | None = None,
    simulate_start: bool = True,
    free_T: bool | None = None,
    parameters: Mapping[str, float] | None = None,
) -> SolveResult:
    """Find a trajectory of `model` by quasidifferential descent.

    `direction` "gauss-newton" (the default) or "native" (the paper's method), or any
    registered name or DirectionSolver; `line_search` likewise, by default the
    direction's own (`default_line_search`: armijo for gauss-newton, golden for native).

    `continuation` lists coarser grids to solve on first (e.g. (11, 101) before
    nodes=1001): each grid's result, interpolated, starts the next. "auto" is the ladder
    11, 101, 1001, … below `nodes` (:func:`grid_schedule`), "none" (or ()) the one grid,
    None the direction's own (`default_continuation`: "auto" for both, from the
    direction's `coarsest_nodes` with its `ladder_steps`: 11, 101, 1001, … for the paper's
    min-norm directions, 101, 301, 1001, 3001, … for gauss-newton). Each grid starts from
    the lowest, on that grid, of the previous stage's iterate, the start that stage had (if
    it came from a stage) and the model's own start. `max_iter` is the budget of all G
    grids together: a coarser grid spends at most max(1, max_iter // (2G)) (its band start
    included) and leaves one iteration to each later grid, so the requested grid gets the
    rest: at least half when max_iter ≥ 2G and ≥ 1 when max_iter ≥ 1 (a coarse grid left
    no iteration is skipped). A stage before the last only provides a start and stops on
    10·ε. The history and `iterations` cover all grids, each record naming its grid
    (`nodes`); each grid after the first adds a record of its start (same iteration
    number); `options["iterations_per_grid"]` is aligned with `options["grids"]`, and a
    status other than `solved` after several grids gives it in the message.

    `scheme` discretizes x' = z (:mod:`qdframe.schemes`: "trapezoid", the paper's;
    "implicit-euler"; "radau-iia", where `nodes` counts mesh and stage points and is odd);
    None is the model's `default_scheme` (implicit Euler unless the model says otherwise).
    `signs` "exact" gives every sign term a·Sgn(s) a selection λ ∈ [−1, 1] per node tied
    to s by the natural map λ = clip(λ + c·s, −1, 1), c = `selection_scale`
    (the result's `selections`); "band" uses each term's C¹ band instead.

    Stops `solved` when the objective and I are ≤ tol (the model's default tol if
    None), `stationary` when every node's deviation is ≤ ε or no step decreases the
    objective (the paper's min-norm directions: where every node's deviation is ≤ ε but the
    iterate is not solved, ε and δ shrink together by 10 and the descent goes on, down to
    ε = `eps_floor`; None: 1e-12 for a certified solve, `nodes`/`mesh` without `accuracy`
    keep the paper's fixed ε and δ; `options["eps"]` and `options["delta"]` are the smallest
    its descents reached), `max_iter` when the budget is spent, `failed` when a backend reports an
    error mid-run (the message says which).

    A line-search trial point where the model returns NaN/inf is rejected (no decrease);
    :class:`~qdframe.errors.ModelOutputError` is raised, naming the piece, node, t and the
    state there, when the model is non-finite at an accepted iterate (its values or
    gradients, at the start too) or on every step from it (the descent cannot continue).
    The returned x(t_0) is the model's x0 exactly where x0 is given. `wall_time_s` is
    the whole call: every grid, its start, its result's checks and the error estimate.

    `nodes` is the number of points (default 101; under `accuracy`, 21: the first mesh).
    `mesh` gives the mesh times 0 = τ_0 < … < τ_K = T of the requested grid (nonuniform
    allowed; `nodes` is then stages·K + 1 and is ignored). A `solved` result carries
    `error_estimate`, an estimate of max_t |x(t) − x*(t)| from a second solve on the
    bisected mesh (:mod:`qdframe.adaptive`; `estimate=False` skips it: None), and
    `switch_times`, where a Filippov selection changes regime (:mod:`qdframe.switches`).
    `accuracy` asks for error_estimate ≤ accuracy: mesh points are moved onto the switch
    times and the mesh is refined where the estimate is large, up to `max_nodes` points;
    with `accuracy` and no `scheme` the scheme is radau-iia (order 3).
    """
    clock = time.perf_counter()
    if isinstance(model, str):
        model = load_model(model)
    if free_T is not None or parameters:  # a copy with T free or fixed, or other guesses of p
        model = unknowns.restated(model, free_T, parameters)
    if model.has_unknowns:  # T or p found with x: the model on s = t/T with constant states
        wrapper = unknowns.Unknowns(model)
        given = dict(locals())
        arguments = {name: given[name] for name in inspect.signature(solve).parameters
                     if name not in ("model", "free_T", "parameters")}
        if mesh is not None:
            arguments["mesh"] = np.asarray(mesh, dtype=float) / (model.T if model.free_T else 1.0)
        result = unknowns.unwrap(wrapper, solve(wrapper, **arguments))
        result.wall_time_s = time.perf_counter() - clock
        return result
    if accuracy is not None and not (isinstance(accuracy, (int, float)) and np.isfinite(accuracy) and accuracy > 0):
        raise InputError("accuracy", "a positive finite number (the target of the error estimate)", accuracy)
    if isinstance(max_nodes, bool) or not isinstance(max_nodes, (int, np.integer)) or max_nodes < 3:
        raise InputError("max_nodes", "an integer ≥ 3", max_nodes)
    if certificate not in (None, *CERTIFICATES):
        raise InputError("certificate", " or ".join(f'"{name}"' for name in CERTIFICATES) + " (None: by the problem)",
                         certificate)
    refining = accuracy is not None or (nodes is None and mesh is None)  # else a fixed grid
    if refining and not estimate:
        raise InputError("estimate", "True when the mesh is refined to an accuracy (estimate=False needs nodes= or "
                         "mesh= without accuracy=)", estimate)
    target = DEFAULT_ACCURACY if accuracy is None else float(accuracy)
    given_nodes = nodes
    if nodes is None:
        nodes = ACCURACY_START_NODES if refining else DEFAULT_NODES
    scheme = (ACCURACY_SCHEME if refining else model.default_scheme) if scheme is None else scheme
    requested, scheme = scheme, (BOOTSTRAP_SCHEME if refining else scheme)
    starts = Starts(model, simulate=simulate_start)
    if refining and mesh is None and given_nodes is None:  # the first mesh: from the model's motion where it has one
        mesh = starts.mesh(ACCURACY_START_NODES - 1)
        if mesh is not None:  # the motion has the switches: no implicit-Euler bootstrap nor coarser grids to find them
            scheme = requested
            continuation = "none" if continuation is None else continuation
    final = Grid(model.T, nodes, scheme) if mesh is None else Grid.from_mesh(_mesh_times(mesh, model.T), scheme)
    nodes = final.nodes
    solver = make_direction(direction)
    if max_iter is None:  # a certified solve: the direction's budget (a first-order method needs more)
        max_iter = solver.certified_max_iter if refining else DEFAULT_MAX_ITER
    if eps_floor is None:  # a fixed grid keeps the paper's ε and δ
        eps_floor = EPS_FLOOR if refining else eps
    options = DescentOptions(
        max_iter=max_iter, tol=model.default_tol if tol is None else tol, delta=delta, eps=eps, gamma_max=gamma_max,
        residual_tol=residual_tol, eps_floor=eps_floor,
    )
    search = make_line_search(solver.default_line_search if line_search is None else line_search)
    if continuation is None and starts.motion() is not None:
        continuation = "none"  # the model's motion sampled on the requested grid starts it: no coarser grids
    grids = grid_schedule(nodes, solver.default_continuation if continuation is None else continuation,
                          solver.coarsest_nodes, solver.ladder_steps)
    stages = []  # the functionals solved in turn: each grid, the first one also with the band if exact
    for count in grids:
        grid = final if count == nodes else Grid(model.T, count, scheme)
        functional = Functional(model, grid, signs=signs, selection_scale=selection_scale)
        if not stages and functional.p:
            stages.append(Functional(model, functional.grid, signs="band"))
        stages.append(functional)
    history, result = [], None
    shrunk_to = []  # (ε, δ) each descent of the user's direction ended with (the paper's: shrunk, perhaps)
    first_start = MODEL
    earlier = []  # what may start the next stage: the last stage's iterate, and its start if that came from a stage
    per_grid = [0] * len(grids)  # iterations spent on each grid (a band start counts on its grid)
    share = max(1, options.max_iter // (2 * len(grids)))  # a coarse grid's cap: the requested grid keeps ≥ half
    for functional in stages:
        count = functional.grid.nodes
        index = grids.index(count)
        last = functional is stages[-1]
        later = len(grids) - 1 - index
        budget = options.max_iter - sum(per_grid) - later  # one iteration kept for each later grid
        if later:
            budget = min(budget, share - per_grid[index])
        if functional.signs != signs:  # the band only starts the exact solve: a short run, one iteration left to it
            budget = min(budget - 1, BAND_START_ITERATIONS)
        if budget <= 0 and not last:  # no iteration here: no result from this grid
            continue
        label, own_start = starts.best(functional)  # the model's start or its simulated motion
        start, from_stage = own_start, False
        if earlier:  # the lowest here of the earlier iterates (the last one first on a tie) and the own start
            candidates = [_interpolate(functional, source) for source in earlier] + [own_start]
            for number, candidate in enumerate(candidates):
                value = functional.objective(candidate)
                if number == 0 or value < lowest:
                    start, lowest, from_stage = candidate, value, number < len(earlier)
        if not history:
            first_start = label
        used, elapsed = (history[-1].iteration, history[-1].time_s) if history else (0, 0.0)

        def shift(record: IterationRecord, used: int = used, elapsed: float = elapsed) -> IterationRecord:
            """A record counted over all grids so far."""
            return dataclasses.replace(record, iteration=record.iteration + used, time_s=record.time_s + elapsed)

        # a stage before the last only provides a start: it stops on the looser ε, which stays fixed
        stage = options if last else dataclasses.replace(options, eps=options.eps * COARSE_EPS_FACTOR,
                                                         eps_floor=options.eps * COARSE_EPS_FACTOR)
        stage = dataclasses.replace(stage, max_iter=budget)
        shown = None if progress is None else (lambda record: progress(shift(record)))
        result = descend(functional, solver, search, stage, shown, start)
        shrunk_to.append((result.options["eps"], result.options["delta"]))
        history += [shift(record) for record in result.history]
        per_grid[index] += result.iterations
        earlier = [result] + ([_iterate(functional, start)] if from_stage and result.iterations else [])
        if result.status == Status.FAILED:
            if functional is not stages[-1]:
                result.message = f"on the grid of {count} nodes{' (band start)' if functional.signs != signs else ''}: {result.message}"
            break
    first = functional.initial_point()  # the returned iterate is never worse than the model's start
    if result.status != Status.FAILED and functional.objective(first) < result.objective:
        reached = result.message.partition("; ")[0]  # how the descent ended, not its diagnosis of that iterate
        result = descend(functional, solver, search, dataclasses.replace(options, max_iter=0), None, first)
        unmet = result.message.partition("; ")[2]  # the diagnosis of the start, which is returned
        result.status = Status.STATIONARY
        result.message = (f"{reached}; the model's start is better than the iterate reached: returned unchanged"
                          + (f"; {unmet}" if unmet else ""))
    result.history = history
    functional, result = _certify(functional, result, solver, search, options, progress, estimate,
                                  target if refining else None, target, certificate, max_nodes, requested, starts)
    result.iterations = result.history[-1].iteration
    result.wall_time_s = time.perf_counter() - clock
    refined = result.options.pop("meshes", [])  # (nodes, iterations) of each mesh an accuracy request solved on
    shrunk_to += result.options.pop("shrunk_to", [])
    grids, per_grid = grids + [count for count, _ in refined], per_grid + [used for _, used in refined]
    # the smallest ε (and its δ) of the solve's descents: where the paper's method got to
    eps_reached, delta_reached = min(shrunk_to) if shrunk_to else (options.eps, options.delta)
    result.options = {**result.options, "eps": eps_reached, "delta": delta_reached, "max_iter": options.max_iter,
                      "start": first_start,
                      "grids": grids, "iterations_per_grid": per_grid,
                      "scheme": functional.grid.scheme.name, "signs": signs, "selection_scale": selection_scale,
                      "uniform": functional.grid.uniform}
    spent = ", ".join(f"{count} nodes {used}" for count, used in zip(grids, per_grid))
    if result.status == Status.MAX_ITER:  # the whole budget, and any remark of the last descent after "; "
        remark = result.message.partition("; ")[2]
        result.message = (f"{options.max_iter} iterations spent" + (f": {spent}" if len(grids) > 1 else "")
                          + (f"; {remark}" if remark else ""))
    elif result.status != Status.SOLVED and len(grids) > 1:
        result.message += f"; {result.iterations} iterations: {spent}"
    return result


DEFAULT_ACCURACY = 1e-6  # the target when none is given: max|x − x*| ≤ 1e-6·max(1, max|x|)
DEFAULT_MAX_ITER = 500  # max_iter=None on a fixed grid (a certified solve: the direction's certified_max_iter)
DEFAULT_NODES = 101  # the paper's tables and the benchmarks' fixed grids (`nodes` is required for one)
ACCURACY_START_NODES = 21  # `nodes` when not given under `accuracy`: the first mesh, refined from there
ACCURACY_SCHEME = "radau-iia"  # the scheme of an accuracy request that names none: order 3
BOOTSTRAP_SCHEME = "implicit-euler"  # an accuracy request's first solves: finds the switches robustly


def _mesh_times(mesh: Sequence[float] | np.ndarray, T: float) -> np.ndarray:
    """The user's mesh as an array checked against the model's horizon."""
    try:
        tau = np.asarray(mesh, dtype=float)
    except (TypeError, ValueError):
        raise InputError("mesh", "increasing mesh times from 0 to T", mesh) from None
    if tau.ndim != 1 or tau.size < 2 or tau[0] != 0.0 or not np.isclose(tau[-1], T, rtol=1e-14, atol=0.0):
        raise InputError("mesh", f"increasing mesh times from 0 to T = {T:g}", f"shape {tau.shape}" if tau.ndim != 1
                         else f"[{tau[0]:g}, …, {tau[-1]:g}]")
    tau = tau.copy()
    tau[-1] = T
    return tau


def _certify(functional: Functional, result: SolveResult, solver: DirectionSolver, search: LineSearch,
             options: DescentOptions, progress: ProgressCallback | None, wanted: bool, accuracy: float | None,
             target: float, certificate: str | None, max_nodes: int,
             scheme: str | Scheme, starts: Starts | None = None) -> tuple[Functional, SolveResult]:
    """The result with its switch times, its error estimate and its status against the
    target: under `accuracy`, refined until the estimate meets it (:func:`adaptive.to_accuracy`),
    else on its fixed grid (:func:`adaptive.on_fixed_grid`). `solved` stays only where the
    estimate is ≤ target·max(1, max|x|); a discrete solve whose estimate is larger, or that
    has none, is `uncertified`. Every descent appends to the history."""
    history, meshes, shrunk_to = result.history, [], []
    companion_solver, companion_search = make_direction("gauss-newton"), make_line_search("armijo")

    def run(target_functional: Functional, previous: SolveResult, own: bool) -> SolveResult:
        """A descent on `target_functional` from `previous` interpolated: the user's solver
        (`own`, counted in the history) or gauss-newton for the estimate's bisected grid."""
        used = history[-1].iteration
        budget = max(options.max_iter - used, 0) if own else COMPANION_ITERATIONS
        stage = dataclasses.replace(options, max_iter=budget)
        shown = None if progress is None or not own else (
            lambda record: progress(dataclasses.replace(record, iteration=record.iteration + used)))
        start = _interpolate(target_functional, previous)
        label, motion = starts.best(target_functional) if starts is not None else (MODEL, None)
        if label != MODEL and target_functional.objective(motion) < target_functional.objective(start):
            start = motion  # the model's motion sampled here is nearer than the last mesh's solution
        out = descend(target_functional, solver if own else companion_solver, search if own else companion_search,
                      stage, shown, start)
        if own:
            meshes.append((target_functional.grid.nodes, out.iterations))
            shrunk_to.append((out.options["eps"], out.options["delta"]))
            elapsed = history[-1].time_s
            history.extend(dataclasses.replace(r, iteration=r.iteration + used, time_s=r.time_s + elapsed)
                           for r in out.history)
        return out

    own, companion = (lambda f, r: run(f, r, True)), (lambda f, r: run(f, r, False))
    if accuracy is not None:
        outcome = adaptive.to_accuracy(functional, result, own, companion, accuracy, scheme, certificate, max_nodes)
    else:
        outcome = adaptive.on_fixed_grid(functional, result, companion, certificate, wanted, target)
    functional, result, found = outcome.functional, outcome.result, outcome.estimate
    result.history = history
    result.error_estimate = found.value
    result.certificate = found.certificate if found.value is not None else None
    result.accuracy = target
    solved = result.status == Status.SOLVED  # the discrete problem: every pointwise check passes
    result.switch_times = switches.switch_times(functional, adaptive.iterate(functional, result)) if solved \
        else np.zeros(0)
    note = outcome.note
    if solved:
        bound = adaptive.tolerance(target, result, functional)
        if found.value is None:
            result.status = Status.UNCERTIFIED
            reason = found.detail or "no error estimate"
            note = _join(note, f"the discrete problem is solved on {result.nodes} points, but its error is not "
                               f"certified: {reason}" + ("" if accuracy is not None else
                                                         f"; more nodes, or accuracy={target:g}"))
        elif found.value > bound:
            result.status = Status.UNCERTIFIED
            note = _join(note, f"the discrete problem is solved on {result.nodes} points, but its error estimate "
                               f"{found.value:.1e} ({found.certificate}) exceeds the target {bound:.1e}"
                         + ("" if accuracy is not None else f": more nodes, or accuracy={target:g}"))
        else:
            note = _join(f"error estimate {found.value:.1e} ({found.certificate}) ≤ target {bound:.1e}", note)
            if found.detail:
                note = _join(note, found.detail)
            if found.switch_times is not None:  # certified, and its replay is the solution: that motion's events
                result.switch_times = switches.polish(result.switch_times, found.switch_times,
                                                      functional.grid.mesh_times)
    result.options = {**result.options, "estimate_time_s": outcome.seconds, "shrunk_to": shrunk_to}
    if accuracy is not None:
        result.options = {**result.options, "accuracy": accuracy, "max_nodes": max_nodes, "meshes": meshes}
    if note:
        result.message = _join(result.message, note)
    return functional, result


def _join(*parts: str) -> str:
    """The non-empty parts of a message, joined by "; "."""
    return "; ".join(part for part in parts if part)


COMPANION_ITERATIONS = 100  # the budget of the estimate's solve on the bisected grid


COARSEST_NODES = 11  # step T/10, the paper's final step in Section 7
BAND_START_ITERATIONS = 10  # at most this many iterations of the band start of an exact solve
COARSE_EPS_FACTOR = 10  # a stage that only starts a later one stops when every node's deviation is ≤ 10·ε


def grid_schedule(nodes: int, continuation: Sequence[int] | str, coarsest: int = COARSEST_NODES,
                  steps: Sequence[int] = (1,)) -> list[int]:
    """The grids a solve runs on, coarsest first, ending with `nodes`.

    "auto": `coarsest` (11: step T/10) intervals times each of `steps` per decade, below
    `nodes`: 11, 101, 1001, … with steps (1,); 101, 301, 1001, 3001, … from 101 with
    steps (1, 3) (gauss-newton's: a switch found on one grid is at most a few nodes off on
    the next, and semismooth Newton moves it about one node per iteration); "none" or ():
    `nodes` alone; a sequence: those node counts (increasing, below `nodes`), then `nodes`.
    Starting the paper's first-order descent from a coarse solution keeps its iteration
    count flat in N: on a fine grid alone the δ-active kinks of many nodes cut its steps.
    """
    if isinstance(continuation, str):
        if continuation == "auto":
            coarse, decade = [], coarsest - 1
            while decade + 1 < nodes:
                coarse += [decade * step + 1 for step in steps if decade * step + 1 < nodes]
                decade *= 10
            return coarse + [nodes]
        if continuation == "none":
            return [nodes]
        raise InputError("continuation", '"auto", "none" or increasing node counts', continuation)
    counts = list(continuation)
    if any(isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2 for n in counts):
        raise InputError("continuation", "node counts ≥ 2", tuple(continuation))
    grids = [int(n) for n in counts] + [nodes]
    if any(b <= a for a, b in zip(grids, grids[1:])):
        raise InputError("continuation", f"increasing node counts below nodes = {nodes}", tuple(continuation))
    return grids


def _interpolate(functional: Functional, previous: SolveResult) -> np.ndarray:
    """The previous grid's x, z, u and λ on `functional`'s grid: by the previous scheme's own
    interpolants where its grid is known (x by the polynomial through each interval's
    points, z, u and λ by the scheme's rule for x′, λ clipped to [−1, 1]; a switch pinned
    on a mesh point is not smeared across it), else linearly."""
    t = functional.grid.t
    source = _source_grid(previous)
    if source is None:
        def on_grid(values: np.ndarray) -> np.ndarray:
            return np.stack([np.interp(t, previous.t, column) for column in values.T], axis=1)
        position = velocity = on_grid
    else:
        def position(values: np.ndarray) -> np.ndarray:
            return estimates.dense(source, values, t)

        def velocity(values: np.ndarray) -> np.ndarray:
            # at a point shared with the source's mesh, the value there (left-continuous like the rule)
            out = source.scheme.velocity(source.t, source.mesh, values, t)
            same = np.searchsorted(source.t, t).clip(0, source.t.size - 1)
            exact = source.t[same] == t
            out[exact] = values[same[exact]]
            return out

    u = None if previous.u is None else velocity(previous.u)
    selections = None if previous.selections is None else velocity(previous.selections)
    if selections is not None and source is not None:  # a polynomial may overshoot [−1, 1]
        selections = np.clip(selections, -1.0, 1.0)
    return functional.pack(position(previous.x), velocity(previous.z), u, selections)  # λ None: the band's


def _source_grid(previous: SolveResult) -> Grid | None:
    """The grid a result was solved on, where its points say it (its scheme's layout on the
    mesh of every `stages`-th point); None for anything else (a plain t)."""
    name = getattr(previous, "options", {}).get("scheme")
    if name is None:
        return None
    try:
        scheme = make_scheme(name)
        grid = Grid.from_mesh(np.asarray(previous.t)[:: scheme.stages], scheme)
    except Exception:  # noqa: BLE001 - not a layout of that scheme
        return None
    return grid if grid.t.shape == np.shape(previous.t) and np.allclose(grid.t, previous.t, rtol=0, atol=1e-12) else None


def _iterate(functional: Functional, xi: np.ndarray) -> SimpleNamespace:
    """ξ on `functional`'s grid as `_interpolate` reads a result: t, x, z, u, selections."""
    x, z = functional.split(xi)
    return SimpleNamespace(t=functional.grid.t, x=x, z=z, u=functional.controls(xi) if functional.m else None,
                           selections=functional.selections(xi) if functional.p else None)


def descend(
    functional: Functional,
    solver: DirectionSolver,
    search: LineSearch,
    options: DescentOptions,
    progress: ProgressCallback | None = None,
    start: np.ndarray | None = None,
) -> SolveResult:
    """Run the descent from `start` (default: the model's initial guess).

    x(t_0) = x0 where given (a start's row 0 is set to it); a NaN/inf of the model at an
    iterate raises ModelOutputError with the state there (:func:`_located`), one at a
    trial point of the line search only rejects that point (:func:`solve`).

    BLAS runs on one thread meanwhile (threadpoolctl): the work per call is a reduction
    over the nodes or a small per-node product, which a multi-threaded BLAS splits into
    pieces too small to pay for the threads, and stalls on when another process holds a
    core (`qdframe bench scale`, docs/benchmarks.md).
    """
    with threadpool_limits(limits=1, user_api="blas"):
        return _descend(functional, solver, search, options, progress, start)


def _descend(functional: Functional, solver: DirectionSolver, search: LineSearch, options: DescentOptions,
             progress: ProgressCallback | None, start: np.ndarray | None) -> SolveResult:
    clock = time.perf_counter()
    solver.start(functional)
    xi = functional.initial_point() if start is None else np.array(start, dtype=float)
    n, given = functional.n, functional.start_given
    xi[0, :n][given] = functional.model.x0[given]  # x0 is data, not an unknown: exactly
    try:
        terms = functional.terms(xi)
    except ModelOutputError as exc:
        raise _located(functional, xi, exc, "the start") from exc
    nodes = functional.grid.nodes
    # the start's record at the time its terms are known, so that each later record's time
    # minus the one before is that iteration alone (`qdframe bench scale`'s s/iter)
    history = [IterationRecord(0, terms.objective, terms.I, 0.0, 0.0, float("nan"), functional.boundary_error(xi),
                               time.perf_counter() - clock, nodes)]
    status, message = Status.MAX_ITER, f"{options.max_iter} iterations spent"
    weights = functional.weights
    rejected, rejected_label = 0, ""  # trial points where the model was NaN/inf, and the last piece named
    stalled: _Trial | None = None
    flooded: tuple[int, np.ndarray, ModelOutputError] | None = None  # the trial point that reached REJECTED_LIMIT
    uncertified: list[float] = []  # the worst check's value ÷ tolerance at each iterate with I ≤ tol
    watchdogs = 0  # full-step rounds tried where the descent stalled (:func:`_watchdog`)
    eps, delta = options.eps, options.delta  # shrunk where the iterate is ε-stationary but not solved
    window = CERTIFY_WINDOW if solver.full_steps else CERTIFY_WINDOW_FIRST_ORDER

    def escape() -> bool:
        """Where the descent would stop `stationary`: a watchdog round of full steps (for a
        solver whose steps are Newton steps, within the budget and WATCHDOG_ROUNDS); True
        when it found a much lower iterate, which the descent continues from."""
        nonlocal xi, terms, watchdogs
        budget = options.max_iter - (len(history) - 1)
        if not solver.full_steps or watchdogs >= WATCHDOG_ROUNDS or budget < 1:
            return False
        watchdogs += 1
        path = _watchdog(functional, solver, xi, terms.objective, options, min(WATCHDOG_STEPS, budget))
        if not path:
            return False
        for point, step in path:
            xi = point
            terms = functional.terms(xi)
            history.append(IterationRecord(len(history), terms.objective, terms.I, 1.0,
                                           float(np.sqrt(weights @ np.sum(step**2, axis=1))), float("nan"),
                                           functional.boundary_error(xi), time.perf_counter() - clock, nodes))
            if progress is not None:
                progress(history[-1])
        uncertified.clear()
        solver.start(functional)  # its kept state (the damping) belongs to the stalled iterate
        return True

    try:
        while True:
            iteration = len(history)
            if terms.objective <= options.tol and terms.I <= options.tol:
                found = certify.checks(functional, xi, options.residual_tol)
                if not certify.failures(found):
                    status, message = Status.SOLVED, ""
                    break
                uncertified.append(max(check.ratio for check in found))
                if (len(uncertified) > window
                        and uncertified[-1] * CERTIFY_SHRINK > uncertified[-1 - window]):
                    if escape():
                        continue
                    status, message = Status.STATIONARY, (f"the pointwise checks shrank by less than {CERTIFY_SHRINK:g}× in "
                                                     f"{window} iterations with I ≤ tol")
                    break
            if iteration > options.max_iter:
                break
            direction = solver.compute(functional, xi, delta)
            deviation = float(np.max(direction.deviation))
            if direction.stationary is None and deviation <= eps:
                if eps > options.eps_floor:  # ε-stationary, not solved: the paper's ε and δ shrink, the descent goes on
                    shrunk = max(eps / EPS_SHRINK, options.eps_floor)
                    eps, delta = shrunk, delta * shrunk / eps
                    uncertified.clear()
                    continue
                status, message = Status.STATIONARY, f"deviation {deviation:.2e} ≤ ε at every node"
                break
            if direction.stationary:
                if escape():
                    continue
                status, message = Status.STATIONARY, f"{solver.name}: no further decrease predicted"
                break
            step = _keep_start(functional, solver, direction.step)
            trials: list[_Trial] = []
            ray = functional.ray(xi, step)

            def along(gamma: float) -> float:
                """The objective at ξ + γG; +inf (no decrease) where the model is NaN/inf."""
                try:
                    value = ray(gamma)
                except ModelOutputError as exc:
                    if not exc.nonfinite:
                        raise
                    trials.append(_Trial(gamma, exc))
                    return np.inf
                trials.append(_Trial(gamma, None if np.isfinite(value) else ModelOutputError(
                    f"model {functional.model.name!r}: the objective overflows", nonfinite=True)))
                return value if np.isfinite(value) else np.inf

            gamma, value = search.search(along, terms.objective, direction.slope, options.gamma_max)
            bad = [trial for trial in trials if trial.error is not None]
            rejected += len(bad)
            rejected_label = bad[-1].error.label or rejected_label if bad else rejected_label
            if not (gamma > 0 and value < terms.objective):
                # non-finite within a rounding-sized move of ξ: the model, not stationarity, stops the descent
                near = NEAR_ITERATE * max(1.0, float(np.max(np.abs(xi)))) / max(float(np.max(np.abs(step))), 1e-300)
                blocking = [trial for trial in bad if trial.gamma <= near]
                if blocking:
                    stalled = min(blocking, key=lambda trial: trial.gamma)
                    break
                if escape():
                    continue
                status, message = Status.STATIONARY, "no step along the direction decreases the objective"
                break
            if rejected >= REJECTED_LIMIT and bad:  # the descent keeps stepping where the model is not defined: stop
                flooded = (iteration, xi + bad[-1].gamma * step, bad[-1].error)
                break
            xi = xi + gamma * step
            terms = functional.terms(xi)
            record = IterationRecord(
                iteration,
                terms.objective,
                terms.I,
                gamma,
                float(np.sqrt(weights @ np.sum(step**2, axis=1))),
                deviation,
                functional.boundary_error(xi),
                time.perf_counter() - clock,
                nodes,
            )
            history.append(record)
            if progress is not None:
                progress(record)
    except BackendError as exc:
        status, message = Status.FAILED, str(exc)
    except ModelOutputError as exc:  # at the accepted iterate (its gradients): nothing to return
        raise _located(functional, xi, exc, f"the iterate after {len(history) - 1} iterations") from exc
    if stalled is not None:
        move = stalled.gamma * float(np.max(np.abs(step)))
        raise _located(functional, xi, stalled.error, f"the iterate after {len(history) - 1} iterations",
                       f"a step of {move:.1e} from it along the direction is non-finite and no step decreases "
                       "the objective: the descent cannot continue") from stalled.error
    if flooded is not None:
        iteration, trial, error = flooded
        raise _located(functional, trial, error, f"a line-search trial point of iteration {iteration}",
                       f"{rejected} trial points rejected where the model is non-finite (the limit is {REJECTED_LIMIT}): "
                       "the descent keeps stepping where the model is not defined; make it finite there, or keep "
                       "the states away from it (in the sets, or by the start)") from error
    if eps < options.eps and status != Status.SOLVED:
        message += f"; ε and δ shrunk to {eps:.0e} and {delta:.0e}" + (" (the floor)" if eps <= options.eps_floor else "")
    if rejected and status != Status.SOLVED:
        message += (f"; {rejected} line-search trial point(s) rejected where the model is non-finite"
                    + (f" (last: {rejected_label})" if rejected_label else ""))
    return _result(functional, solver, search, dataclasses.replace(options, eps=eps, delta=delta), xi, status, message,
                   history, time.perf_counter() - clock)


def _watchdog(functional: Functional, solver: DirectionSolver, xi: np.ndarray, objective: float,
              options: DescentOptions, steps: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Full steps from ξ where the monotone descent stalled (the watchdog technique of
    Chamberlain, Powell, Lemaréchal and Pedersen, 1982): semismooth Newton next to a kink
    of the selections' natural map (a switch between two points of a fine grid) can need a
    step that raises I before the next ones lower it far below, which a line search that
    demands a decrease at every step never takes. From a fresh solver state (its damping
    reset), up to `steps` steps γ = 1: the path to the first solved iterate (I ≤ tol and
    every pointwise check passes), else to the lowest one if that is at most WATCHDOG_GAIN ×
    `objective`, else to the one with I ≤ tol whose pointwise checks are nearest their
    tolerances if CERTIFY_SHRINK× nearer than at ξ, else an empty list (the descent stops
    where it stalled)."""
    solver.start(functional)
    path: list[tuple[np.ndarray, np.ndarray]] = []
    best, best_at = objective, 0
    worst = _worst_ratio(functional, xi, objective, options)  # the checks' worst ratio where I ≤ tol
    nearer, nearer_at = worst / CERTIFY_SHRINK, 0
    point = xi
    try:
        for count in range(1, steps + 1):
            direction = solver.compute(functional, point, options.delta)
            if direction.stationary:
                break
            step = _keep_start(functional, solver, direction.step)
            point = point + step
            terms = functional.terms(point)
            if not np.isfinite(terms.objective):
                break
            path.append((point, step))
            ratio = _worst_ratio(functional, point, terms.objective if terms.I <= options.tol else np.inf, options)
            if ratio <= 1.0:
                return path  # solved there
            if ratio < nearer:
                nearer, nearer_at = ratio, count
            if terms.objective < best:
                best, best_at = terms.objective, count
    except (ModelOutputError, BackendError, np.linalg.LinAlgError):
        pass  # a full step left where the model or the step's solver is defined: not taken
    if best_at and best <= WATCHDOG_GAIN * objective:
        return path[:best_at]
    if nearer_at:  # I ≤ tol, the pointwise checks CERTIFY_SHRINK× nearer their tolerances
        return path[:nearer_at]
    return []


def _worst_ratio(functional: Functional, xi: np.ndarray, objective: float, options: DescentOptions) -> float:
    """The largest value ÷ tolerance of the pointwise checks at ξ where its objective is ≤ tol
    (≤ 1: solved), else inf."""
    if not objective <= options.tol:
        return np.inf
    return max(check.ratio for check in certify.checks(functional, xi, options.residual_tol))


@dataclass(frozen=True)
class _Trial:
    """A line-search trial step γ and, where the model was NaN/inf there, its error."""

    gamma: float
    error: ModelOutputError | None


# with I ≤ tol but a pointwise check failing, the descent goes on while the worst check's
# ratio to its tolerance shrinks by at least CERTIFY_SHRINK every CERTIFY_WINDOW iterations;
# slower than that (a residual left at a few nodes, shrinking a few % per step) it stops
# `stationary`. The window is long because the ratio falls in steps: semismooth Newton fixes
# a few nodes' selections per step, so on a fine grid (paper-7.3) the ratio can stay nearly
# flat for stretches of iterations before it falls, and a short window would stop a descent
# that is still on its way to certified.
CERTIFY_WINDOW = 40
CERTIFY_SHRINK = 4.0
CERTIFY_WINDOW_FIRST_ORDER = 400  # the paper's min-norm directions converge linearly: a longer window
EPS_SHRINK = 10.0  # ε and δ are divided by this where the iterate is ε-stationary but not solved
EPS_FLOOR = 1e-12  # the smallest ε of a certified solve (solve's eps_floor=None where the mesh is refined)
# where the descent would stop `stationary`, a solver whose steps are Newton steps (`full_steps`)
# gets up to WATCHDOG_ROUNDS rounds of WATCHDOG_STEPS full steps (:func:`_watchdog`), kept when
# they end WATCHDOG_GAIN lower (a long stick-slip horizon on a fine mesh stalls with one selection
# on the wrong side of a crossing, which a few full steps correct)
WATCHDOG_ROUNDS = 3
WATCHDOG_STEPS = 6
WATCHDOG_GAIN = 1e-2
NEAR_ITERATE = 1e-6  # a trial that moves ξ by at most this (relative, max-norm) is next to the iterate
# line-search trial points where the model is NaN/inf that a descent rejects before it stops with the
# last one's piece, node, t and state: a few are a line search overshooting into a region the model
# leaves undefined; thousands are a descent that keeps heading there (docs/guide.md, "Reliability").
# The limit sits above what a descent blocked next to the NaN region rejects before it stops with
# the error naming the iterate (tests/test_first_hour_api.py's NaN models)
REJECTED_LIMIT = 500
START_ROUNDING = 1e-9  # a direction's move of a given x(t_0), relative to max(1, ‖G‖∞), that is rounding


def _keep_start(functional: Functional, solver: DirectionSolver, step: np.ndarray) -> np.ndarray:
    """The step with exact zeros on the given x(t_0) (x0 is not an unknown).

    Directions that solve for the step with x(t_0) as a constraint (gauss-newton's QP)
    satisfy it only to rounding (~1e-15); more than START_ROUNDING is an error, not rounding.
    """
    given = functional.start_given
    moved = step[0, : functional.n][given]
    if not np.any(moved):
        return step
    size = float(np.max(np.abs(moved)))
    if not size <= START_ROUNDING * max(1.0, float(np.max(np.abs(step)))):
        raise BackendError(f"direction {getattr(solver, 'label', solver.name)!r} moved the given x(t_0) by {size:.2e}: "
                           "a direction must keep x(t_0) = x0")
    step = step.copy()
    step[0, : functional.n][given] = 0.0
    return step


def _located(functional: Functional, xi: np.ndarray, error: ModelOutputError, where: str,
             why: str = "") -> ModelOutputError:
    """`error` (a model's NaN/inf or wrong shape) as one line naming the piece, the node, t and
    the state (x, u) of the iterate `xi` at that node, as `check-model` names its points."""
    name = functional.model.name
    if not error.nonfinite or error.label is None:
        return ModelOutputError(f"{error} (at {where})" + (f"; {why}" if why else ""), label=error.label,
                                node=error.node, nonfinite=error.nonfinite)
    text = f"model {name!r}: {error.label} is non-finite"
    if error.node is not None:
        node = error.node
        names = list(functional.model.state_names) + list(functional.model.control_names)
        state = ", ".join(f"{label} = {value:.6g}" for label, value in zip(names, functional.arguments(xi)[node]))
        text += f" at node {node} (t = {functional.grid.t[node]:.6g}) of {where}, where ({state})"
    else:
        text += f" at {where}"
    return ModelOutputError(text + (f"; {why}" if why else ""), label=error.label, node=error.node, nonfinite=True)


def _residuals_disagree(functional: Functional, residuals, I: float) -> str:
    """What I ≤ tol implies for each residual, checked (empty when all agree).

    χ ≤ I gives |x0 + ∫z − xT| ≤ √(2I); φ, υ, ω ≤ I give, at any node k,
    h, |x − x0 − ∫z|, ‖e‖ ≤ √(2I/w_k); the boundary error read from x adds υ's at T.
    """
    slack = 1.0 + 1e-6
    pointwise = np.sqrt(2.0 * I / np.min(functional.weights)) * slack + 1e-300
    checks = [
        ("boundary error", residuals.boundary_error, np.sqrt(2.0 * I) * slack + pointwise),
        ("inclusion residual", residuals.inclusion_residual, pointwise),
        ("consistency error", residuals.consistency_error, pointwise),
        ("surface error", residuals.surface_error or 0.0, pointwise),
        # σ's natural map with scale c bounds the one with c = 1: min(1, c)·|r_1| ≤ |r_c|
        ("selection residual", residuals.selection_residual or 0.0, pointwise / min(1.0, functional.selection_scale)),
    ]
    return ", ".join(f"{name} {value:.2e} > {bound:.2e}" for name, value, bound in checks if value > bound)


def _result(functional, solver, search, options, xi, status, message, history, elapsed) -> SolveResult:
    model = functional.model
    terms = functional.terms(xi)
    residuals = functional.residuals(xi)
    if status == Status.SOLVED:
        disagreement = _residuals_disagree(functional, residuals, terms.I)
        if disagreement:
            status, message = Status.FAILED, f"I = {terms.I:.2e} ≤ tol but {disagreement}: an internal inconsistency"
    found = certify.checks(functional, xi, options.residual_tol)
    if status != Status.SOLVED and terms.objective <= options.tol and terms.I <= options.tol:
        message += f"; I = {terms.I:.1e} ≤ tol but not pointwise: {certify.failures(found)}"
    if status in (Status.STATIONARY, Status.MAX_ITER) and terms.I > options.tol:  # I bounded away from 0: name where it sits
        diagnosis = unmet_conditions(functional, xi, options.residual_tol)
        message += f"; {diagnosis}" if diagnosis else ""
    x, z = functional.split(xi)
    with plugin_code(model, "exact_solution()"):
        exact = model.exact_solution(functional.grid.t)
    solution_error = None if exact is None else float(np.max(np.abs(x - exact)))
    bounds = [
        None if b is None else {"coordinate": block.coords[0], "lower": b[0], "upper": b[1]}
        for block, b in zip(functional.blocks, functional.set_bounds(xi))
    ]
    return SolveResult(
        model=model.name,
        direction=getattr(solver, "label", solver.name),
        line_search=search.name,
        nodes=functional.grid.nodes,
        T=model.T,
        status=status,
        message=message,
        iterations=len(history) - 1,
        wall_time_s=elapsed,
        objective=terms.objective,
        I=terms.I,
        terms={"phi": terms.phi, "chi": terms.chi, "omega": terms.omega, "upsilon": terms.upsilon, "sigma": terms.sigma},
        cost=terms.cost if functional.cost is not None else None,
        boundary_error=residuals.boundary_error,
        inclusion_residual=residuals.inclusion_residual,
        surface_error=residuals.surface_error,
        consistency_error=residuals.consistency_error,
        selection_residual=residuals.selection_residual,
        solution_error=solution_error,
        t=functional.grid.t,
        x=x,
        z=z,
        u=functional.controls(xi) if functional.m else None,
        selections=functional.selections(xi) if functional.p else None,
        selection_names=list(functional.selection_names),
        state_names=tuple(model.state_names),
        control_names=tuple(model.control_names),
        set_bounds=bounds,
        options={
            "scheme": functional.grid.scheme.name,
            "max_iter": options.max_iter,
            "tol": options.tol,
            "delta": options.delta,
            "eps": options.eps,
            "gamma_max": options.gamma_max,
            "residual_tol": options.residual_tol,
        },
        history=list(history),
        checks={check.name: {"value": check.value, "tol": check.tol} for check in found},
        binding_check=certify.binding(found),
    )
