"""The grids of a solve and a descent on each: a :class:`~qdframe.solve.plan.Plan` made
concrete for one model (:func:`staged`: the first mesh, the continuation ladder below it, a
functional each, the starts on offer) and the descents on them, coarsest first
(:func:`run_grids`), each from the lowest start on offer there.

`continuation` lists coarser grids to solve on first (e.g. (11, 101) before nodes=1001):
each grid's result, interpolated, starts the next. "auto" is the ladder 11, 101, 1001, …
below `nodes` (:func:`~qdframe.solve.continuation.grid_schedule`), "none" (or ()) the one
grid, None the direction's own (`default_continuation`: "auto" from the direction's
`coarsest_nodes` with its `ladder_steps`: 11, 101, 1001, … for the paper's min-norm
directions, 101, 301, 1001, 3001, … for gauss-newton), and none where the model's motion
starts the requested grid. Each grid starts from the lowest, on that grid, of the previous
stage's iterate, the start that stage had (if it came from a stage) and the model's own
start. `max_iter` is the budget of all G grids together: a coarser grid spends at most
max(1, max_iter // (2G)) (its band start included) and leaves one iteration to each later
grid, so the requested grid gets the rest: at least half when max_iter ≥ 2G and ≥ 1 when
max_iter ≥ 1 (a coarse grid left no iteration is skipped). A stage before the last only
provides a start and stops on 10·ε. The history and `iterations` cover all grids, each
record naming its grid (`nodes`); each grid after the first adds a record of its start
(same iteration number); `options["iterations_per_grid"]` is aligned with
`options["grids"]`, and a status other than `solved` after several grids says so."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..descent import multipliers
from ..descent.loop import DescentOptions, ProgressCallback, descend
from ..directions.base import DirectionSolver
from ..functional import Functional
from ..line_searches.base import LineSearch
from ..model import InclusionModel
from ..result import IterationRecord, SolveResult
from ..schemes import Scheme
from ..schemes.grid import Grid
from ..status import Status
from .continuation import BAND_START_ITERATIONS, COARSE_EPS_FACTOR, grid_schedule, interpolate, iterate_view
from .plan import Plan, mesh_times
from .start import MODEL, Starts


@dataclass
class Staged:
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


def staged(model: InclusionModel, plan: Plan) -> Staged:
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
    return Staged(plan, grids, stages, starts)


@dataclass
class Run:
    """The descents on a plan's grids: the last functional and result, the history over all
    grids, the iterations per grid, the (ε, δ) each descent ended with, the first start."""

    functional: Functional
    result: SolveResult
    per_grid: list[int]
    shrunk_to: list[tuple[float, float]]
    first_start: str


def run_grids(plan: Staged, progress: ProgressCallback | None) -> Run:
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
    previous = None  # the last grid's functional
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
        if previous is not None:  # a cost's λ and shifts from the stage before (starts compared at them)
            functional.take_multipliers(previous)
        label, start, source = lowest_start(plan.starts, functional, earlier)
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
        previous = functional
        shrunk_to.append((result.descent.eps, result.descent.delta))
        history += [shift(record) for record in result.history]
        per_grid[index] += result.iterations
        earlier = [result] + ([iterate_view(functional, start)] if from_stage and result.iterations else [])
        if result.status == Status.FAILED:
            if not last:
                band = " (band start)" if functional.signs != plan.signs else ""
                result.reason = f"on the grid of {count} nodes{band}: {result.reason}"
            break
    result = not_worse_than_start(functional, plan, result)
    result.history = history
    return Run(functional, result, per_grid, shrunk_to, first_start)


def stalled(plan: Staged, run: Run) -> bool:
    """Whether a Newton-type descent stopped at a local minimum of I (`stationary` with I > tol;
    with a cost, of its augmented Lagrangian, :mod:`qdframe.descent.multipliers`; a cost whose
    penalty is raised restarts on its own, :mod:`qdframe.solve.optimum`)."""
    return (plan.solver.full_steps and run.result.status == Status.STATIONARY
            and run.result.I > plan.options.tol
            and (run.functional.cost is None or multipliers.applies(run.functional, plan.solver)))


def again(plan: Staged, run: Run, again: Staged, label: str, whence: str,
           progress: ProgressCallback | None) -> tuple[Staged, Run]:
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
    second = run_grids(dataclasses.replace(again, plan=budget), shown)
    if not (second.result.status in (Status.SOLVED, Status.UNCERTIFIED) or second.result.objective < run.result.objective):
        run.result.remarks.append(f"from {whence} too, it ended {second.result.status}, no lower")
        return plan, run
    second.result.history = run.result.history + [dataclasses.replace(
        record, iteration=record.iteration + used, time_s=record.time_s + elapsed) for record in second.result.history]
    per_grid = list(second.per_grid)
    for count, spent in zip(plan.grids, run.per_grid):  # the first run's iterations, on the grids both ran
        if count in again.grids:
            per_grid[again.grids.index(count)] += spent
    return again, Run(second.functional, second.result, per_grid, run.shrunk_to + second.shrunk_to, label)


def lowest_start(starts: Starts, functional: Functional,
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


def not_worse_than_start(functional: Functional, plan: Staged, result: SolveResult) -> SolveResult:
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
