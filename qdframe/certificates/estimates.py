"""Error estimates of a solved trajectory: max over its points of |x(t_k) − x*(t_k)|.

Two certificates, each for the problems it can judge (:func:`certificate_for`):

**bisection** — where the problem has one solution. The same problem is solved again on
the bisected mesh (every interval halved: :meth:`~qdframe.schemes.grid.Grid.bisected`), from the
result interpolated, by gauss-newton, and the two are compared at the result's points in
what the user is given (:meth:`~qdframe.model.InclusionModel.observed`: x, and with a free
T or parameters the T and p found, at each solve's own t = s·T). With x_h and x_{h/2} the two discrete solutions and
p ≥ 1 the order, x_h − x* ≈ (x_h − x_{h/2})·2^p/(2^p − 1), a factor ≤ 2 for every p ≥ 1;
the estimate takes 2.5 (p = 1 with a quarter's margin for the higher-order terms on
coarse grids), plus what the two discrete solutions cannot see, the result's own defects:

    2.5·max_k |x_h(t_k) − x_{h/2}(t_k)| + boundary error + consistency error
        + T·(inclusion residual + max a·selection residual) + 64ε·max(1, |x|)
        + max_j |pinned_j − located_j|·2·max|z|.

The defects matter near the solver's tolerance: a trajectory that misses x_j(T) = xT_j by
b is at least b from every solution there, and a velocity h outside F moves x by up to
T·h over the horizon. The last term is for a switch pinned on a mesh point
(:func:`qdframe.solve.adaptive.settle_switches`) where the solution does not switch: both solves
share the pin, so their difference cannot show it; a selection held a time δ too long
moves x by up to δ times the velocity's jump.

**replay** — where the solutions form a set (a free input, a set-valued right-hand side)
or the problem is an initial-value problem. The trajectory's own choices are replayed
through the true dynamics: from its x(0), the Filippov motion x_ref of
x' ∈ g + B·Sgn(s) (:func:`qdframe.certificates.model_system.model_system`), each set's velocity the point
nearest to the trajectory's own choice, the controls the trajectory's u, all continued
between the points by the scheme's own rule for x' (:meth:`~qdframe.schemes.Scheme.velocity`),
integrated by DOP853 with event location (rtol = atol = 1e-11). x_ref is a true motion of
the inclusion; the estimate is

    max_k |x(t_k) − x_ref(t_k)| + how far x_ref misses the end, periodic and surface
        conditions + the integration's uncertainty + 64ε·max(1, |x|),

the uncertainty being how far the motion integrated at 10 times the tolerance moves
(measured only when the rest of the estimate meets its target). Each piece between the
input's kinks and the events tries its whole span as its first step; where DOP853 took
every piece in one accepted step (a motion polynomial there, or smooth on the mesh's
scale), a looser run would take the same steps and measure nothing: the uncertainty is then the sum of the steps' tolerances,
2·steps·tol·max(1, |x|) (each accepted step's error is within atol + rtol·|x| by DOP853's
own estimate). A model without sign terms
has no events to locate: its motion x' = P_F(x, u)(w(t)) is found at every point at once by
the collocation replay of :mod:`qdframe.certificates.projection_replay` (vectorized Newton–Picard sweeps,
the uncertainty its change when the sub-steps double), not point by point.

For an initial-value problem x_ref is the solution, so this is the true error itself.
Where the solutions form a set, it bounds how far the trajectory is from a true motion
and how far that motion is from meeting the conditions (the benchmark's yardstick).
Where the estimate is only a verdict (a fixed grid's), the replay stops at the first piece
after which the distance it has seen passes the target: no value, that distance (`above`).

Each estimate also gives the local error per mesh interval (how far x − x_other moves
within it), which :func:`qdframe.solve.adaptive.refine` equidistributes.
"""

from __future__ import annotations

import bisect

import dataclasses
from collections.abc import Callable

