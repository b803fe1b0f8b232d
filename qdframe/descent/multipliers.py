"""A cost's optimum over the solutions by the method of multipliers, inside a descent.

With a cost 𝒥 whose least value over the solutions is not 0 (a least effort, a shortest
time, a terminal cost), the minimizer of 𝒥 + λ·I is not a solution for any finite λ (it
trades cost against I). The method of multipliers (Hestenes 1969, Powell 1969; Nocedal &
Wright, Numerical Optimization, 2nd ed., §17.3–17.4) keeps λ moderate and moves each
residual r of I by a shift s = y/λ, y its multiplier (:mod:`qdframe.functional.shifts`):
after each descent of the shifted objective 𝒥 + (λ/2)·Σ w·(r + s)², the shifts move to
s + r (an equation) or max(0, s + ℓ) (a side of a set, a bound), and the descent goes on
from its last iterate. As s → y*/λ the minimizer tends to the constrained optimum: the
descent ends `solved` where every pointwise check passes (I unshifted ≤ tol, the checks of
:mod:`.checks`) and the multipliers' gap |yᵀr| (the first-order distance of 𝒥 from the
optimum of the discrete problem) is at most GAP_TOL·max(1, |𝒥|).

λ starts at the model's (a cost whose least value is 0, as the paper's Example 7.1, ends in
the first round with no shift), is at least MULTIPLIER_START after it, and is raised
×RAISE_BY where a round cuts the largest violation by less than FEASIBLE_RATE, never past
PENALTY_CAP. A first round where the cost won outright (its gap more than WARM_SHARE of
the cost: a shortest time at λ = 1 shrinks T towards 0 with the block at rest) gives no
multipliers: the next starts afresh from the descent's own start.

Applies to Newton-type directions (gauss-newton), whose linearized system carries the shifts;
the paper's min-norm direction raises the penalty between solves instead
(:mod:`qdframe.solve.optimum`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from . import checks
from ..directions.base import DirectionSolver
from ..errors import BackendError
from ..functional import Functional
from ..functional.shifts import Shifts
from ..result import PenaltyRecord, SolveResult
from ..status import Status
from .options import DescentOptions

MULTIPLIER_START = 1e2
PENALTY_CAP = 1e6
RAISE_BY = 10.0
FEASIBLE_RATE = 0.25
MAX_ROUNDS = 40
STEP_TOL = 1e-7  # relative to max(1, max|x|): a Newton step this small (1/10 of the default target) ends a descent
GAP_TOL = 1e-7  # a tenth of the default accuracy asked of the cost, |J − J*| ≤ 1e-6·max(1, |J|)
WARM_SHARE = 0.1
RESTORE_STEPS = 5  # a restoration's iterations (Gauss–Newton on I alone from a point infeasible by ~tol) …
RESTORE_REACH = 10.0  # … tried where the violation is at most this × what the checks allow …
SLOW_ROUNDS = 3  # … after this many rounds in a row at PENALTY_CAP that cut it by less than FEASIBLE_RATE, or at the last


def applies(functional: Functional, solver: DirectionSolver) -> bool:
    """A cost, a direction whose step model reads the shifts (a Newton-type one), and no unknown
    constants (a free T or parameters): Gauss–Newton's model leaves out the constraints' own
    curvature Σ y·∇²r, which the bilinear T·F of a free end time makes as large as the decrease
    near the optimum (a shortest time stalls with its residuals at 1e-8); there the penalty is
    raised instead (:mod:`qdframe.solve.optimum`), which drives y/λ, and the term, to 0."""
    return functional.cost is not None and solver.full_steps and not functional.model.constant_states


def violation(residuals: Shifts) -> float:
    """The largest violation of a constraint behind I: |r| of an equation, max(0, ℓ) of a side."""
    sides = np.where(residuals.point[None, :, None], np.abs(residuals.blocks), np.maximum(residuals.blocks, 0.0))
    parts = [np.abs(residuals.consistency), np.abs(residuals.end), np.abs(residuals.surface), sides,
             np.abs(residuals.selections), np.maximum(residuals.bounds, 0.0)]
    return max((float(np.max(part)) for part in parts if part.size), default=0.0)


def _weighted_multipliers(functional: Functional, residuals: Shifts) -> Shifts:
    """y/λ of every residual of I at the functional's shifts: w·(r + s) of an equation,
    w·max(0, ℓ + s) of a side (the end conditions unweighted), in the residuals' layout."""
    s = functional.shifts if functional.shifts is not None else residuals.cleared()
    w = functional.grid.weights
    sides = residuals.blocks + s.blocks
    shifted = np.where(s.point[None, :, None], sides, np.maximum(sides, 0.0))
    return dataclasses.replace(
        residuals, consistency=w[:, None] * (residuals.consistency + s.consistency), end=residuals.end + s.end,
        surface=w[:, None] * (residuals.surface + s.surface), blocks=w[:, None, None] * shifted,
        selections=w[:, None] * (residuals.selections + s.selections),
        bounds=w[:, None] * np.maximum(residuals.bounds + s.bounds, 0.0))


