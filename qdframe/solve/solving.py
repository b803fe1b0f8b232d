"""`qdframe.solve`, the call a user makes: a plan (:mod:`qdframe.solve.plan`: the arguments
checked, the one rule that sets the defaults), the grids and a descent on each
(:mod:`qdframe.solve.grids`), the ladder of second chances (:mod:`qdframe.solve.ladder`),
the verdict (:mod:`qdframe.solve.verdict`), and the result finished in one place."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence

import numpy as np

from .. import unknowns
from ..descent.loop import ProgressCallback
from ..directions.base import DirectionSolver
from ..functional import Functional
from ..line_searches.base import LineSearch
from ..model import InclusionModel
from ..registry import load_model
from ..result import SolveResult
from ..schemes import Scheme
from ..status import Status
from . import optimum
from .grids import Run, Staged, run_grids, staged
from .ladder import LADDER, Attempt, FreeInputs
from .plan import Plan, plan
from .start import swept_T
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
    """The solve of `model` by `chosen`: the grids and the ladder of second chances, the
    verdict, and after it the free inputs' second chance; the result finished in one place."""
    if model.has_unknowns:  # T or p found with x: the model on s = t/T with constant states
        return _with_unknowns(model, chosen, progress, clock)
    attempt, functional, result = _verdict(_attempt(model, chosen, progress))
    retry = FreeInputs()
    if retry.applies(attempt, functional, result):
        held = result.status
        attempt, functional, result = _verdict(_attempt(model, retry.plan(attempt), progress))
        result.remarks.append(retry.remark.format(status=held))
    result.wall_time_s = time.perf_counter() - clock
    return result


def _attempt(model: InclusionModel, chosen: Plan, progress: ProgressCallback | None) -> Attempt:
    """The grids of `chosen` on `model`, then each stage of the ladder that applies, in turn."""
    plan = staged(model, chosen)
    attempt = Attempt(model, chosen, plan, run_grids(plan, progress), progress)
    for stage in LADDER:
        if stage.applies(attempt):
            attempt = stage.apply(attempt)
    return attempt


def _verdict(attempt: Attempt) -> tuple[Attempt, Functional, SolveResult]:
    """The attempt's last trajectory certified (:func:`qdframe.solve.verdict.certify_result`),
    the cost's rounds counted in, summarized."""
    plan, run = attempt.staged, attempt.run
    chosen = attempt.plan
    functional, result = certify_result(run.functional, run.result, plan.solver, plan.search, plan.options,
                                        attempt.progress, chosen.estimate, plan.target if plan.refining else None,
                                        plan.target, chosen.certificate, chosen.max_nodes, plan.requested, plan.starts)
    if attempt.rounds:
        _penalty_verdict(functional, result, attempt.rounds, plan.target)
    result.iterations = result.history[-1].iteration
    return attempt, functional, _summarized(plan, run, functional, result)


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


def _summarized(plan: Staged, run: Run, functional: Functional, result: SolveResult) -> SolveResult:
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
