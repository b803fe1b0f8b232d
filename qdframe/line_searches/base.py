"""The LineSearch interface: choose γ along a direction (paper (180))."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import ClassVar


class LineSearch(ABC):
    """Chooses the step γ ∈ (0, γ̄] along a direction G.

    `along(γ)` is the objective at ξ + γG (:meth:`~qdframe.functional.Functional.ray`:
    χ + υ in closed form, each trial evaluates only the set pieces); `value` is its value
    at γ = 0 and `slope` the directional derivative there (negative for a descent
    direction). Returns (γ, along(γ)); γ = 0 means no decrease was found.
    """

    name: ClassVar[str] = ""

    @abstractmethod
    def search(
        self, along: Callable[[float], float], value: float, slope: float, gamma_max: float
    ) -> tuple[float, float]:
        ...