def gap(functional: Functional, residuals: Shifts) -> float:
    """|yᵀr| at the functional's λ and shifts: the multipliers y = λ·w·(r + s) (resp.
    λ·w·max(0, ℓ + s)) against the residuals; without shifts 2λ·I, the penalty's gap."""
    y = _weighted_multipliers(functional, residuals)
    total = float(np.sum(y.consistency * residuals.consistency))
    total += float(np.sum(y.end * residuals.end))
    total += float(np.sum(y.surface * residuals.surface))
    total += float(np.sum(y.blocks * residuals.blocks))
    total += float(np.sum(y.selections * residuals.selections))
    total += float(np.sum(y.bounds * residuals.bounds))
    return abs(functional.penalty * total)


def tolerance_share(functional: Functional, xi: np.ndarray, residual_tol: float) -> float:
    """Σ|y|·tol over every constraint behind I at ξ, y its multiplier (as in :func:`gap`) and tol
    what its pointwise check lets it miss by (:mod:`.checks`: residual_tol times the size of x,
    of z for a velocity's set, 1 for a selection): how far the least cost can move while every
    check passes, to first order (the least cost's sensitivity to a constraint's right-hand side
    is its multiplier)."""
    x, z = functional.split(xi)
    tol_x, tol_z = checks.scaled_tol(residual_tol, x), checks.scaled_tol(residual_tol, z)
    y = _weighted_multipliers(functional, functional.constraint_residuals(xi))
    total = tol_x * (float(np.sum(np.abs(y.consistency))) + float(np.sum(np.abs(y.end)))
                     + float(np.sum(np.abs(y.surface))) + float(np.sum(y.bounds)))
    total += tol_z * float(np.sum(np.abs(y.blocks)))
    total += residual_tol * float(np.sum(np.abs(y.selections)))
    return functional.penalty * total


def iterate(functional: Functional, result: SolveResult) -> np.ndarray:
    """ξ of a descent's result on its functional."""
    u = None if result.u is None else np.asarray(result.u, float)
    selections = None if result.selections is None else np.asarray(result.selections, float)
    return functional.pack(np.asarray(result.x, float), np.asarray(result.z, float), u, selections)


def optimum(functional: Functional, solver: DirectionSolver, options: DescentOptions,
            once: Callable[..., SolveResult], start: np.ndarray | None,
            near: bool) -> SolveResult:
    """A descent to the cost's optimum (module docstring): `once(ξ, max_iter, near)` descends once
    on the functional (its λ and shifts as they stand) from ξ (None: the model's start). From a
    start that is not a coarser grid's solution (`near`), a first descent without the cost finds a
    solution of the constraints (from rest, a block with friction the cost keeps still at λ = 100:
    its selections stick and the semismooth step cannot leave; a motor whose states are 1e-2 in
    size had its cost win at λ = 1e6); the rounds then go from there at λ = MULTIPLIER_START."""
    budget = options.max_iter
    weight = max(functional.penalty, MULTIPLIER_START)
    feasible = None
    if not near and functional.shifts is None and budget > 0:
        with functional.without_cost():  # a solution first, the cost not felt
            feasible = once(start, budget, False)
        start, budget = iterate(functional, feasible), budget - feasible.iterations
        functional.set_multipliers(None, weight)
    else:
        functional.set_multipliers(functional.shifts, max(functional.penalty, weight))
    first = once(start, budget, near or feasible is not None)
    if feasible is not None:
        first = after(feasible, first)
    if budget <= 0:
        return first
    origin = start if start is not None else functional.initial_point()
    return rounds(functional, solver, options, first, once, origin, options.max_iter)


def after(earlier: SolveResult, later: SolveResult) -> SolveResult:
    """`later` with `earlier`'s history before its own, its iterations and time counted on."""
    later.history = _joined(earlier.history, later.history)
    later.iterations = later.history[-1].iteration
    later.wall_time_s += earlier.wall_time_s
    return later


def _joined(history: list, more: list) -> list:
    """`history` then `more` (its first record, the start, left out), counted on."""
    used, elapsed = history[-1].iteration, history[-1].time_s
    return history + [dataclasses.replace(record, iteration=record.iteration + used, time_s=record.time_s + elapsed)
                      for record in more[1:]]


