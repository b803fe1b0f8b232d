"""A cost whose minimum over the solutions is not zero (a shortest time, a least effort):
the penalty λ of 𝒥 + λ·I raised until the penalized minimizer is a solution and an optimum
within the target.

The paper minimizes 𝒥(x) + λ·I(x, z) with a fixed λ (Example 7.1, λ = 10), which finds a
solution of the inclusion only where 𝒥's minimum is 0 (there both terms vanish together).
Where it is not, the minimizer x_λ trades cost against I: near the solutions I is
quadratic in the residuals r (I ≈ ‖r‖²), the stationarity of 𝒥 + λ‖r‖² gives the
multiplier μ ≈ 2λ·r, and to first order

    𝒥* − 𝒥(x_λ) ≈ μ·r = 2λ·I(x_λ)   (the optimality gap),    r(x_λ) = O(1/λ),

𝒥* the least cost over the solutions. (For a shortest time, 𝒥 = T and the gap is T* − T_λ;
on ``block-time-optimal`` the measured T* − T_λ is 2λ·I to three digits at λ = 1e5 … 1e9.)

So the solve is the usual one with λ raised between rounds (:func:`raise_penalty`): after a
round at λ, the gap 2λ·I and every pointwise check (:mod:`qdframe.descent.checks`) fall like 1/λ,
I like 1/λ², so λ is multiplied by RAISE_SAFETY times the largest of (the gap ÷
GAP_FRACTION·target, the worst check ÷ its tolerance, √(I ÷ tol)), between MIN_RAISE and
MAX_RAISE, and made at least 1/(GAP_FRACTION·target) (the gap is c/λ: c = 1 is the first
guess), until a round is solved with the gap within GAP_FRACTION of the target (or λ would
pass MAX_PENALTY: the result says so). A round starts from the last one's trajectory where
that one is on the path x_λ → x* (its gap at most WARM_SHARE of its cost), else afresh from
the straight line between the given ends (:func:`qdframe.solve.start.straight_guess`): a small λ
can make the cost win outright (a shortest time at λ = 1 shrinks T towards 0 with the block
at rest), and the path does not lead back from there; and from the model's start at rest a
round can stop on a stuck phase (a block with |u| ≤ 1.5: I = 0.12).
The descent ends such a round `solved` at a stationary point of 𝒥 + λ·I with I ≤ tol and
every check passed (:func:`qdframe.descent.loop._penalized_optimum`).

The error estimate of the result adds to the grid's estimate the penalty's part, the
distance still to go as λ → ∞ extrapolated from the last two rounds (x_λ − x* is O(1/λ)):
max|x_λ − x_λ'|·λ'/(λ − λ'), λ' the round before. A cost whose minimum is reached with
𝒥 ≤ tol (Example 7.1) is solved in the first round, and its penalty part is 0.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

import numpy as np

from ..certificates.estimates import observed_difference
from ..descent.multipliers import PENALTY_CAP
from ..model import InclusionModel
from .start import straight_guess
from ..status import Status

if TYPE_CHECKING:
    from ..functional import Functional
    from ..result import SolveResult

GAP_FRACTION = 0.1  # the optimality gap 2λ·I is kept within this share of the target
RAISE_SAFETY = 10.0  # λ is raised this much past what the first-order rates say is enough
MIN_RAISE, MAX_RAISE = 10.0, 1e4  # the raise of one round
MAX_PENALTY = 1e12  # past it the steps' rounding, not the penalty, limits the answer
WARM_SHARE = 0.1  # a round starts from the last one's trajectory where its gap is within this share of its cost
EASE = 0.1  # a raised λ restarted far from its path x_λ is first solved at this share of it (needs_easing)


@dataclasses.dataclass
class Round:
    """One solve of 𝒥 + λ·I: its λ, its last grid's functional, its result and the iterations it took."""

    weight: float
    functional: Functional
    result: SolveResult

    def __post_init__(self) -> None:
        self.iterations = self.result.history[-1].iteration if self.result.history else 0


def penalized(model: InclusionModel, weight: float, previous: SolveResult | None) -> InclusionModel:
    """A copy of `model` whose cost has the penalty `weight` and whose start is the trajectory
    of `previous` (x, z and the controls, interpolated in t), if given."""
    out = copy.copy(model)
    cost = model.cost()
    out.cost = lambda: dataclasses.replace(cost, weight=float(weight))  # type: ignore[method-assign]
    if previous is None and len(model.end_indices):  # a fresh start: the straight line between the given ends
        out.initial_guess = lambda times: straight_guess(model, times)  # type: ignore[method-assign]
    if previous is not None:
        t, x, z = np.asarray(previous.t, float), np.asarray(previous.x, float), np.asarray(previous.z, float)
        u = None if previous.u is None else np.asarray(previous.u, float)

        def along(values: np.ndarray, times: np.ndarray) -> np.ndarray:
            return np.stack([np.interp(times, t, column) for column in values.T], axis=1) if values.size else \
                np.zeros((times.size, values.shape[1]))

        out.initial_guess = lambda times: (along(x, times), along(z, times))  # type: ignore[method-assign]
        if u is not None and u.shape[1]:
            out.initial_controls = lambda times: along(u, times)  # type: ignore[method-assign]
    return out


def gap(result: SolveResult, weight: float) -> float:
    """The first-order optimality gap 𝒥* − 𝒥(x_λ) ≈ 2λ·I (module docstring)."""
    return 2.0 * weight * float(result.I)