import numpy as np

from ..functional import Functional
from ..functional.held import less_sign_points
from ..schemes.grid import Grid
from ..result import SolveResult
from ..status import Status
from .switches import bound_times, switch_times

BISECTION, REPLAY = "bisection", "replay"
CERTIFICATES = (BISECTION, REPLAY)
CLAIM_REACH = 2.0  # a pin holds the switch located within this many of its mesh intervals (misplaced_switches)
ESTIMATE_FACTOR = 2.5  # 2^p/(2^p − 1) ≤ 2 for every order p ≥ 1, with a quarter's margin
ROUNDING = 64 * np.finfo(float).eps  # relative: the estimate never claims less than rounding (its reference's too)
REPLAY_TOL = 1e-11  # DOP853's rtol and atol in the replay
UNMEASURED = 100  # a replay above its target adds this many REPLAY_TOL·max(1, |x|) for its unmeasured integration error

Resolve = Callable[[Functional, SolveResult], SolveResult]  # a descent on a functional from a result


@dataclasses.dataclass
class Estimate:
    """An error estimate of one trajectory: its value (None: none could be made, `detail`
    says why), the local error per mesh interval (K,), which certificate made it, and what
    it compared with (the bisected solve, or the replayed motion at the points)."""

    value: float | None
    local: np.ndarray | None
    certificate: str = ""
    detail: str = ""
    companion: SolveResult | None = None
    reference: np.ndarray | None = None
    switch_times: tuple[float, ...] | None = None  # the replayed motion's, where that motion is the solution (an IVP)
    above: float | None = None  # no value: the estimate is at least this, above its target (a replay stopped early)


def solutions_form_a_set(functional: Functional) -> bool:
    """Whether the model leaves a choice: controls, or a set that is not a point (an
    interval, a ball, an intersection) outside its sign terms; a cost picks one solution."""
    if functional.cost is not None:
        return False
    if functional.m:
        return True
    exact = functional if functional.signs == "exact" else like(functional, functional.grid, "exact")
    probe = np.zeros((1, exact.dim))  # exact's layout: with signs="band" the functional has no selections
    probe[0, : functional.n] = np.nan_to_num(functional.model.x0)
    return any(not sides.equation for sides in exact.distance_sides(probe))


def initial_value_problem(functional: Functional) -> bool:
    """x(0) wholly given and no end or periodic condition."""
    return bool(np.all(functional.start_given) and functional.end.size == 0 and functional.periodic.size == 0)


def certificate_for(functional: Functional) -> str:
    """replay where the solutions form a set or the problem is an initial-value problem
    (there it measures the true error), bisection where a boundary-value problem has one solution
    or a cost picks one (the optimum: a replay would measure the distance to the motion under the
    controls found, not to the optimal one)."""
    if functional.cost is not None:
        return BISECTION
    return REPLAY if solutions_form_a_set(functional) or initial_value_problem(functional) else BISECTION


def estimate(functional: Functional, result: SolveResult, resolve: Resolve, certificate: str | None = None,
             target: float | None = None, verdict: bool = False) -> Estimate:
    """The error estimate of a solved `result` on `functional`'s grid by `certificate`
    (None: :func:`certificate_for`); an unsolved result has none. A replay of a problem
    with one solution that the integrator cannot carry out falls back to bisection. Given
    the `target` it is held against, a replay already above it skips measuring its own
    integration error (the estimate cannot certify either way); where the estimate is only a
    `verdict` (a fixed grid's: no refinement reads its local errors), a replay stops as soon as
    the difference it has seen exceeds the target, with no value but that lower bound (`above`)."""
    if result.status != Status.SOLVED:
        return Estimate(None, None, detail=f"the result is {result.status}")
    chosen = certificate or certificate_for(functional)
    if chosen == REPLAY:
        found = replay(functional, result, target, stop=verdict)
        if found.value is not None or found.above is not None or solutions_form_a_set(functional) \
                or certificate == REPLAY:
            return found
        fallback = bisection(functional, result, resolve)
        fallback.detail = f"{found.detail}; by bisection instead" if fallback.value is not None else \
            f"{found.detail}; {fallback.detail}"
        return fallback
    return bisection(functional, result, resolve)