def _optimal(functional: Functional, solver: DirectionSolver, options: DescentOptions, xi: np.ndarray) -> float | None:
    """For a solution of the discrete problem (I ≤ tol, every check) whose Newton step moves x by
    at most STEP_TOL·max(1, max|x|), that move (the model's optimum is that near, though a line
    search stopped short of proving it: the objective's rounding at a kink of the model; the
    error estimate adds it); None otherwise."""
    if functional.terms(xi).I > options.tol or checks.failures(checks.checks(functional, xi, options.residual_tol)):
        return None
    step = _newton_step(functional, solver, options, xi)
    if step is None:
        return None
    scale = max(1.0, float(np.max(np.abs(functional.split(xi)[0]))))
    move = float(np.max(np.abs(step[:, : functional.n])))
    return move if move <= STEP_TOL * scale else None


def _newton_step(functional: Functional, solver: DirectionSolver, options: DescentOptions,
                 xi: np.ndarray) -> np.ndarray | None:
    """The direction's step at ξ outside a descent; None where its backend fails (the descent's
    own steps turn such a failure into `failed`; here there is simply no such step)."""
    solver.start(functional)
    try:
        return solver.compute(functional, xi, options.delta).step
    except BackendError:
        return None


def rounds(functional: Functional, solver: DirectionSolver, options: DescentOptions, first: SolveResult,
           once: Callable[..., SolveResult], start: np.ndarray, budget: int) -> SolveResult:
    """The descent's result after the multipliers' rounds (module docstring). `first`: the
    descent at the functional's λ and shifts; `once(ξ, max_iter, near, watchdog)` descends once
    more (a round without the watchdog's full steps: its stall is its shifts', not a kink's);
    `start` the descent's own start; `budget` its iterations in all. Where a round takes no
    step (the decrease the moved shifts ask for is below the objective's rounding, which the
    cost's size sets), the Newton step is taken whole where it lowers the violation; where a
    descent stops short of proving its optimum but the Newton step is below STEP_TOL, it is
    solved (:func:`_optimal`); where the gap is met and the violation is within RESTORE_REACH of
    the checks but the rounds at PENALTY_CAP barely cut it (SLOW_ROUNDS in a row) or are about to
    stop, the nearest solution is tried (:func:`_restored`: how far it moves x joins the Newton
    step's in the estimate). A round that leaves the iterate where it was raises λ ×100, or at
    PENALTY_CAP ends the rounds. The functional keeps the last λ and shifts
    (a finer grid's functional takes them: :meth:`Functional.take_multipliers`)."""
    result = first
    last_violation, count, move, restored_gap, restored_move = np.inf, 0, None, 0.0, 0.0
    spent = [(functional.penalty, first.iterations)]  # (λ, iterations) of each round, the first's with the solution's
    previous, slow = None, 0  # the iterate the last round started from; rounds at the cap in a row that barely cut the violation
    while True:
        xi = iterate(functional, result)
        residuals = functional.constraint_residuals(xi)
        now, distance = violation(residuals), gap(functional, residuals)
        cost = abs(result.cost or 0.0)
        close = distance <= GAP_TOL * max(1.0, cost)
        move = _optimal(functional, solver, options, xi) if result.status != Status.SOLVED and close else None
        if move is not None:
            result.status, result.reason, result.remarks = Status.SOLVED, "", []
        stuck = previous is not None and np.array_equal(xi, previous)  # the last round did not move it
        if result.status == Status.SOLVED and close:
            break
        used = result.iterations
        if count and result.status not in (Status.SOLVED, Status.STATIONARY):
            break  # the descent's own limit (its budget, a failed step), not the multipliers, ended it
        capped = functional.penalty >= PENALTY_CAP
        slow = slow + 1 if capped and count and now > FEASIBLE_RATE * last_violation else 0
        halted = count >= MAX_ROUNDS or used >= budget or (stuck and capped)
        if halted or slow >= SLOW_ROUNDS:
            if close and now <= RESTORE_REACH * checks.scaled_tol(options.residual_tol, xi[:, : functional.n]):
                restored = _restored(functional, options, once, xi, result, budget - used)
                if restored is not None:  # the multipliers' optimum made feasible: its gap and the move count on
                    shift = iterate(functional, restored)[:, : functional.n] - xi[:, : functional.n]
                    result, restored_gap, restored_move = restored, distance, float(np.max(np.abs(shift)))
                    continue
            slow = 0  # not restored: the next try after as many slow rounds again
        if halted:
            result.remarks.append(f"the multipliers' rounds stopped after {count} at λ = {functional.penalty:.0e}: "
                                  f"violation {now:.1e}, gap |yᵀr| {distance:.1e}")
            break
        warm = count > 0 or distance <= WARM_SHARE * max(cost, 1e-300)
        weight = functional.penalty
        if not warm or (count and now > FEASIBLE_RATE * last_violation):
            # no step at all: the shifts' pull on a kink of a residual at its root (a selection at
            # an end of Sgn where its switch is 0) is a wall to the descent; a higher λ shrinks it
            weight = min(weight * RAISE_BY ** (2 if stuck else 1), PENALTY_CAP)
        base = functional.shifts if functional.shifts is not None else residuals.cleared()
        moved = base.moved(residuals) if warm else residuals.cleared()
        functional.set_multipliers(moved.scaled(functional.penalty / weight), weight)
        earlier, previous = result, xi
        result = once(xi if warm else start, budget - used, True, False)
        if result.iterations == 0 and result.status != Status.SOLVED:
            step = _newton_step(functional, solver, options, xi)
            trial = xi if step is None else xi + step
            if step is not None and violation(functional.constraint_residuals(trial)) < now:
                result = after(result, once(trial, budget - used, True, False))
        spent.append((weight, result.iterations))
        result = after(earlier, result)
        last_violation, count = now, count + 1
    xi = iterate(functional, result)
    share = tolerance_share(functional, xi, options.residual_tol)
    result.penalty = PenaltyRecord(functional.penalty, max(distance, restored_gap), tuple(spent),
                                   max(move or 0.0, restored_move), share)
    result.multipliers = costates(functional, xi)
    return result


