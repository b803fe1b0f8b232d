"""`golden`: golden-section minimization of I(ξ + γG) on [0, γ̄] (paper (180))."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from .base import LineSearch

_RATIO = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True)
class GoldenSection(LineSearch):
    """Bounded golden-section search; if it finds no decrease, it searches again on
    [0, γ̄·shrink], up to `retries` times, before reporting γ = 0."""

    name = "golden"
    rtol: float = 1e-6
    shrink: float = 1e-3
    retries: int = 4

    def search(self, along: Callable[[float], float], value: float, slope: float, gamma_max: float) -> tuple[float, float]:
        upper = gamma_max
        for _ in range(self.retries + 1):
            gamma, best = _golden(along, upper, self.rtol * upper)
            if best < value:
                return gamma, best
            upper *= self.shrink
        return 0.0, value


def _golden(f: Callable[[float], float], upper: float, tol: float) -> tuple[float, float]:
    lo, hi = 0.0, upper
    a, b = hi - _RATIO * (hi - lo), lo + _RATIO * (hi - lo)
    fa, fb = f(a), f(b)
    while hi - lo > tol:
        if fa <= fb:
            hi, b, fb = b, a, fa
            a = hi - _RATIO * (hi - lo)
            fa = f(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + _RATIO * (hi - lo)
            fb = f(b)
    f_end = f(upper)  # the bound itself, which the bracket never evaluates
    candidates = [(fa, a), (fb, b), (f_end, upper)]
    best, gamma = min(candidates)
    return gamma, best
