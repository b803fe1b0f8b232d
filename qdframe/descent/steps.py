"""A direction's step as the descent takes it: exact on the given x(t_0)
(:func:`keep_start`), and full steps where the monotone descent stalled or cut a Newton
step (:func:`watchdog`)."""

from __future__ import annotations

import numpy as np

from . import checks
from .checks import CERTIFY_SHRINK
from ..directions.base import DirectionSolver
from ..errors import BackendError, ModelOutputError
from ..functional import Functional
from .options import DescentOptions


START_ROUNDING = 1e-9  # a direction's move of a given x(t_0), relative to max(1, ‖G‖∞), that is rounding
# where the descent would stop `stationary`, a solver whose steps are Newton steps (`full_steps`)
# gets up to WATCHDOG_ROUNDS rounds of WATCHDOG_STEPS full steps (:func:`watchdog`), kept when
# they end WATCHDOG_GAIN lower (a long stick-slip horizon on a fine mesh stalls with one selection
# on the wrong side of a crossing, which a few full steps correct)
WATCHDOG_ROUNDS = 3
WATCHDOG_STEPS = 6
WATCHDOG_GAIN = 1e-2
# and, in a descent that starts from a coarser grid's solution, once where the line search cuts a
# Newton step (γ < γ̄): the same round from that iterate, nonmonotone as the technique is meant.
# There the selections' kinks sit a few nodes from where the solution puts them, and a line search
# lets semismooth Newton move them about one node per step; full steps move them all at once.
# Not from other starts: far from a solution a full-step path can end at a degenerate member of
# the solution set (a free period T → 0 on relay-period), and more rounds led descents astray.
EAGER_ROUNDS = 1


def keep_start(functional: Functional, solver: DirectionSolver, step: np.ndarray) -> np.ndarray:
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


def watchdog(functional: Functional, solver: DirectionSolver, xi: np.ndarray, objective: float,
             options: DescentOptions, steps: int,
             first: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Full steps from ξ where the monotone descent stalled or cut a Newton step (the
    watchdog technique of Chamberlain, Powell, Lemaréchal and Pedersen, 1982): semismooth
    Newton next to a kink of the selections' natural map (a switch between two points of a
    fine grid) can need a step that raises I before the next ones lower it far below, which
    a line search that demands a decrease at every step never takes. From a fresh solver
    state (its damping reset), up to `steps` steps γ = 1 (the first one `first` where given:
    the step a line search cut, taken whole): the path to the first solved iterate (I ≤ tol
    and every pointwise check passes), else to the lowest one if that is at most
    WATCHDOG_GAIN × `objective`, else to the one with I ≤ tol whose pointwise checks are
    nearest their tolerances if CERTIFY_SHRINK× nearer than at ξ, else an empty list, the
    solver's state as it was (the descent stops where it stalled, or goes on as if the
    round had not been tried)."""
    kept = solver.snapshot()
    solver.start(functional)
    path: list[tuple[np.ndarray, np.ndarray]] = []
    best, best_at = objective, 0
    worst = worst_ratio(functional, xi, objective, options)  # the checks' worst ratio where I ≤ tol
    nearer, nearer_at = worst / CERTIFY_SHRINK, 0
    point = xi
    try:
        for count in range(1, steps + 1):
            if count == 1 and first is not None:
                step = first
            else:
                direction = solver.compute(functional, point, options.delta)
                if direction.stationary:
                    break
                step = keep_start(functional, solver, direction.step)
            point = point + step
            terms = functional.terms(point)
            if not np.isfinite(terms.objective):
                break
            path.append((point, step))
            ratio = worst_ratio(functional, point, terms.objective if terms.I <= options.tol else np.inf, options)
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
    solver.restore(kept)
    return []


def worst_ratio(functional: Functional, xi: np.ndarray, objective: float, options: DescentOptions) -> float:
    """The largest value ÷ tolerance of the pointwise checks at ξ where its objective is ≤ tol
    (≤ 1: solved), else inf."""
    if not objective <= options.tol:
        return np.inf
    return max(check.ratio for check in checks.checks(functional, xi, options.residual_tol))