def bisection(functional: Functional, result: SolveResult, resolve: Resolve) -> Estimate:
    """The estimate from a second solve on the bisected mesh (module docstring)."""
    finer = like(functional, functional.grid.bisected())
    companion = resolve(finer, result)
    if companion.status != Status.SOLVED:
        return Estimate(None, None, BISECTION, f"the solve on the bisected grid ({companion.nodes} nodes) ended "
                        f"{companion.status}", companion)
    grid = functional.grid
    difference = observed_difference(functional.model, grid, result.x, finer.grid, companion.x)  # (N, ·)
    value = ESTIMATE_FACTOR * float(np.max(np.abs(difference))) + defects(functional, result) \
        + misplaced_switches(functional, result)
    return Estimate(value, _local(grid, difference, ESTIMATE_FACTOR), BISECTION, "", companion)


def cost_estimate(result: SolveResult, finer: SolveResult | None) -> float | None:
    """An estimate of |𝒥 − 𝒥*|, 𝒥 the cost of the returned trajectory (``result.cost``, the
    scheme's quadrature) and 𝒥* the least cost over the solutions of the continuous problem,
    from the solve on the bisected mesh that made the bisection estimate (`finer`), as that
    estimate does for x: 𝒥_h − 𝒥* ≈ (𝒥_h − 𝒥_{h/2})·2^p/(2^p − 1), taken as ESTIMATE_FACTOR·
    |𝒥_h − 𝒥_{h/2}|, plus what the discrete solves leave and their difference cannot show:
    each one's optimality gap |yᵀr| (``penalty.optimality_gap``, the first-order distance of
    its 𝒥 from its discrete problem's optimum), the result's Σ|y|·tol (``penalty.tolerance_share``:
    how far the least cost moves while every pointwise check is met within its tolerance, the
    same for both solves) and rounding, 64ε·max(1, |𝒥|). None without a cost or a bisected solve."""
    if result.cost is None or finer is None or finer.cost is None:
        return None
    gaps = sum(abs(solve.penalty.optimality_gap) for solve in (result, finer) if solve.penalty is not None)
    share = result.penalty.tolerance_share if result.penalty is not None else 0.0
    return ESTIMATE_FACTOR * abs(result.cost - finer.cost) + gaps + share + ROUNDING * max(1.0, abs(result.cost))


def observed_difference(model, grid: Grid, x: np.ndarray, other_grid: Grid, other: np.ndarray) -> np.ndarray:
    """What the user is given by `other` (on `other_grid`) minus what `x` (on `grid`) gives, at
    x's points: at the user's times (with a free T, t = s·T, each solution its own T) and in
    the model's ``observed`` columns (x, then a T or parameters found), (N, ·); inf where `other`'s
    T is 0."""
    scale = model.time_scale(other)
    if not scale > 0:  # the other solve shrank T to 0 (a shortest time's first round): nothing to compare
        return np.full_like(model.observed(x), np.inf)
    times = grid.t * model.time_scale(x) / scale
    return model.observed(dense(other_grid, other, times)) - model.observed(x)


