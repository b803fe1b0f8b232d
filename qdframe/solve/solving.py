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
from ..descent import multipliers
from ..descent.loop import ProgressCallback
from ..certificates.estimates import cost_estimate
from ..directions.base import DirectionSolver
from ..functional import Functional
from ..line_searches.base import LineSearch
from ..model import InclusionModel
from ..registry import load_model
from ..result import GridsRecord, PenaltyRecord, SolveResult
from ..schemes import Scheme
from ..status import Status
from . import optimum
from .grids import Run, Staged, run_grids, staged
from .ladder import LADDER, Attempt, FreeInputs
from .plan import Plan, plan
from .start import swept_candidates
from .unwrap import unwrap
from .verdict import Refined, certify_result

PERIOD_CANDIDATES = 3  # a period's solve tries at most this many of the sweep's first T's (nearest first)
PERIOD_FLOOR = 0.5  # … each with T bounded below by this share of its first T (T → 0 closes every period)


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
    residual_tol: float | None = None,
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
    """Find a trajectory of `model` by quasidifferential descent, certified to a target.

    One rule (:mod:`qdframe.solve.plan`, whose table it is) decides the kind of solve: given
    `accuracy`, or neither `nodes` nor `mesh`, the mesh is refined until the error estimate
    of max_t |x(t) − x*(t)| is ≤ accuracy·max(1, max|x|) (default 1e-6), from 21 points (or
    the model's simulated motion), by radau-iia after implicit Euler's first solves, up to
    `max_nodes`; otherwise the grid of `nodes` points (default 101) or the `mesh` times
    0 = τ_0 < … < τ_K = T is fixed, its estimate made once (`estimate=False` skips it).
    `qdframe.solve.plan(model, …)` returns that plan for the same arguments.

    `direction` "gauss-newton" (the default), "native" (the paper's method), any registered
    name or a DirectionSolver; `line_search` likewise (default: the direction's own).
    `continuation` the coarser grids solved first ("auto", "none", a list, or None: the
    direction's own; :mod:`qdframe.solve.grids` says how `max_iter`, the budget of the whole
    solve, is shared among them). `scheme` discretizes x' = z ("trapezoid", the paper's;
    "implicit-euler"; "radau-iia"; None: the plan's). `signs` "exact" gives every sign term
    a·Sgn(s) a selection λ ∈ [−1, 1] per node tied to s by the natural map with scale
    `selection_scale`; "band" uses each term's C¹ band. `inputs` "held" keeps the choice in
    each fixed set one per mesh interval of radau-iia; "free" lets every point choose.
    `certificate` "replay" or "bisection" (None: by the problem). `free_T` and `parameters`
    restate the model with T free or fixed, or other guesses of its unknown parameters.

    The descent (:mod:`qdframe.descent`) stops `solved` when the objective and I are ≤ `tol`
    (the model's default) and every pointwise check passes (`residual_tol`: 1e-8, and at most
    accuracy/100 when refining to a tighter target), `stationary`
    when it can go no further (the paper's δ, ε, γ̄ as `delta`, `eps`, `gamma_max`; ε and δ
    shrink down to `eps_floor`), `max_iter` when the budget is spent, `failed` when a
    backend reports an error. The verdict keeps `solved` only where the estimate meets the
    target (`uncertified` otherwise). A model non-finite at an accepted iterate raises
    ModelOutputError naming the piece, node, t and state. `progress` is called with each
    iteration's record; `wall_time_s` is the whole call.
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
    functional, result, refined = certify_result(run.functional, run.result, plan.plan, attempt.progress,
                                                 plan.starts)
    if attempt.rounds:
        _penalty_verdict(functional, result, attempt.rounds, plan.target, plan.options.residual_tol)
    if result.cost is not None:
        _cost_verdict(functional, result, refined.finer, plan.target)
    result.iterations = result.history[-1].iteration
    return attempt, functional, _summarized(plan, run, functional, result, refined)


def _with_unknowns(model: InclusionModel, chosen: Plan, progress: ProgressCallback | None, clock: float) -> SolveResult:
    """The solve of a model with T or parameters unknown: its wrapper on s = t/T, unwrapped."""
    wrapper = unknowns.Unknowns(model)
    candidates = [wrapper.T0]
    if wrapper.scaled and np.all(np.isfinite(model.x0)) and not wrapper.n_controls:  # a better first T
        candidates = swept_candidates(wrapper) or candidates
    if chosen.mesh is not None and model.free_T:  # the mesh on s = t/T
        chosen = dataclasses.replace(chosen, mesh=tuple(np.asarray(chosen.mesh) / model.T))
    # a period has several candidates (each half-period where a velocity alone is periodic): where
    # the solve from the nearest does not end solved, the next ones are tried (PERIOD_CANDIDATES),
    # each with T ≥ PERIOD_FLOOR of it where there are several (a stalled try is not drawn to T → 0;
    # a single one may be the trivial period itself, which the message then names: unwrap.SHRUNK)
    tries = candidates[:PERIOD_CANDIDATES] if wrapper.periodic else candidates[:1]
    first = None
    for T0 in tries:
        wrapper = unknowns.Unknowns(model)
        wrapper.T0 = T0
        if len(tries) > 1 and wrapper.time_bound.lo < PERIOD_FLOOR * T0:
            wrapper.time_bound = unknowns.Bound(PERIOD_FLOOR * T0, wrapper.time_bound.hi)
        result = unwrap(wrapper, _solve(wrapper, chosen, progress, time.perf_counter()))
        if result.status == Status.SOLVED:
            if first is not None:
                result.remarks.append(f"from the first T = {first.unknowns.T_start:.6g} of the sweep the solve "
                                      f"ended {first.status} (T = {first.T:.3g}); from T = {T0:.6g} it is solved")
            break
        first = first or result
    else:
        result = first
    result.wall_time_s = time.perf_counter() - clock
    return result


def _penalty_verdict(functional: Functional, result: SolveResult, rounds: list, target: float,
                     residual_tol: float) -> None:
    """The penalty's part added to the error estimate, the gap and the rounds in the options,
    and `solved` withdrawn where the sum passes the target."""
    weight = rounds[-1].weight
    extra = optimum.penalty_error(rounds)
    xi = functional.pack(result.x, result.z, result.u, result.selections)
    result.penalty = PenaltyRecord(weight, optimum.gap(result, weight), tuple((r.weight, r.iterations) for r in rounds),
                                   tolerance_share=multipliers.tolerance_share(functional, xi, residual_tol))
    if result.error_estimate is not None:
        grid = result.error_estimate
        result.error_estimate += extra
        said = f"error estimate {grid:.1e} ({result.certificate})"  # the verdict's words: the sum in their place
        result.remarks = [remark.replace(said, f"error estimate {result.error_estimate:.1e} ({result.certificate} "
                                                f"{grid:.1e} and the penalty's part {extra:.1e})", 1)
                          for remark in result.remarks]
    if result.status == Status.SOLVED:
        bound = target * functional.model.accuracy_scale(result.x)
        if result.error_estimate is not None and result.error_estimate > bound:
            result.status = Status.UNCERTIFIED
            result.remarks.append(f"with the penalty's part {extra:.1e} the error estimate "
                                  f"{result.error_estimate:.1e} exceeds the target {bound:.1e}")
        elif len(rounds) > 1:  # (one round: the cost's minimum reached with the model's λ, nothing to add)
            result.remarks.append(f"an optimum of the cost: gap {optimum.gap(result, weight):.1e} (2λ·I, "
                                  f"λ = {weight:.0e}), penalty's part of the estimate {extra:.1e}")


def _cost_verdict(functional: Functional, result: SolveResult, finer: SolveResult | None, target: float) -> None:
    """A cost's estimate of |𝒥 − 𝒥*| (:func:`qdframe.certificates.estimates.cost_estimate`), and
    `solved` withdrawn where there is none or it passes target·max(1, |𝒥|): `solved` promises
    the optimum as well as the trajectory."""
    result.cost_estimate = cost_estimate(result, finer)
    if result.status != Status.SOLVED:
        return
    bound = target * max(1.0, abs(float(result.cost)))  # type: ignore[arg-type]
    if result.cost_estimate is None:
        result.status = Status.UNCERTIFIED
        result.remarks.append(f"the cost {result.cost:.6g} has no estimate of its distance to the optimum "
                              f"(it needs the bisection certificate's solve on the bisected mesh)")
    elif result.cost_estimate > bound:
        result.status = Status.UNCERTIFIED
        result.remarks.append(f"the cost's estimate {result.cost_estimate:.1e} (|𝒥 − 𝒥*|, from the bisected "
                              f"mesh) exceeds the target {bound:.1e}")
    else:
        result.remarks.append(f"cost estimate {result.cost_estimate:.1e} ≤ target {bound:.1e}")


def _summarized(plan: Staged, run: Run, functional: Functional, result: SolveResult, refined: Refined) -> SolveResult:
    """The result's options over the whole solve (grids, iterations per grid, the smallest
    ε and δ reached, the start) and its message where it did not end `solved`."""
    options = plan.options
    shrunk_to = run.shrunk_to + list(refined.shrunk_to)
    grids = plan.grids + [count for count, _ in refined.meshes]
    per_grid = run.per_grid + [used for _, used in refined.meshes]
    # the smallest ε (and its δ) of the solve's descents: where the paper's method got to
    eps_reached, delta_reached = min(shrunk_to) if shrunk_to else (options.eps, options.delta)
    result.descent = dataclasses.replace(result.descent, eps=eps_reached, delta=delta_reached,
                                         max_iter=options.max_iter, scheme=functional.grid.scheme.name)
    # "none": held asked (the default) and nothing to hold, the model has no fixed set of inputs
    inputs = "held" if functional.held else "none" if plan.plan.inputs == "held" and not functional.model.has_unknowns \
        else "free"
    result.grids = GridsRecord(run.first_start, tuple(grids), tuple(per_grid), plan.signs, plan.selection_scale,
                               inputs, functional.grid.uniform)
    result.binding = _binding(functional, result, options.residual_tol)
    spent = ", ".join(f"{count} nodes {used}" for count, used in zip(grids, per_grid))
    if result.status == Status.MAX_ITER:  # the whole budget, over all grids
        result.reason = f"{options.max_iter} iterations spent" + (f": {spent}" if len(grids) > 1 else "")
    elif result.status != Status.SOLVED and len(grids) > 1:
        result.remarks.append(f"{result.iterations} iterations: {spent}")
    return result


def _binding(functional: Functional, result: SolveResult, residual_tol: float) -> dict[str, list[list[float]]]:
    """Where each bound side (``state_bounds``, ``control_bounds``) binds: {"u ≤ 1.5": [[t_a, t_b], …]},
    the first and last point of each run of points within the bounds check's tolerance of it."""
    bounds = functional.bounds
    if bounds is None:
        return {}
    y = functional.arguments(functional.pack(np.asarray(result.x, float), np.asarray(result.z, float),
                                             None if result.u is None else np.asarray(result.u, float),
                                             None if result.selections is None else np.asarray(result.selections, float)))
    sides = functional.values.bound_sides(y)
    tol = result.checks.get("bounds", {}).get("tol", residual_tol)
    t = np.asarray(result.t, float) * functional.model.time_scale(np.asarray(result.x, float))
    out: dict[str, list[list[float]]] = {}
    for j, name in enumerate(bounds.names):
        active = np.concatenate([[False], sides[:, j] >= -tol, [False]])
        starts, ends = np.flatnonzero(~active[:-1] & active[1:]), np.flatnonzero(active[:-1] & ~active[1:]) - 1
        if starts.size:
            out[name] = [[float(t[a]), float(t[b])] for a, b in zip(starts, ends)]
    return out
