"""`qdframe.solve`, the call a user makes: the model and its unknowns, the arguments checked,
the grids (a continuation ladder, or a mesh refined to an accuracy), the start of each grid,
the descent on each (:mod:`qdframe.descent.loop`) and the verdict on the last
(:mod:`qdframe.solve.verdict`)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from . import optimum
from .. import unknowns
from .continuation import BAND_START_ITERATIONS, COARSE_EPS_FACTOR, grid_schedule, interpolate, iterate_view
from ..descent.loop import DescentOptions, ProgressCallback, descend
from ..directions.base import DirectionSolver
from ..functional import Functional
from ..line_searches.base import LineSearch
from ..model import InclusionModel
from ..registry import load_model
from ..result import IterationRecord, SolveResult
from ..schemes import Scheme
from ..schemes.grid import Grid
from ..status import Status
from .plan import Plan, mesh_times, plan
from .start import LINE, MODEL, SIMULATED, LineStarts, Starts, swept_T
from .unwrap import unwrap
from .verdict import certify_result


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
    inputs: str = "held",
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

    `direction` "gauss-newton" (the default) or "native" (the paper's method), or any registered name or
    DirectionSolver; `line_search` likewise, by default the direction's own (armijo, golden).

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
    10·ε. The history and `iterations` cover all grids, each record naming its grid (`nodes`); each grid
    after the first adds a record of its start (same iteration number); `options["iterations_per_grid"]`
    is aligned with `options["grids"]`, and a status other than `solved` after several grids says so.

    `scheme` discretizes x' = z (:mod:`qdframe.schemes`: "trapezoid", the paper's; "implicit-euler";
    "radau-iia", where `nodes` counts mesh and stage points and is odd); None is the model's
    `default_scheme` (implicit Euler unless the model says otherwise). `signs` "exact" gives every sign
    term a·Sgn(s) a selection λ ∈ [−1, 1] per node tied to s by the natural map λ = clip(λ + c·s, −1, 1),
    c = `selection_scale` (the result's `selections`); "band" uses each term's C¹ band instead. `inputs`
    "held" keeps the choice in each fixed set (a bounded input) one per mesh interval of radau-iia
    (:mod:`qdframe.functional.held`); "free" lets every point choose.

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
    bisected mesh (:mod:`qdframe.solve.adaptive`; `estimate=False` skips it: None), and
    `switch_times`, where a Filippov selection changes regime (:mod:`qdframe.certificates.switches`).
    `accuracy` asks for error_estimate ≤ accuracy: mesh points are moved onto the switch
    times and the mesh is refined where the estimate is large, up to `max_nodes` points;
    with `accuracy` and no `scheme` the scheme is radau-iia (order 3).
    """
    clock = time.perf_counter()
    if isinstance(model, str):
        model = load_model(model)
    if free_T is not None or parameters:  # a copy with T free or fixed, or other guesses of p
        model = unknowns.restated(model, free_T, parameters)
    chosen = plan(model, nodes, direction, line_search, max_iter=max_iter, tol=tol, delta=delta, eps=eps,
                  gamma_max=gamma_max, residual_tol=residual_tol, eps_floor=eps_floor, continuation=continuation,
                  scheme=scheme, signs=signs, selection_scale=selection_scale, inputs=inputs, mesh=mesh,
                  estimate=estimate, accuracy=accuracy, max_nodes=max_nodes, certificate=certificate,
                  simulate_start=simulate_start)
    return _solve(model, chosen, progress, clock)