def raise_by(result: SolveResult, weight: float, target: float, tol: float) -> float | None:
    """The factor to raise λ by after a round, or None where the round is the answer (solved
    with the gap within GAP_FRACTION·target) or no higher λ can help (it did not end solved
    or at a stationary point of 𝒥 + λ·I, or the gap, I and every check are within their
    tolerances already)."""
    if not (result.status == Status.SOLVED
            or (result.status == Status.STATIONARY and result.descent.stationary_point)):
        return None  # the descent's own limit (a fixed ε, the budget) ended it, not λ
    wanted = gap(result, weight) / (GAP_FRACTION * target)
    if result.status == Status.SOLVED and wanted <= 1.0:
        return None
    checks = [check["value"] / check["tol"] for check in result.checks.values() if check["tol"] > 0]
    needed = max([wanted, np.sqrt(max(float(result.I), 0.0) / tol), *checks])
    if needed <= 1.0:  # nothing λ governs is out of its tolerance: the descent's stop, not λ, ended the round
        return None
    return float(np.clip(RAISE_SAFETY * needed, MIN_RAISE, MAX_RAISE))


def raise_penalty(model: InclusionModel, first: tuple[Functional, SolveResult], target: Callable[[SolveResult], float],
                  tol: float, rerun: Callable[[InclusionModel], tuple[Functional, SolveResult]]) -> list[Round]:
    """The rounds of 𝒥 + λ·I from the model's λ (`first`: its functional and result) with λ
    raised until :func:`raise_by` says stop or λ would pass MAX_PENALTY; `rerun(model)` solves
    a model (the grids without the verdict)."""
    weight = float(model.cost().weight)  # type: ignore[union-attr]
    rounds = [Round(weight, *first)]
    while (factor := raise_by(rounds[-1].result, weight, target(rounds[-1].result), tol)) is not None:
        if weight * factor > MAX_PENALTY:
            rounds[-1].result.remarks.append(
                f"the penalty λ = {weight:.0e} would pass {MAX_PENALTY:.0e} to bring the optimality gap "
                f"{gap(rounds[-1].result, weight):.1e} (2λ·I) within the target")
            break
        last = rounds[-1].result
        weight = max(weight * factor, 1.0 / (GAP_FRACTION * target(last)))
        # on the path x_λ where the penalty's share of the objective is small; else from the model's start
        warm = last.cost is not None and gap(last, rounds[-1].weight) <= WARM_SHARE * abs(last.cost)
        rounds.append(Round(weight, *rerun(penalized(model, weight, last if warm else None))))
    return rounds


def needs_easing(functional: Functional, start: np.ndarray) -> bool:
    """Whether a descent of 𝒥 + λ·I from `start` (another grid's solution, interpolated) should
    first run at EASE·λ (:func:`eased`): a raised penalty (no multipliers' shifts, λ above their
    cap) whose part λ·I of the start's objective exceeds the cost's. Where the refinement moves
    from implicit Euler's first grid to radau-iia on its mesh, λ·I is 1e6–1e9 at λ ~ 1e9 (the
    first-order scheme's solution is O(h) from the other's); Gauss–Newton at that λ cannot move
    along the constraints, and the descent ended wherever rounding led it: the fastest move by
    5 with |u| ≤ 2 from T = 2 `stationary` at T = 4.87 with OpenBLAS's Haswell kernels (T* = 3.65).
    At EASE·λ it reaches x_λ', and from there λ·(1/EASE), a step the rounds take, is safe."""
    if functional.cost is None or functional.shifts is not None or functional.penalty <= PENALTY_CAP:
        return False
    terms = functional.terms(start)
    penalty = functional.penalty * float(terms.I)
    return penalty > abs(float(terms.objective) - penalty)


@contextmanager
def eased(functional: Functional) -> Iterator[None]:
    """The functional at EASE·λ inside the block (:func:`needs_easing`)."""
    weight = functional.penalty
    functional.set_multipliers(None, EASE * weight)
    try:
        yield
    finally:
        functional.set_multipliers(None, weight)


def penalty_error(rounds: list[Round]) -> float:
    """The part of the error the finite λ leaves: the change from the round before, in what
    the user is given (x at the user's times, and a T or parameters found: the model's
    ``observed``, as the bisection estimate compares), times λ'/(λ − λ'), λ' the round
    before (x_λ − x* is O(1/λ)); 0 with one round (the cost's minimum reached with 𝒥 ≤ tol,
    where the penalty is exact)."""
    if len(rounds) < 2:
        return 0.0
    changes = [_change(later, earlier) for earlier, later in zip(rounds[-3:-1], rounds[-2:])]
    last, before = rounds[-1], rounds[-2]
    if last.functional.shifts is None:  # the penalty raised: x_λ − x* is O(1/λ)
        return changes[-1] * before.weight / (last.weight - before.weight)
    # the multipliers' rounds converge linearly: what is left is the last change times ρ/(1 − ρ),
    # ρ the last two changes' ratio (at most 1/2; 1/2 where there is one change)
    rate = min(changes[-1] / changes[0], 0.5) if len(changes) == 2 and 0 < changes[0] < np.inf else 0.5
    return changes[-1] * rate / (1.0 - rate)


def _change(later: Round, earlier: Round) -> float:
    """max |x_later − x_earlier| in what the user is given (:func:`observed_difference`)."""
    difference = observed_difference(later.functional.model, later.functional.grid, np.asarray(later.result.x, float),
                                     earlier.functional.grid, np.asarray(earlier.result.x, float))
    return float(np.max(np.abs(difference)))

