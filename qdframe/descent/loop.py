"""The δ-quasidifferential descent loop (paper Section 6): from a start ξ, a direction G
per iteration (:mod:`qdframe.directions`), a step γ along it (:mod:`qdframe.line_searches`),
until the objective and I are ≤ tol and every pointwise check passes (:mod:`qdframe.descent.checks`)
or the descent can go no further. The public call, with its grids and certificate, is
:func:`qdframe.solve.solving.solve`."""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from threadpoolctl import ThreadpoolController

from . import checks
from .checks import CERTIFY_SHRINK
from ..directions.base import DirectionSolver
from ..errors import BackendError, InputError, ModelOutputError
from ..functional import Functional
from ..line_searches.base import LineSearch
from .outcome import located, result_of
from ..result import IterationRecord, SolveResult
from ..status import Status
from .options import EPS_FLOOR, DescentOptions, ProgressCallback  # noqa: F401  (the loop's options)
from .steps import EAGER_ROUNDS, WATCHDOG_ROUNDS, WATCHDOG_STEPS, keep_start, watchdog

# with I ≤ tol but a pointwise check failing, the descent goes on while the worst check's
# ratio to its tolerance shrinks by at least CERTIFY_SHRINK every CERTIFY_WINDOW iterations;
# slower than that (a residual left at a few nodes, shrinking a few % per step) it stops
# `stationary`. The window is long because the ratio falls in steps: semismooth Newton fixes
# a few nodes' selections per step, so on a fine grid (paper-7.3) the ratio can stay nearly
# flat for stretches of iterations before it falls, and a short window would stop a descent
# that is still on its way to certified.
CERTIFY_WINDOW = 40
CERTIFY_WINDOW_FIRST_ORDER = 400  # the paper's min-norm directions converge linearly: a longer window
EPS_SHRINK = 10.0  # ε and δ are divided by this where the iterate is ε-stationary but not solved
NEAR_ITERATE = 1e-6  # a trial that moves ξ by at most this (relative, max-norm) is next to the iterate
# a line search that finds no decrease along a step whose slope is at most this × |objective| stops
# at a stationary point for every purpose here (a cost's optimum is certified to ~1e-6 of it):
# at a large penalty λ the model's slope is λ-amplified rounding (λ·r carries λ·1e-16), so the
# step's predicted decrease and the objective's actual change differ in sign at ~1e-12 of it.
# Seen on the time-optimal block at λ = 1.6e9: slope −2.9e-14 at objective 1.633 on 10001
# nodes, −1.6e-12 on 20001 (the objective rising 4e-14 along it), on one CPU and not another.
STALL_SLOPE = 1e-11
# line-search trial points where the model is NaN/inf that a descent rejects before it stops with the
# last one's piece, node, t and state: a few are a line search overshooting into a region the model
# leaves undefined; thousands are a descent that keeps heading there (docs/guide.md, "Reliability").
# The limit sits above what a descent blocked next to the NaN region rejects before it stops with
# the error naming the iterate (tests/test_first_hour_api.py's NaN models)
REJECTED_LIMIT = 500


def descend(
    functional: Functional,
    solver: DirectionSolver,
    search: LineSearch,
    options: DescentOptions,
    progress: ProgressCallback | None = None,
    start: np.ndarray | None = None,
    near_solution: bool = False,
) -> SolveResult:
    """Run the descent from `start` (default: the model's initial guess); `near_solution`:
    the start is a coarser grid's solution, where a Newton step the line search cuts is
    first tried whole (:data:`qdframe.descent.steps.EAGER_ROUNDS`).

    x(t_0) = x0 where given (a start's row 0 is set to it); a NaN/inf of the model at an
    iterate raises ModelOutputError with the state there (:func:`_located`), one at a
    trial point of the line search only rejects that point (:func:`solve`).

    BLAS runs on one thread meanwhile (threadpoolctl): the work per call is a reduction
    over the nodes or a small per-node product, which a multi-threaded BLAS splits into
    pieces too small to pay for the threads, and stalls on when another process holds a
    core (`qdframe bench scale`, docs/benchmarks.md).
    """
    with _blas().limit(limits=1, user_api="blas"):
        return _descend(functional, solver, search, options, progress, start, near_solution)