def misplaced_switches(functional: Functional, result: SolveResult) -> float:
    """What pinned switches that are not where the solution switches can move it by, which a
    solve on the bisected mesh, pinned at the same points, cannot see: the largest distance
    between a pinned time and the located one, times the largest jump the velocity can make
    (2·max|z|). Zero where the mesh has no pins or the switches have settled on them, and for a
    pin with no switch located within CLAIM_REACH mesh intervals of it (the switch it was put on
    has moved away or gone: where the solution switches now, no pin is shared, and the solve on
    the bisected mesh sees it)."""
    pins = np.asarray(functional.grid.switches, dtype=float)
    if not pins.size:
        return 0.0
    xi = functional.pack(result.x, result.z, result.u, result.selections)
    jumps = switch_times(functional, xi, crossings=True, merge=False, bounds=False)
    kinks = bound_times(functional, xi)
    if jumps.size + kinks.size == 0:
        return 0.0
    located = np.concatenate([jumps, kinks])
    nearest = np.argmin(np.abs(pins[:, None] - located[None, :]), axis=1)
    distance = np.abs(pins - located[nearest])
    # a pin with no switch located within CLAIM_REACH of the mesh intervals beside it holds none:
    # the solution is smooth there, and a mesh point where nothing happens moves nothing
    tau = functional.grid.mesh_times
    h = np.diff(tau)
    at = np.clip(np.searchsorted(tau, pins), 1, h.size)  # the interval to the pin's right is `at`, to its left at − 1
    beside = np.maximum(h[at - 1], h[np.minimum(at, h.size - 1)])
    distance = np.where(distance <= CLAIM_REACH * beside, distance, 0.0)
    kink = nearest >= jumps.size
    # a velocity jump misplaced by d moves x by d·(the jump); a bound's kink (z continuous, its slope
    # jumps) by d²·(the jump of the slope), here at most 2·max|z'| (z's differences over the mesh)
    slope = np.abs(np.diff(result.z, axis=0)) / np.maximum(np.diff(functional.grid.t), 1e-300)[:, None]
    jump_part = float(np.max(distance[~kink], initial=0.0)) * 2.0 * float(np.max(np.abs(result.z)))
    kink_part = float(np.max(distance[kink] ** 2, initial=0.0)) * 2.0 * float(np.max(slope, initial=0.0))
    return jump_part + kink_part


def defects(functional: Functional, result: SolveResult) -> float:
    """What a trajectory's own residuals can move it from a solution by (module docstring)."""
    scale = max(1.0, float(np.max(np.abs(result.x))))
    floor = result.boundary_error + result.consistency_error + ROUNDING * scale
    if result.penalty is not None:  # a cost's optimum: how far its last Newton step would still move x
        floor += result.penalty.newton_step
    velocity = result.inclusion_residual
    if result.selection_residual is not None and functional.p:
        velocity += selection_amplitude(functional, result) * result.selection_residual
    return floor + functional.grid.T * velocity


def selection_amplitude(functional: Functional, result: SolveResult) -> float:
    """The largest |sense·a(y)| of a sign term along the trajectory: how far a selection's
    error moves a velocity."""
    y = result.x if result.u is None else np.concatenate([result.x, result.u], axis=1)
    return max((float(np.max(np.abs(functional.pieces.amplitude_values(functional.blocks[b], term, y))))
                for b, term in functional.sign_terms), default=0.0)


