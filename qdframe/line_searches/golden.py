"""`golden`: golden-section minimization of I(ξ + γG) on [0, γ̄] (paper (180))."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from .base import LineSearch

_RATIO = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True)
class GoldenSection(LineSearch):
    """Bounded golden-section search on [0, γ̄].

    Golden section assumes one minimum on the interval. When I along G is not unimodal
    and the bracket closes on a point no lower than I(ξ) (a decrease confined near 0
    that the first probes stepped over), γ is halved from γ̄ until I decreases, up to
    `halvings` times, and the search repeats on [0, 2γ]; γ = 0 if no decrease is found.
    """

    name = "golden"
    rtol: float = 1e-6
    halvings: int = 60

    def search(self, along: Callable[[float], float], value: float, slope: float, gamma_max: float) -> tuple[float, float]:
        gamma, best = _golden(along, gamma_max, self.rtol * gamma_max)
        if best < value:
            return gamma, best
        trial = gamma_max
        for _ in range(self.halvings):
            trial *= 0.5
            lower = along(trial)
            if lower < value:
                upper = min(2.0 * trial, gamma_max)
                gamma, best = _golden(along, upper, self.rtol * upper)
                return (gamma, best) if best < lower else (trial, lower)
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