@functools.cache
def _blas() -> ThreadpoolController:
    """The process's thread pools, found once, at the first descent (finding them searches the loaded
    libraries, a millisecond or two: a solve runs a descent per grid and per settling round)."""
    return ThreadpoolController()


def _descend(functional: Functional, solver: DirectionSolver, search: LineSearch, options: DescentOptions,
             progress: ProgressCallback | None, start: np.ndarray | None, near_solution: bool) -> SolveResult:
    clock = time.perf_counter()
    solver.start(functional)
    xi, terms = _started(functional, start)
    # the start's record at the time its terms are known, so that each later record's time
    # minus the one before is that iteration alone (`qdframe bench scale`'s s/iter)
    history = [_record(functional, 0, xi, terms, 0.0, None, float("nan"), clock)]
    status, message = Status.MAX_ITER, f"{options.max_iter} iterations spent"
    rejected, rejected_label = 0, ""  # trial points where the model was NaN/inf, and the last piece named
    blocked: tuple[str, np.ndarray, ModelOutputError, str] | None = None  # where the model stops the descent
    uncertified: list[float] = []  # the worst check's value ÷ tolerance at each iterate with I ≤ tol
    # full-step rounds left (:func:`qdframe.descent.steps.watchdog`): where the descent stalls, and
    # (from a coarser grid's solution) where a line search cuts a Newton step
    rounds = {False: WATCHDOG_ROUNDS, True: EAGER_ROUNDS if near_solution else 0}
    eps, delta = options.eps, options.delta  # shrunk where the iterate is ε-stationary but not solved
    window = CERTIFY_WINDOW if solver.full_steps else CERTIFY_WINDOW_FIRST_ORDER
    optimal = False  # the stop is a stationary point of the objective (no decrease predicted, ε at the floor)

    def escape(cut: np.ndarray | None = None) -> bool:
        """A round of full steps (for a solver whose steps are Newton steps, within the budget)
        where the descent would stop `stationary`, or from the step `cut` where the line search
        cut it; True when it found a much lower iterate, which the descent continues from."""
        nonlocal xi, terms
        budget = options.max_iter - (len(history) - 1)
        kind = cut is not None
        if not solver.full_steps or budget < 1 or rounds[kind] < 1:
            return False
        rounds[kind] -= 1
        first = None if cut is None else options.gamma_max * cut  # the cut step taken whole
        path = watchdog(functional, solver, xi, terms.objective, options, min(WATCHDOG_STEPS, budget), first)
        for point, step in path:
            xi, terms = point, functional.terms(point)
            _append(history, progress, _record(functional, len(history), xi, terms, 1.0, step, float("nan"), clock))
        if path:
            uncertified.clear()
            solver.start(functional)  # its kept state (the damping) belongs to the stalled iterate
        return bool(path)

    try:
        while True:
            iteration = len(history)
            if terms.objective <= options.tol and terms.I <= options.tol:
                found = checks.checks(functional, xi, options.residual_tol)
                if not checks.failures(found):
                    status, message = Status.SOLVED, ""
                    break
                uncertified.append(max(check.ratio for check in found))
                if len(uncertified) > window and uncertified[-1] * CERTIFY_SHRINK > uncertified[-1 - window]:
                    if escape():
                        continue
                    status, message = Status.STATIONARY, (f"the pointwise checks shrank by less than "
                                                          f"{CERTIFY_SHRINK:g}× in {window} iterations with I ≤ tol")
                    break
            elif _creeping(functional, solver, options, history, terms):
                if escape():
                    continue
                status, message = Status.STATIONARY, (f"the objective fell by less than {CERTIFY_SHRINK:g}× in "
                                                      f"{CERTIFY_WINDOW} iterations with I = {terms.I:.1e} > tol")
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
                optimal = eps <= EPS_FLOOR  # ε-stationary down to the certified floor
                break
            if direction.stationary:
                if escape():
                    continue
                status, message = Status.STATIONARY, f"{solver.name}: no further decrease predicted"
                optimal = True
                break
            step = keep_start(functional, solver, direction.step)
            gamma, value, bad = _line_search(functional, search, xi, step, terms.objective, direction.slope,
                                             options.gamma_max)
            rejected += len(bad)
            rejected_label = (bad[-1].error.label or rejected_label) if bad else rejected_label
            if not (gamma > 0 and value < terms.objective):
                blocked = _blocked_next_to(xi, step, bad, len(history) - 1)
                if blocked is not None:
                    break
                if escape():
                    continue
                status, message = Status.STATIONARY, "no step along the direction decreases the objective"
                optimal = abs(direction.slope) <= STALL_SLOPE * abs(terms.objective)
                break
            if gamma < options.gamma_max and escape(cut=step):  # full steps may pass the kink
                continue
            if rejected >= REJECTED_LIMIT and bad:  # the descent keeps stepping where the model is not defined: stop
                blocked = (f"a line-search trial point of iteration {iteration}", xi + bad[-1].gamma * step,
                           bad[-1].error,
                           f"{rejected} trial points rejected where the model is non-finite (the limit is "
                           f"{REJECTED_LIMIT}): the descent keeps stepping where the model is not defined; make it "
                           "finite there, or keep the states away from it (in the sets, or by the start)")
                break
            xi = xi + gamma * step
            terms = functional.terms(xi)
            _append(history, progress, _record(functional, iteration, xi, terms, gamma, step, deviation, clock))
    except BackendError as exc:
        status, message = Status.FAILED, str(exc)
    except ModelOutputError as exc:  # at the accepted iterate (its gradients): nothing to return
        raise located(functional, xi, exc, f"the iterate after {len(history) - 1} iterations") from exc
    if blocked is not None:
        where, point, error, why = blocked
        raise located(functional, point, error, where, why) from error
    if optimal and _penalized_optimum(functional, xi, terms, options):
        status, message = Status.SOLVED, ""
    remarks = [] if status == Status.SOLVED else _remarks(options, eps, delta, rejected, rejected_label)
    result = result_of(functional, solver, search, dataclasses.replace(options, eps=eps, delta=delta), xi, status,
                       message, remarks, history, time.perf_counter() - clock)
    result.options["stationary_point"] = optimal  # of the objective: a higher penalty can move it (qdframe.solve.optimum)
    return result