def _restored(functional: Functional, options: DescentOptions, once: Callable[..., SolveResult], xi: np.ndarray,
              result: SolveResult, budget: int) -> SolveResult | None:
    """Where the rounds at the cap barely cut the violation or stop (a round that takes no step:
    the decrease the moved shifts ask for is below what the descent resolves at the cost's size) at
    an iterate whose gap already meets GAP_TOL but whose pointwise checks fail: the nearest
    solution of the constraints (a descent of I alone, the cost and shifts off, at most
    RESTORE_STEPS iterations), taken `solved` where every check passes there and its cost is within
    GAP_TOL·max(1, |𝒥|) of the iterate's (to first order the cost moves by the multipliers against
    the residuals removed, yᵀr, which the gap bounds); None otherwise. A last resort: the move is
    in the damped metric, not along the optimum (tried at every slow round, it moved a clipped
    control's kink by 2e-5 and took `least-effort-bounded` at accuracy=1e-8 from 905 to 3725 points)."""
    if budget < 1 or result.cost is None:
        return None
    with functional.without_cost():
        feasible = once(xi, min(RESTORE_STEPS, budget), True, False)
    if feasible.status != Status.SOLVED:
        return None
    restored = after(result, after(feasible, once(iterate(functional, feasible), 0, True, False)))
    if restored.cost is None or abs(restored.cost - result.cost) > GAP_TOL * max(1.0, abs(result.cost)) or \
            restored.I > options.tol or checks.failures(checks.checks(functional, iterate(functional, restored),
                                                                       options.residual_tol)):
        return None
    restored.status, restored.reason, restored.remarks = Status.SOLVED, "", []
    return restored


def costates(functional: Functional, xi: np.ndarray) -> np.ndarray | None:
    """The multipliers of the dynamics, (N, n): per state x_i, the density λ·(r + s) of the
    multiplier of its block's residual (an equation's r = z_i − f_i(y); a set's two sides
    signed, max(0, ℓ₊ + s₊) − max(0, ℓ₋ + s₋)): the multipliers μ of L = 𝒥 + ∫μ·(x' − f),
    μ = −p with p Pontryagin's costates (H = c + p·f), to the scheme's order, with no estimate
    (docs/guide.md, "Optimal control", gives what was measured). None where a block has several
    coordinates or a state has none (a resolved one)."""
    blocks = functional.blocks
    if any(block.size != 1 for block in blocks) or len(blocks) != functional.n:
        return None
    residuals = functional.constraint_residuals(xi)
    s = functional.shifts if functional.shifts is not None else residuals.cleared()
    sides = residuals.blocks + s.blocks
    out = np.zeros((xi.shape[0], functional.n))
    for b, block in enumerate(blocks):
        plus = sides[:, b, 0] if s.point[b] else np.maximum(sides[:, b, 0], 0.0)
        out[:, block.coords[0]] = plus if s.point[b] else plus - np.maximum(sides[:, b, 1], 0.0)
    return functional.penalty * out