def _solve(model: InclusionModel, chosen: Plan, progress: ProgressCallback | None, clock: float) -> SolveResult:
    """The solve of `model` by `chosen`: the grids, the second chances, the verdict."""
    if model.has_unknowns:  # T or p found with x: the model on s = t/T with constant states
        return _with_unknowns(model, chosen, progress, clock)

    def planned(model: InclusionModel, simulate: bool = chosen.simulate_start) -> _Staged:
        return _staged(model, dataclasses.replace(chosen, simulate_start=simulate))

    plan = planned(model)
    run = _run_grids(plan, progress)
    if run.first_start == SIMULATED and _stalled(plan, run):
        plan, run = _from_the_model(plan, run, planned(model, simulate=False), progress)
    if run.first_start == MODEL and _stalled(plan, run):
        run = _from_the_line(model, plan, run, progress)
    rounds: list[optimum.Round] = []
    if run.functional.cost is not None:  # a cost: λ raised until the minimizer is a solution (qdframe.solve.optimum)
        plan, run, rounds = _raised_penalty(model, plan, run, planned, progress)
    functional, result = certify_result(run.functional, run.result, plan.solver, plan.search, plan.options, progress,
                                        chosen.estimate, plan.target if plan.refining else None, plan.target,
                                        chosen.certificate, chosen.max_nodes, plan.requested, plan.starts)
    if rounds:
        _penalty_verdict(functional, result, rounds, plan.target)
    result.iterations = result.history[-1].iteration
    result.wall_time_s = time.perf_counter() - clock
    result = _summarized(plan, run, functional, result)
    return _free_instead(plan, functional, result,
                         lambda: _solve(model, dataclasses.replace(chosen, inputs="free"), progress, clock), clock)


def _with_unknowns(model: InclusionModel, chosen: Plan, progress: ProgressCallback | None, clock: float) -> SolveResult:
    """The solve of a model with T or parameters unknown: its wrapper on s = t/T, unwrapped."""
    wrapper = unknowns.Unknowns(model)
    if wrapper.scaled and np.all(np.isfinite(model.x0)) and not wrapper.n_controls:  # a better first T
        wrapper.T0 = swept_T(wrapper)
    if chosen.mesh is not None and model.free_T:  # the mesh on s = t/T
        chosen = dataclasses.replace(chosen, mesh=tuple(np.asarray(chosen.mesh) / model.T))
    result = unwrap(wrapper, _solve(wrapper, chosen, progress, time.perf_counter()))
    result.wall_time_s = time.perf_counter() - clock
    return result


def _free_instead(plan: "_Staged", functional: Functional, result: SolveResult, free: Callable[[], SolveResult],
                  clock: float) -> SolveResult:
    """`result`, or where its last functional held the inputs and a Newton-type descent ended
    `stationary` there (no held choice meets the problem: one cannot follow a surface that
    moves the state within an interval), the solve with each point's own choice (`free()`),
    saying so. (A first-order method's stationary or max_iter says nothing of the held choice.)"""
    if functional.held is None or result.status != Status.STATIONARY or not plan.solver.full_steps:
        return result
    retried = free()
    retried.remarks.append(f"with the inputs held the solve ended {result.status}: each point chose its own "
                           f"(inputs=\"free\")")
    retried.wall_time_s = time.perf_counter() - clock
    return retried


def _raised_penalty(model: InclusionModel, plan: _Staged, run: _Run, planned, progress) -> tuple[_Staged, _Run, list]:
    """The rounds of ∫cost + λ·I with λ raised (:func:`qdframe.solve.optimum.raise_penalty`), the
    last round's plan and run; its history is every round's, counted on."""
    last = {"plan": plan, "run": run}
    history = list(run.result.history)

    def rerun(model: InclusionModel) -> tuple[Functional, SolveResult]:
        last["plan"] = planned(model)
        last["run"] = _run_grids(last["plan"], progress)
        used, elapsed = history[-1].iteration, history[-1].time_s
        history.extend(dataclasses.replace(record, iteration=record.iteration + used, time_s=record.time_s + elapsed)
                       for record in last["run"].result.history)
        return last["run"].functional, last["run"].result

    def target(result: SolveResult) -> float:
        return plan.target * model.accuracy_scale(result.x)

    rounds = optimum.raise_penalty(model, (run.functional, run.result), target, plan.options.tol, rerun)
    last["run"].result.history = history
    return last["plan"], last["run"], rounds