def _blocked_next_to(xi: np.ndarray, step: np.ndarray, bad: list["_Trial"], iterations: int):
    """Where the model is non-finite within a rounding-sized move of ξ along the step (the
    model, not stationarity, stops the descent): `blocked`'s (where, point, error, why), or None."""
    near = NEAR_ITERATE * max(1.0, float(np.max(np.abs(xi)))) / max(float(np.max(np.abs(step))), 1e-300)
    blocking = [trial for trial in bad if trial.gamma <= near]
    if not blocking:
        return None
    trial = min(blocking, key=lambda trial: trial.gamma)
    move = trial.gamma * float(np.max(np.abs(step)))
    return (f"the iterate after {iterations} iterations", xi, trial.error,
            f"a step of {move:.1e} from it along the direction is non-finite and no step "
            "decreases the objective: the descent cannot continue")


def _creeping(functional: Functional, solver: DirectionSolver, options: DescentOptions,
              history: list[IterationRecord], terms) -> bool:
    """I > tol, and the objective fell by less than CERTIFY_SHRINK in the last CERTIFY_WINDOW
    iterations (a Newton-type solver without a cost: the paper's descent converges linearly).
    Such a descent sits at a local minimum of I that it only creeps along: it stops
    `stationary` there (after a watchdog round), so that the solve restarts from another
    start rather than spend its budget (paper-7.3 on 1001 nodes from a 31-node solution,
    tests/test_continuation.py)."""
    return (solver.full_steps and functional.cost is None and terms.I > options.tol
            and len(history) > CERTIFY_WINDOW
            and terms.objective * CERTIFY_SHRINK > history[-1 - CERTIFY_WINDOW].objective)


