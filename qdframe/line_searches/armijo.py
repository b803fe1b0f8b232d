"""`armijo`: backtracking from γ̄ until the Armijo sufficient-decrease test holds."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .base import LineSearch

ROUNDING = 4.0 * float(np.finfo(float).eps)  # a decrease below this share of |value| is the objective's rounding


@dataclass(frozen=True)
class Armijo(LineSearch):
    """γ = γ̄·βʲ for the least j with I(ξ + γG) ≤ I(ξ) + c·γ·I'(ξ; G).

    Along a descent direction (slope < 0) the halving stops, with no step, once even the whole
    first-order decrease γ·|slope| is below ROUNDING·|value|: no trial can show a decrease the
    objective's rounding does not swamp (a stalled search used to halve all `max_halvings`
    times, 60 objectives, most of a cost's solve time near its optimum)."""

    name = "armijo"
    c: float = 1e-4
    beta: float = 0.5
    max_halvings: int = 60

    def search(self, along: Callable[[float], float], value: float, slope: float, gamma_max: float) -> tuple[float, float]:
        decrease = min(slope, 0.0)
        floor = ROUNDING * abs(value)
        gamma = gamma_max
        for _ in range(self.max_halvings):
            if decrease < 0.0 and gamma * -decrease < floor:
                break
            trial = along(gamma)
            if trial <= value + self.c * gamma * decrease and trial < value:
                return gamma, trial
            gamma *= self.beta
        return 0.0, value