def replay(functional: Functional, result: SolveResult, target: float | None = None, stop: bool = False) -> Estimate:
    """The estimate from the true motion driven by the trajectory's own choices (module
    docstring); its integration error is measured (a second integration, 10× looser) unless
    the rest of the estimate is above `target` already. With `stop` (and a target) the
    integration ends at the first piece after which the difference at the points passed
    exceeds the target: the estimate can only be larger (no value; `above` is what it saw)."""
    from .filippov import FilippovError, integrate
    from .model_system import model_system

    exact = functional if functional.signs == "exact" else like(functional, functional.grid, "exact")
    grid = exact.grid
    xi = exact.pack(result.x, result.z, result.u, result.selections if functional.signs == "exact" else None)
    y = exact.arguments(xi)
    # the sets' choice: z without the sign terms' part B(y)·λ, the trajectory's own selections
    w = less_sign_points(exact, exact.pieces, result.z, y, exact.selections(xi))[0]
    t = grid.t

    def rule(values: np.ndarray) -> Callable[[float], np.ndarray]:
        return PointRule(grid, values)

    controls = rule(result.u) if exact.m else None
    inputs = exact.m or solutions_form_a_set(exact)  # a choice to continue between the points
    if inputs and not exact.sign_terms:
        return _collocation_replay(exact, result)
    scale = max(1.0, float(np.max(np.abs(result.x))))
    watch = _Watch(t, result.x, target - ROUNDING * scale) if stop and target is not None else None
    try:
        system = model_system(exact, controls, rule(w) if inputs else None,
                              breaks=grid.mesh_times[1:-1] if inputs else ())
        motion = integrate(system, result.x[0], grid.T, rtol=REPLAY_TOL, atol=REPLAY_TOL, halt=watch)
    except (FilippovError, np.linalg.LinAlgError, ValueError) as exc:
        return Estimate(None, None, REPLAY, f"no replay: {exc}")
    if motion.halted is not None:
        seen = watch.seen + ROUNDING * scale
        return Estimate(None, None, REPLAY, f"the true motion {'its choices drive' if inputs else 'from its x(0)'} "
                        f"is {seen:.2e} from it by t = {motion.halted:.4g}, above the target {target:.2e} "
                        "(the replay stopped there)", above=seen)
    reference = motion(t)
    difference = result.x - reference
    miss = exact.boundary_error(np.concatenate([reference, np.zeros_like(reference)], axis=1))
    miss += _surface_miss(exact, reference)
    value = float(np.max(np.abs(difference))) + miss + ROUNDING * scale
    if target is not None and value > target:  # cannot certify: an allowance for the integration instead
        value += UNMEASURED * REPLAY_TOL * scale
    elif motion.one_step:  # one step a piece: a looser run steps alike; each step's error is within the tolerance
        value += 2 * motion.steps * REPLAY_TOL * scale
    else:
        try:
            looser = integrate(system, result.x[0], grid.T, rtol=10 * REPLAY_TOL, atol=10 * REPLAY_TOL)
        except (FilippovError, np.linalg.LinAlgError, ValueError) as exc:
            return Estimate(None, None, REPLAY, f"no replay at a looser tolerance: {exc}")
        value += float(np.max(np.abs(looser(t) - reference)))  # the integration's own error, with margin
    detail = f"the true motion from x(0) misses the conditions by {miss:.1e}" if miss else ""
    solution = not inputs and initial_value_problem(exact)  # the replayed motion is the solution itself
    return Estimate(value, _local(grid, difference, 1.0), REPLAY, detail, reference=reference,
                    switch_times=tuple(motion.switch_times) if solution else None)


class _Watch:
    """The `halt` of a replay that stops once it cannot certify: the largest |x(t_k) − x_ref(t_k)|
    over the points t_k each finished piece covers, against `limit`."""

    def __init__(self, t: np.ndarray, x: np.ndarray, limit: float) -> None:
        self.t, self.x, self.limit, self.seen = t, x, limit, 0.0

    def __call__(self, start: float, end: float, piece) -> bool:
        first, last = np.searchsorted(self.t, [start, end], side="left")
        last += int(last < self.t.size and self.t[last] == end)
        if last > first:
            moved = np.abs(self.x[first:last] - np.atleast_2d(piece(self.t[first:last])).T)
            self.seen = max(self.seen, float(np.max(moved)))
        return self.seen > self.limit