def _started(functional: Functional, start: np.ndarray | None):
    """The first iterate (the model's initial guess where no `start`), x(t_0) = x0 where
    given, and its terms."""
    xi = functional.initial_point() if start is None else np.array(start, dtype=float)
    given = functional.start_given
    xi[0, : functional.n][given] = functional.model.x0[given]  # x0 is data, not an unknown: exactly
    try:
        return xi, functional.terms(xi)
    except ModelOutputError as exc:
        raise located(functional, xi, exc, "the start") from exc


def _remarks(options: DescentOptions, eps: float, delta: float, rejected: int, label: str) -> list[str]:
    """What an unsolved descent says after its reason: ε and δ shrunk, trial points rejected."""
    remarks = []
    if eps < options.eps:
        remarks.append(f"ε and δ shrunk to {eps:.0e} and {delta:.0e}" + (" (the floor)" if eps <= options.eps_floor else ""))
    if rejected:
        remarks.append(f"{rejected} line-search trial point(s) rejected where the model is non-finite"
                       + (f" (last: {label})" if label else ""))
    return remarks


def _penalized_optimum(functional: Functional, xi: np.ndarray, terms, options: DescentOptions) -> bool:
    """Whether a stationary point of ∫cost + λ·I (`optimal`) is a solution of the discrete problem: with a
    cost whose minimum is not 0 (a shortest time) the objective stays above tol, and its
    stationary point is the answer where I ≤ tol and every pointwise check passes (how close
    it is to the cost's minimum over the solutions: :mod:`qdframe.solve.optimum`)."""
    return (functional.cost is not None and terms.I <= options.tol
            and not checks.failures(checks.checks(functional, xi, options.residual_tol)))


def _record(functional: Functional, iteration: int, xi: np.ndarray, terms, gamma: float, step: np.ndarray | None,
            deviation: float, clock: float) -> IterationRecord:
    """The history's record of iterate ξ reached by γ·step (step None: the start)."""
    norm = 0.0 if step is None else float(np.sqrt(functional.weights @ np.sum(step**2, axis=1)))
    return IterationRecord(iteration, terms.objective, terms.I, gamma, norm, deviation, functional.boundary_error(xi),
                           time.perf_counter() - clock, functional.grid.nodes)


def _append(history: list[IterationRecord], progress: ProgressCallback | None, record: IterationRecord) -> None:
    history.append(record)
    if progress is not None:
        progress(record)


@dataclass(frozen=True)
class _Trial:
    """A line-search trial step γ and, where the model was NaN/inf there, its error."""

    gamma: float
    error: ModelOutputError | None


def _line_search(functional: Functional, search: LineSearch, xi: np.ndarray, step: np.ndarray, objective: float,
                 slope: float, gamma_max: float) -> tuple[float, float, list[_Trial]]:
    """The line search's γ along ξ + γ·step and its objective, with the trial points where
    the model was NaN/inf (each counts as no decrease: +inf)."""
    trials: list[_Trial] = []
    ray = functional.ray(xi, step)

    def along(gamma: float) -> float:
        """The objective at ξ + γG; +inf (no decrease) where the model is NaN/inf (the trial is
        recorded and the result's remarks count it: NumPy's overflow warnings would only repeat it)."""
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                value = ray(gamma)
        except ModelOutputError as exc:
            if not exc.nonfinite:
                raise
            trials.append(_Trial(gamma, exc))
            return np.inf
        if not np.isfinite(value):
            trials.append(_Trial(gamma, ModelOutputError(f"model {functional.model.name!r}: the objective overflows",
                                                         nonfinite=True)))
            return np.inf
        return value

    gamma, value = search.search(along, objective, slope, gamma_max)
    return gamma, value, trials