def _penalty_verdict(functional: Functional, result: SolveResult, rounds: list, target: float) -> None:
    """The penalty's part added to the error estimate, the gap and the rounds in the options,
    and `solved` withdrawn where the sum passes the target."""
    weight = rounds[-1].weight
    extra = optimum.penalty_error(rounds)
    result.options = {**result.options, "penalty": weight, "optimality_gap": optimum.gap(result, weight),
                      "penalty_rounds": [(r.weight, r.iterations) for r in rounds]}
    if result.error_estimate is not None:
        result.error_estimate += extra
    if result.status == Status.SOLVED:
        bound = target * functional.model.accuracy_scale(result.x)
        if result.error_estimate is not None and result.error_estimate > bound:
            result.status = Status.UNCERTIFIED
            result.remarks.append(f"with the penalty's part {extra:.1e} the error estimate "
                                  f"{result.error_estimate:.1e} exceeds the target {bound:.1e}")
        elif len(rounds) > 1:  # (one round: the cost's minimum reached with the model's λ, nothing to add)
            result.remarks.append(f"an optimum of the cost: gap {optimum.gap(result, weight):.1e} (2λ·I, "
                                  f"λ = {weight:.0e}), penalty's part of the estimate {extra:.1e}")


@dataclass
class _Staged:
    """A plan made concrete for one model: the grids in turn (each a functional; the first one
    also with the band where signs are exact), and the starts on offer."""

    plan: Plan
    grids: list[int]
    stages: list[Functional]
    starts: Starts

    @property
    def options(self) -> DescentOptions:
        return self.plan.options

    @property
    def solver(self) -> DirectionSolver:
        return self.plan.direction

    @property
    def search(self) -> LineSearch:
        return self.plan.line_search

    @property
    def refining(self) -> bool:
        return self.plan.refining

    @property
    def target(self) -> float:
        return self.plan.target

    @property
    def requested(self) -> str | Scheme:
        return self.plan.scheme

    @property
    def signs(self) -> str:
        return self.plan.signs

    @property
    def selection_scale(self) -> float:
        return self.plan.selection_scale


def _staged(model: InclusionModel, plan: Plan) -> _Staged:
    """The grids of `plan` on `model`: its first mesh (from the model's motion where the plan
    says so and the model has one), the continuation ladder below it, a functional each."""
    starts = Starts(model, simulate=plan.simulate_start)
    mesh, scheme, continuation = plan.mesh, plan.first_scheme, plan.continuation
    if plan.from_motion:  # the first mesh: from the model's motion where it has one
        mesh = starts.mesh(plan.nodes - 1)
        if mesh is not None:  # the motion has the switches: no implicit-Euler bootstrap nor coarser grids to find them
            scheme = plan.scheme
            continuation = "none" if continuation is None else continuation
    final = Grid(model.T, plan.nodes, scheme) if mesh is None else Grid.from_mesh(mesh_times(mesh, model.T), scheme)
    solver = plan.direction
    if continuation is None and starts.motion() is not None:
        continuation = "none"  # the model's motion sampled on the requested grid starts it: no coarser grids
    grids = grid_schedule(final.nodes, solver.default_continuation if continuation is None else continuation,
                          solver.coarsest_nodes, solver.ladder_steps)
    # the functionals solved in turn: each grid, the first one also with the band if exact and
    # there is no motion to start from (its selections are the motion's modes, the band's are not)
    stages = []
    band = starts.motion() is None
    for count in grids:
        grid = final if count == final.nodes else Grid(model.T, count, scheme)
        functional = Functional(model, grid, signs=plan.signs, selection_scale=plan.selection_scale,
                                inputs=plan.inputs)
        if not stages and functional.p and band:
            stages.append(Functional(model, functional.grid, signs="band"))
        stages.append(functional)
    return _Staged(plan, grids, stages, starts)


@dataclass
class _Run:
    """The descents on a plan's grids: the last functional and result, the history over all
    grids, the iterations per grid, the (ε, δ) each descent ended with, the first start."""

    functional: Functional
    result: SolveResult
    per_grid: list[int]
    shrunk_to: list[tuple[float, float]]
    first_start: str


