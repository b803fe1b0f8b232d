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
round at λ, the gap 2λ·I and every pointwise check (:mod:`qdframe.certify`) fall like 1/λ,
I like 1/λ², so λ is multiplied by RAISE_SAFETY times the largest of (the gap ÷
GAP_FRACTION·target, the worst check ÷ its tolerance, √(I ÷ tol)), between MIN_RAISE and
MAX_RAISE, and made at least 1/(GAP_FRACTION·target) (the gap is c/λ: c = 1 is the first
guess), until a round is solved with the gap within GAP_FRACTION of the target (or λ would
pass MAX_PENALTY: the result says so). A round starts from the last one's trajectory where
that one is on the path x_λ → x* (its gap at most WARM_SHARE of its cost), else from the
model's start: a small λ can make the cost win outright (a shortest time at λ = 1 shrinks T
towards 0 with the block at rest), and the path does not lead back from there.
The descent ends such a round `solved` at a stationary point of 𝒥 + λ·I with I ≤ tol and
every check passed (:func:`qdframe.descent._penalized_optimum`).

The error estimate of the result adds to the grid's estimate the penalty's part, the
distance still to go as λ → ∞ extrapolated from the last two rounds (x_λ − x* is O(1/λ)):
max|x_λ − x_λ'|·λ'/(λ − λ'), λ' the round before. A cost whose minimum is reached with
𝒥 ≤ tol (Example 7.1) is solved in the first round, and its penalty part is 0.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from .model import InclusionModel
from .status import Status

if TYPE_CHECKING:
    from .result import SolveResult

GAP_FRACTION = 0.1  # the optimality gap 2λ·I is kept within this share of the target
RAISE_SAFETY = 10.0  # λ is raised this much past what the first-order rates say is enough
MIN_RAISE, MAX_RAISE = 10.0, 1e4  # the raise of one round
MAX_PENALTY = 1e12  # past it the steps' rounding, not the penalty, limits the answer
WARM_SHARE = 0.1  # a round starts from the last one's trajectory where its gap is within this share of its cost


@dataclasses.dataclass
class Round:
    """One solve of 𝒥 + λ·I: its λ and its result."""

    weight: float
    result: SolveResult


def penalized(model: InclusionModel, weight: float, previous: SolveResult | None) -> InclusionModel:
    """A copy of `model` whose cost has the penalty `weight` and whose start is the trajectory
    of `previous` (x, z and the controls, interpolated in t), if given."""
    out = copy.copy(model)
    cost = model.cost()
    out.cost = lambda: dataclasses.replace(cost, weight=float(weight))  # type: ignore[method-assign]
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
    or stationary)."""
    if result.status not in (Status.SOLVED, Status.STATIONARY):
        return None
    wanted = gap(result, weight) / (GAP_FRACTION * target)
    if result.status == Status.SOLVED and wanted <= 1.0:
        return None
    checks = [check["value"] / check["tol"] for check in result.checks.values() if check["tol"] > 0]
    needed = max([wanted, np.sqrt(max(float(result.I), 0.0) / tol), *checks])
    return float(np.clip(RAISE_SAFETY * needed, MIN_RAISE, MAX_RAISE))


def raise_penalty(model: InclusionModel, first: SolveResult, target: Callable[[SolveResult], float], tol: float,
                  rerun: Callable[[InclusionModel], SolveResult]) -> tuple[InclusionModel, list[Round]]:
    """The rounds of 𝒥 + λ·I from the model's λ (`first` its result) with λ raised until
    :func:`raise_by` says stop or λ would pass MAX_PENALTY; `rerun(model)` solves a model
    (the grids without the verdict). Returns the model of the last round and every round."""
    weight = float(model.cost().weight)  # type: ignore[union-attr]
    rounds, current = [Round(weight, first)], model
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
        current = penalized(model, weight, last if warm else None)
        rounds.append(Round(weight, rerun(current)))
    return current, rounds


def penalty_error(rounds: list[Round]) -> float:
    """The part of x's error the finite λ leaves: max|x_λ − x_λ'|·λ'/(λ − λ') over the last two
    rounds (the grids of both rounds before the verdict: the same points, else x_λ'
    interpolated to x_λ's times); 0 with one round (the cost's minimum reached with 𝒥 ≤ tol,
    where the penalty is exact)."""
    if len(rounds) < 2:
        return 0.0
    last, before = rounds[-1], rounds[-2]
    t, x = np.asarray(last.result.t, float), np.asarray(last.result.x, float)
    earlier = np.asarray(before.result.x, float)
    if earlier.shape != x.shape or not np.allclose(before.result.t, t, rtol=0.0, atol=1e-14 * max(1.0, t[-1])):
        earlier = np.stack([np.interp(t, before.result.t, column) for column in earlier.T], axis=1)
    return float(np.max(np.abs(x - earlier))) * before.weight / (last.weight - before.weight)
