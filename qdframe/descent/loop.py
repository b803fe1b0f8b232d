"""The δ-quasidifferential descent loop (paper Section 6): from a start ξ, a direction G
per iteration (:mod:`qdframe.directions`), a step γ along it (:mod:`qdframe.line_searches`),
until the objective and I are ≤ tol and every pointwise check passes (:mod:`qdframe.descent.checks`)
or the descent can go no further. The public call, with its grids and certificate, is
:func:`qdframe.solve.solving.solve`."""

from __future__ import annotations

import dataclasses
import functools
import time
from dataclasses import dataclass

import numpy as np
from threadpoolctl import ThreadpoolController

from . import checks, multipliers
from .checks import CERTIFY_SHRINK
from ..directions.base import DirectionSolver
from ..errors import BackendError, ModelOutputError
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
        if multipliers.applies(functional, solver):  # a cost: its optimum by the method of multipliers

            done = [0]  # iterations of the descents so far: progress counts on over them

            def once(xi: np.ndarray | None, budget: int, near: bool, watchdog: bool = True) -> SolveResult:
                shown = None if progress is None else (
                    lambda record, used=done[0]: progress(dataclasses.replace(record, iteration=record.iteration + used)))
                result = _descend(functional, solver, search, dataclasses.replace(options, max_iter=budget), shown,
                                  xi, near, watchdog)
                done[0] += result.iterations
                return result

            return multipliers.optimum(functional, solver, options, once, start, near_solution)
        return _descend(functional, solver, search, options, progress, start, near_solution)


@functools.cache
def _blas() -> ThreadpoolController:
    """The process's thread pools, found once, at the first descent (finding them searches the loaded
    libraries, a millisecond or two: a solve runs a descent per grid and per settling round)."""
    return ThreadpoolController()


def _descend(functional: Functional, solver: DirectionSolver, search: LineSearch, options: DescentOptions,
             progress: ProgressCallback | None, start: np.ndarray | None, near_solution: bool,
             watchdog: bool = True) -> SolveResult:
    descent = _Descent(functional, solver, search, options, progress, start, near_solution, watchdog)
    try:
        while descent.advance():
            pass
    except BackendError as exc:
        descent.status, descent.message = Status.FAILED, str(exc)
    except ModelOutputError as exc:  # at the accepted iterate (its gradients): nothing to return
        raise located(functional, descent.xi, exc, f"the iterate after {len(descent.history) - 1} iterations") from exc
    return descent.finished()