def _run_grids(plan: _Staged, progress: ProgressCallback | None) -> _Run:
    """One descent per grid, coarsest first, each from the lowest start on offer there.

    A coarser grid spends at most max(1, max_iter // (2G)) (its band start included) and
    leaves one iteration to each later grid; a stage before the last stops on 10·ε. The
    returned iterate is never worse than the model's start."""
    options, grids = plan.options, plan.grids
    history, result = [], None
    shrunk_to = []  # (ε, δ) each descent of the user's direction ended with (the paper's: shrunk, perhaps)
    first_start = MODEL
    earlier = []  # what may start the next stage: the last stage's iterate, and its start if that came from a stage
    per_grid = [0] * len(grids)  # iterations spent on each grid (a band start counts on its grid)
    share = max(1, options.max_iter // (2 * len(grids)))  # a coarse grid's cap: the requested grid keeps ≥ half
    for functional in plan.stages:
        count = functional.grid.nodes
        index = grids.index(count)
        last = functional is plan.stages[-1]
        later = len(grids) - 1 - index
        budget = options.max_iter - sum(per_grid) - later  # one iteration kept for each later grid
        if later:
            budget = min(budget, share - per_grid[index])
        if functional.signs != plan.signs:  # the band only starts the exact solve: a short run, one iteration left
            budget = min(budget - 1, BAND_START_ITERATIONS)
        if budget <= 0 and not last:  # no iteration here: no result from this grid
            continue
        label, start, source = _lowest_start(plan.starts, functional, earlier)
        from_stage = source is not None
        # a coarser grid's solution: its switches are a few nodes off here, which full steps pass
        near = getattr(source, "status", None) == Status.SOLVED and source.nodes < count
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
        result = descend(functional, plan.solver, plan.search, stage, shown, start, near_solution=near)
        shrunk_to.append((result.options["eps"], result.options["delta"]))
        history += [shift(record) for record in result.history]
        per_grid[index] += result.iterations
        earlier = [result] + ([iterate_view(functional, start)] if from_stage and result.iterations else [])
        if result.status == Status.FAILED:
            if not last:
                band = " (band start)" if functional.signs != plan.signs else ""
                result.reason = f"on the grid of {count} nodes{band}: {result.reason}"
            break
    result = _not_worse_than_start(functional, plan, result)
    result.history = history
    return _Run(functional, result, per_grid, shrunk_to, first_start)


def _stalled(plan: _Staged, run: _Run) -> bool:
    """Whether a Newton-type descent stopped at a local minimum of I (`stationary` with I > tol;
    a cost's rounds restart on their own, :mod:`qdframe.solve.optimum`)."""
    return (plan.solver.full_steps and run.functional.cost is None and run.result.status == Status.STATIONARY
            and run.result.I > plan.options.tol)


def _from_the_model(plan: _Staged, run: _Run, again: _Staged, progress: ProgressCallback | None) -> tuple[_Staged, _Run]:
    """Where the simulated start stopped at a local minimum of I: the solve again as if the
    model had no motion (`again`: the model's own start, its grids; :func:`_again`). A model
    with controls is simulated under its first controls, whose motion can sit next to a
    local minimum on a coarse grid (paper-7.3 on 11 and 101 points)."""
    return _again(plan, run, again, MODEL, "the model's own start", progress)


def _from_the_line(model: InclusionModel, plan: _Staged, run: _Run, progress: ProgressCallback | None) -> _Run:
    """Where the grids from the model's start (x ≡ x0, at rest) stopped at a local minimum of
    I: the grids again from the straight line between the given ends (:func:`_again`).
    paper-7.3 at N = 11: the model's start stops at a local minimum, the line is solved."""
    if not len(model.end_indices):
        return run
    return _again(plan, run, dataclasses.replace(plan, starts=LineStarts(model)), LINE,
                  "the straight line between the given ends", progress)[1]


def _again(plan: _Staged, run: _Run, again: _Staged, label: str, whence: str,
           progress: ProgressCallback | None) -> tuple[_Staged, _Run]:
    """`again` (another start, perhaps other grids) with the budget `run` left: its plan and
    run (started from `label`) where it ends solved or lower than `run`, its history after
    `run`'s and the iterations on the grids both ran added; else `plan` and `run`, with a
    remark that the start `whence` ended no lower."""
    used, elapsed = run.result.history[-1].iteration, run.result.history[-1].time_s
    left = plan.options.max_iter - used
    if left < 1:
        return plan, run
    shown = None if progress is None else (lambda record: progress(dataclasses.replace(
        record, iteration=record.iteration + used, time_s=record.time_s + elapsed)))
    # the budget left for these grids; the plan returned keeps the whole (the refinement after
    # it and the message count the iterations over the whole solve)
    budget = dataclasses.replace(again.plan, options=dataclasses.replace(again.options, max_iter=left))
    second = _run_grids(dataclasses.replace(again, plan=budget), shown)
    if not (second.result.status in (Status.SOLVED, Status.UNCERTIFIED) or second.result.objective < run.result.objective):
        run.result.remarks.append(f"from {whence} too, it ended {second.result.status}, no lower")
        return plan, run
    second.result.history = run.result.history + [dataclasses.replace(
        record, iteration=record.iteration + used, time_s=record.time_s + elapsed) for record in second.result.history]
    per_grid = list(second.per_grid)
    for count, spent in zip(plan.grids, run.per_grid):  # the first run's iterations, on the grids both ran
        if count in again.grids:
            per_grid[again.grids.index(count)] += spent
    return again, _Run(second.functional, second.result, per_grid, run.shrunk_to + second.shrunk_to, label)


def _lowest_start(starts: Starts, functional: Functional,
                  earlier: list) -> tuple[str, np.ndarray, SolveResult | None]:
    """The start of a grid: the lowest there of the earlier stages' iterates (the last one
    first on a tie) and the model's own start (or its simulated motion); its label, and
    the stage's result it came from (None: the model's start)."""
    label, start = starts.best(functional)
    source, lowest = None, np.inf
    if earlier:
        candidates = [interpolate(functional, result) for result in earlier] + [start]
        for number, candidate in enumerate(candidates):
            value = functional.objective(candidate)
            if number == 0 or value < lowest:
                start, lowest, source = candidate, value, earlier[number] if number < len(earlier) else None
    return label, start, source


def _not_worse_than_start(functional: Functional, plan: _Staged, result: SolveResult) -> SolveResult:
    """The result, or the model's start returned unchanged where it is lower than the
    iterate reached (status `stationary`, the message saying both)."""
    first = functional.initial_point()
    if result.status == Status.FAILED or not functional.objective(first) < result.objective:
        return result
    reached = result.reason  # how the descent ended, not its diagnosis of that iterate
    result = descend(functional, plan.solver, plan.search, dataclasses.replace(plan.options, max_iter=0), None, first)
    result.status = Status.STATIONARY
    result.reason = reached
    # then the diagnosis of the start, which is returned
    result.remarks = ["the model's start is better than the iterate reached: returned unchanged", *result.remarks]
    return result


def _summarized(plan: _Staged, run: _Run, functional: Functional, result: SolveResult) -> SolveResult:
    """The result's options over the whole solve (grids, iterations per grid, the smallest
    ε and δ reached, the start) and its message where it did not end `solved`."""
    options = plan.options
    refined = result.options.pop("meshes", [])  # (nodes, iterations) of each mesh an accuracy request solved on
    shrunk_to = run.shrunk_to + result.options.pop("shrunk_to", [])
    grids = plan.grids + [count for count, _ in refined]
    per_grid = run.per_grid + [used for _, used in refined]
    # the smallest ε (and its δ) of the solve's descents: where the paper's method got to
    eps_reached, delta_reached = min(shrunk_to) if shrunk_to else (options.eps, options.delta)
    result.options = {**result.options, "eps": eps_reached, "delta": delta_reached, "max_iter": options.max_iter,
                      "start": run.first_start, "grids": grids, "iterations_per_grid": per_grid,
                      "scheme": functional.grid.scheme.name, "signs": plan.signs,
                      "selection_scale": plan.selection_scale, "inputs": "held" if functional.held else "free",
                      "uniform": functional.grid.uniform}
    spent = ", ".join(f"{count} nodes {used}" for count, used in zip(grids, per_grid))
    if result.status == Status.MAX_ITER:  # the whole budget, over all grids
        result.reason = f"{options.max_iter} iterations spent" + (f": {spent}" if len(grids) > 1 else "")
    elif result.status != Status.SOLVED and len(grids) > 1:
        result.remarks.append(f"{result.iterations} iterations: {spent}")
    return result