def _collocation_replay(functional: Functional, result: SolveResult) -> Estimate:
    """:func:`replay` for a model without sign terms, by :func:`qdframe.certificates.projection_replay.replay`:
    z and u continued by the scheme's rule, the uncertainty its own."""
    from .projection_replay import replay as collocate

    grid = functional.grid

    def continuation(values: np.ndarray, times: np.ndarray) -> np.ndarray:
        return grid.scheme.velocity(grid.t, grid.mesh, values, times)

    try:
        motion = collocate(functional.model, grid.t, result.x, result.z, result.u if functional.m else None,
                           continuation=continuation)
    except (np.linalg.LinAlgError, ValueError) as exc:
        return Estimate(None, None, REPLAY, f"no replay: {exc}")
    reference = motion.x
    miss = motion.end_miss + _surface_miss(functional, reference)
    scale = max(1.0, float(np.max(np.abs(result.x))))
    value = motion.error + miss + motion.uncertainty + ROUNDING * scale
    detail = f"the true motion from x(0) misses the conditions by {miss:.1e}" if miss else ""
    return Estimate(value, _local(grid, result.x - reference, 1.0), REPLAY, detail, reference=reference)


def _surface_miss(functional: Functional, reference: np.ndarray) -> float:
    """How far a replayed motion leaves the model's surface (0 without one)."""
    if functional.surface is None:
        return 0.0
    return float(np.max(np.abs(functional.surface.function(reference)[0])))


class PointRule:
    """The scheme's own x'(t) of `values` (Scheme.velocity) at one time: the integrator asks
    for one point at a time, so the interval's Lagrange weights are formed from floats."""

    def __init__(self, grid: Grid, values: np.ndarray) -> None:
        self.tau = grid.mesh_times.tolist()
        offsets = np.asarray(grid.scheme.velocity_points)
        self.points = grid.mesh[:-1, None] + offsets[None, :]  # (K, q): each interval's points
        self.times = grid.t[self.points].tolist()
        self.values = values[self.points]  # (K, q, ...)

    def __call__(self, time: float) -> np.ndarray:
        k = min(max(bisect.bisect_right(self.tau, time) - 1, 0), len(self.times) - 1)
        nodes, values = self.times[k], self.values[k]
        out = 0.0
        for i, ti in enumerate(nodes):
            basis = 1.0
            for j, tj in enumerate(nodes):
                if j != i:
                    basis *= (time - tj) / (ti - tj)
            out = out + basis * values[i]
        return np.asarray(out, dtype=float)


def _local(grid: Grid, difference: np.ndarray, factor: float) -> np.ndarray:
    """The local error of mesh interval j: how far `difference` moves within it, from its first mesh point."""
    interval = np.searchsorted(grid.mesh, np.arange(1, grid.nodes)) - 1  # the interval of each point p ≥ 1
    start = grid.mesh[interval]  # base(p)
    moved = np.max(np.abs(difference[1:] - difference[start]), axis=1)
    local = np.zeros(grid.mesh.size - 1)
    np.maximum.at(local, interval, factor * moved)
    return local


def dense(grid: Grid, values: np.ndarray, times: np.ndarray) -> np.ndarray:
    """`values` (at grid.t) at `times` by the scheme's interpolant: on each mesh interval the
    polynomial through its points (linear for one-step schemes)."""
    tau = grid.mesh_times
    interval = np.clip(np.searchsorted(tau, times, side="right") - 1, 0, tau.size - 2)
    stages = grid.scheme.stages
    first = grid.mesh[interval]  # the interval's mesh point; its points are first … first + stages
    out = np.zeros((times.size, values.shape[1]))
    for i in range(stages + 1):  # Lagrange basis over the interval's stages + 1 points
        basis = np.ones(times.size)
        for j in range(stages + 1):
            if j != i:
                basis *= (times - grid.t[first + j]) / (grid.t[first + i] - grid.t[first + j])
        out += basis[:, None] * values[first + i]
    return out


def like(functional: Functional, grid: Grid, signs: str | None = None) -> Functional:
    """A functional of the same model and sign treatment (or `signs`) on `grid`, with its cost's λ and shifts."""
    out = Functional(functional.model, grid, signs=functional.signs if signs is None else signs,
                     selection_scale=functional.selection_scale, inputs=functional.inputs)
    out.take_multipliers(functional)  # a cost's λ and shifts (qdframe.descent.multipliers)
    return out
