"""`armijo`: backtracking from γ̄ until the Armijo sufficient-decrease test holds."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from .base import LineSearch


@dataclass(frozen=True)
class Armijo(LineSearch):
    """γ = γ̄·βʲ for the least j with I(ξ + γG) ≤ I(ξ) + c·γ·I'(ξ; G)."""

    name = "armijo"
    c: float = 1e-4
    beta: float = 0.5
    max_halvings: int = 60

    def search(self, along: Callable[[float], float], value: float, slope: float, gamma_max: float) -> tuple[float, float]:
        decrease = min(slope, 0.0)
        gamma = gamma_max
        for _ in range(self.max_halvings):
            trial = along(gamma)
            if trial <= value + self.c * gamma * decrease and trial < value:
                return gamma, trial
            gamma *= self.beta
        return 0.0, value