class _Descent:
    """One descent's state between iterations: the iterate and its terms, the history, how it
    ends (status, message), and what its stopping rules keep (the full-step rounds left, the
    worst check's ratios with I ≤ tol, the shrunk ε and δ, the rejected trial points)."""

    def __init__(self, functional: Functional, solver: DirectionSolver, search: LineSearch, options: DescentOptions,
                 progress: ProgressCallback | None, start: np.ndarray | None, near_solution: bool,
                 watchdog: bool = True) -> None:
        self.functional, self.solver, self.search, self.options, self.progress = (functional, solver, search,
                                                                                   options, progress)
        self.clock = time.perf_counter()
        solver.start(functional)
        self.xi, self.terms = _started(functional, start)
        # the start's record at the time its terms are known, so that each later record's time
        # minus the one before is that iteration alone (`qdframe bench scale`'s s/iter)
        self.history = [_record(functional, 0, self.xi, self.terms, 0.0, None, float("nan"), self.clock)]
        self.status, self.message = Status.MAX_ITER, f"{options.max_iter} iterations spent"
        self.rejected, self.rejected_label = 0, ""  # trial points where the model was NaN/inf, the last piece named
        self.blocked: tuple[str, np.ndarray, ModelOutputError, str] | None = None  # where the model stops it
        self.uncertified: list[float] = []  # the worst check's value ÷ tolerance at each iterate with I ≤ tol
        # full-step rounds left (:func:`qdframe.descent.steps.watchdog`): where the descent stalls, and
        # (from a coarser grid's solution) where a line search cuts a Newton step
        # (no watchdog where the caller says: a multiplier round's stall is its shifts', not a kink's)
        self.rounds = {False: WATCHDOG_ROUNDS if watchdog else 0, True: EAGER_ROUNDS if near_solution else 0}
        self.eps, self.delta = options.eps, options.delta  # shrunk where ε-stationary but not solved
        self.window = CERTIFY_WINDOW if solver.full_steps else CERTIFY_WINDOW_FIRST_ORDER
        self.optimal = False  # the stop is a stationary point of the objective (no decrease predicted, ε at the floor)

    def stop(self, status: Status, message: str, optimal: bool = False) -> bool:
        self.status, self.message, self.optimal = status, message, optimal
        return False

    def escape(self, cut: np.ndarray | None = None) -> bool:
        """A round of full steps (for a solver whose steps are Newton steps, within the budget)
        where the descent would stop `stationary`, or from the step `cut` where the line search
        cut it; True when it found a much lower iterate, which the descent continues from."""
        functional, solver, options = self.functional, self.solver, self.options
        budget = options.max_iter - (len(self.history) - 1)
        kind = cut is not None
        if not solver.full_steps or budget < 1 or self.rounds[kind] < 1:
            return False
        self.rounds[kind] -= 1
        first = None if cut is None else options.gamma_max * cut  # the cut step taken whole
        path = watchdog(functional, solver, self.xi, self.terms.objective, options, min(WATCHDOG_STEPS, budget), first)
        for point, step in path:
            self.xi, self.terms = point, functional.terms(point)
            _append(self.history, self.progress, _record(functional, len(self.history), self.xi, self.terms, 1.0,
                                                         step, float("nan"), self.clock))
        if path:
            self.uncertified.clear()
            solver.start(functional)  # its kept state (the damping) belongs to the stalled iterate
        return bool(path)

    def settled(self) -> bool | None:
        """The stopping rules at the iterate, before a direction: False to stop, True to go on
        from a new iterate (a round of full steps), None to take the next step."""
        functional, options, terms = self.functional, self.options, self.terms
        if terms.objective <= options.tol and terms.I <= options.tol:
            found = checks.checks(functional, self.xi, options.residual_tol)
            if not checks.failures(found):
                return self.stop(Status.SOLVED, "")
            self.uncertified.append(max(check.ratio for check in found))
            window = self.window
            if len(self.uncertified) > window and self.uncertified[-1] * CERTIFY_SHRINK > self.uncertified[-1 - window]:
                return True if self.escape() else self.stop(
                    Status.STATIONARY, f"the pointwise checks shrank by less than {CERTIFY_SHRINK:g}× in {window} "
                                       "iterations with I ≤ tol")
        elif _creeping(functional, self.solver, options, self.history, terms):
            return True if self.escape() else self.stop(
                Status.STATIONARY, f"the objective fell by less than {CERTIFY_SHRINK:g}× in {CERTIFY_WINDOW} "
                                   f"iterations with I = {terms.I:.1e} > tol")
        return None

    def advance(self) -> bool:
        """One iteration (paper Section 6): False where the descent stops."""
        functional, solver, options = self.functional, self.solver, self.options
        iteration = len(self.history)
        settled = self.settled()
        if settled is not None:
            return settled
        if iteration > options.max_iter:
            return False
        direction = solver.compute(functional, self.xi, self.delta)
        deviation = float(np.max(direction.deviation))
        if direction.stationary is None and deviation <= self.eps:
            if self.eps > options.eps_floor:  # ε-stationary, not solved: the paper's ε and δ shrink, on it goes
                shrunk = max(self.eps / EPS_SHRINK, options.eps_floor)
                self.eps, self.delta = shrunk, self.delta * shrunk / self.eps
                self.uncertified.clear()
                return True
            # ε-stationary down to the certified floor: a stationary point
            return self.stop(Status.STATIONARY, f"deviation {deviation:.2e} ≤ ε at every node", self.eps <= EPS_FLOOR)
        if direction.stationary:
            return True if self.escape() else self.stop(
                Status.STATIONARY, f"{solver.name}: no further decrease predicted", True)
        step = keep_start(functional, solver, direction.step)
        gamma, value, bad = _line_search(functional, self.search, self.xi, step, self.terms.objective, direction.slope,
                                         options.gamma_max)
        self.rejected += len(bad)
        self.rejected_label = (bad[-1].error.label or self.rejected_label) if bad else self.rejected_label
        if not (gamma > 0 and value < self.terms.objective):
            self.blocked = _blocked_next_to(self.xi, step, bad, len(self.history) - 1)
            if self.blocked is not None:
                return False
            return True if self.escape() else self.stop(
                Status.STATIONARY, "no step along the direction decreases the objective",
                abs(direction.slope) <= STALL_SLOPE * abs(self.terms.objective))
        if gamma < options.gamma_max and self.escape(cut=step):  # full steps may pass the kink
            return True
        if self.rejected >= REJECTED_LIMIT and bad:  # the descent keeps stepping where the model is not defined
            self.blocked = (f"a line-search trial point of iteration {iteration}", self.xi + bad[-1].gamma * step,
                            bad[-1].error,
                            f"{self.rejected} trial points rejected where the model is non-finite (the limit is "
                            f"{REJECTED_LIMIT}): the descent keeps stepping where the model is not defined; make it "
                            "finite there, or keep the states away from it (in the sets, or by the start)")
            return False
        self.xi = self.xi + gamma * step
        self.terms = functional.terms(self.xi)
        _append(self.history, self.progress, _record(functional, iteration, self.xi, self.terms, gamma, step,
                                                     deviation, self.clock))
        return True

    def finished(self) -> SolveResult:
        """The result of the last iterate (a model that blocks the descent raised, named)."""
        functional, options = self.functional, self.options
        if self.blocked is not None:
            where, point, error, why = self.blocked
            raise located(functional, point, error, where, why) from error
        status, message = self.status, self.message
        if self.optimal and _penalized_optimum(functional, self.xi, self.terms, options):
            status, message = Status.SOLVED, ""
        remarks = [] if status == Status.SOLVED else _remarks(options, self.eps, self.delta, self.rejected,
                                                               self.rejected_label)
        result = result_of(functional, self.solver, self.search,
                           dataclasses.replace(options, eps=self.eps, delta=self.delta), self.xi, status, message,
                           remarks, self.history, time.perf_counter() - self.clock)
        # a stationary point of the objective: a higher penalty can move it (qdframe.solve.optimum)
        result.descent = dataclasses.replace(result.descent, stationary_point=self.optimal)
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
