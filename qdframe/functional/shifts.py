"""The augmented Lagrangian's shifts: each residual of I moved by its multiplier over λ.

A cost whose least value over the solutions is not 0 is minimized subject to the
inclusion, I's residuals r being the constraints. The method of multipliers (Hestenes
1969, Powell 1969; Nocedal & Wright, Numerical Optimization, 2nd ed., §17.3–17.4) minimizes

    𝒥 + (λ/2)·Σ w·(r + s)²      (an equation r = 0: υ, χ, ω, a point set's φ, σ)
    𝒥 + (λ/2)·Σ w·max(0, ℓ + s)²   (an inequality ℓ ≤ 0: a side of a set, a bound)

with s = y/λ, y the multipliers, and after each minimization moves s ← s + r (an
equation) or s ← max(0, s + ℓ) (an inequality). With s → y*/λ the minimizer is the
constrained optimum at a fixed, moderate λ: no penalty driven to infinity.

:class:`Shifts` holds s on the nodes of the grid it was found on (`t`) and gives it on any
other grid by linear interpolation in t (:meth:`Shifts.at`): the multipliers y = λ·w·(r + s)
are the discrete costates, so s as a function of t does not depend on the grid.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields, replace

import numpy as np


@dataclass(frozen=True)
class Shifts:
    """s of every residual of I, on the nodes `t` (arrays with one row per node, `end` one value
    per end condition). `blocks` (N, B, 2): per block the shift of its side ψ = +1 (a point
    set's equation, an S_k block's ψ* side) and of ψ = −1; `bounds` (N, q): per finite side
    of a bound (:class:`~.terms.Bounds`)."""

    t: np.ndarray
    consistency: np.ndarray  # υ: x_k − x0 − Z_k
    end: np.ndarray  # χ
    surface: np.ndarray  # ω: e(x_k), (N, o) (o = 0 without a surface)
    blocks: np.ndarray  # φ
    selections: np.ndarray  # σ: the natural map, (N, p)
    bounds: np.ndarray  # β: the bounds' sides
    point: np.ndarray  # (B,) bool: the block is a point set (its φ an equation, its side ψ = −1 unused)

    def at(self, t: np.ndarray) -> "Shifts":
        """The shifts on the nodes t (the same arrays where t are this one's nodes)."""
        t = np.asarray(t, float)
        if t.shape == self.t.shape and np.array_equal(t, self.t):
            return self

        def along(values: np.ndarray) -> np.ndarray:
            flat = values.reshape(values.shape[0], -1)
            out = np.stack([np.interp(t, self.t, column) for column in flat.T], axis=1) if flat.shape[1] else \
                np.zeros((t.size, 0))
            return out.reshape((t.size,) + values.shape[1:])

        return replace(self, t=t, **{f.name: along(getattr(self, f.name)) for f in fields(self)
                                     if f.name not in ("t", "end", "point")})

    def moved(self, residuals: "Shifts") -> "Shifts":
        """The next shifts from the residuals r (ℓ) at the minimizer, on the same nodes:
        s + r for the equations, max(0, s + ℓ) for the sides of the sets that are not points
        and the bounds (an unused side's residual is 0)."""
        blocks = self.blocks + residuals.blocks
        blocks = np.where(self.point[None, :, None], blocks, np.maximum(blocks, 0.0))
        return replace(self, consistency=self.consistency + residuals.consistency, end=self.end + residuals.end,
                       surface=self.surface + residuals.surface, blocks=blocks,
                       selections=self.selections + residuals.selections,
                       bounds=np.maximum(self.bounds + residuals.bounds, 0.0))

    def scaled(self, factor: float) -> "Shifts":
        """s·factor (the multipliers y = λ·s kept where λ changes: factor = λ_old/λ_new)."""
        if factor == 1.0:
            return self
        return replace(self, **{f.name: getattr(self, f.name) * factor for f in fields(self)
                                if f.name not in ("t", "point")})

    def cleared(self) -> "Shifts":
        """Shifts of 0 in this one's shape (no multipliers: the plain penalty)."""
        return replace(self, **{f.name: np.zeros_like(getattr(self, f.name)) for f in fields(self)
                                if f.name not in ("t", "point")})


def equation_part(r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """½(r + s)² − ½s² = r·(½r + s): an equation's shifted square less its constant."""
    return r * (0.5 * r + s)


def side_part(ell: np.ndarray, s: np.ndarray) -> np.ndarray:
    """½·max(0, ℓ + s)² − ½s² (s ≥ 0): ℓ·(½ℓ + s) where ℓ + s ≥ 0, else −½s²."""
    return np.where(ell + s >= 0.0, ell * (0.5 * ell + s), -0.5 * s * s)


def shifted_sums(residuals: Shifts, shifts: Shifts, integral: Callable[[np.ndarray], float]) -> tuple[float, float, float]:
    """φ (with the bounds' β), ω and σ of the shifted objective: every residual r moved to r + s,
    every side ℓ to max(0, ℓ + s), each square less its constant ½s² (the objective keeps the
    precision of its changes: ½s² can be 1e8 times them near the optimum); `integral` is Σ_k w_k·."""
    sides = np.where(shifts.point[None, :, None], equation_part(residuals.blocks, shifts.blocks),
                     side_part(residuals.blocks, shifts.blocks))
    sides[:, shifts.point, 1] = 0.0
    phi = integral(np.sum(sides, axis=(1, 2))) + integral(np.sum(side_part(residuals.bounds, shifts.bounds), axis=1))
    omega = integral(np.sum(equation_part(residuals.surface, shifts.surface), axis=1))
    sigma = integral(np.sum(equation_part(residuals.selections, shifts.selections), axis=1))
    return phi, omega, sigma
