"""Residuals with one element of their generalized Jacobians, for Newton-type directions.

gauss-newton (:mod:`qdframe.directions.gauss_newton`) writes I as half a sum of squares:
the consistency υ and end χ residuals (:class:`~qdframe.functional.terms.Values`), the
surface's e(x), σ's natural map and, per block, the distance h_b = max(0, max_side ℓ)
with each side's ℓ and gradient (:class:`DistanceSides`), and the cost's pieces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import Cost
from .layout import Layout
from .pieces import Pieces


@dataclass(frozen=True)
class DistanceSides:
    """A block's sides: tuples (ℓ (N,), ∂ℓ/∂y (N, n + m + p), ∂ℓ/∂z_b = ψ (N, k)); h_b = max(0, max ℓ).

    `equation`: F_b(y) is a single point (one-piece max-groups, sign terms with
    selections): then the ψ = +1 side alone is the signed residual z_b − f_b(y), h = |ℓ|.
    """

    coords: tuple[int, ...]
    sides: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
    equation: bool = False

    @property
    def h(self) -> np.ndarray:
        return np.maximum(0.0, np.max([ell for ell, _, _ in self.sides], axis=0))


@dataclass(eq=False)
class Jacobians:
    """Residuals and Jacobian elements at ξ: one of the parts of
    :class:`~qdframe.functional.Functional`, the model's pieces evaluated by its `pieces`."""

    layout: Layout
    pieces: Pieces
    cost: Cost | None

    def distance_sides(self, xi: np.ndarray) -> list[DistanceSides]:
        """For every block, h_b = max(0, max_side ℓ_side) with each side's signed ℓ and
        one element of its generalized Jacobian (:meth:`_Side.gradient`). One-coordinate
        blocks have two sides, ψ = +1 and ψ = −1 (the interval's ends); S_k blocks have
        one, ψ = ψ*."""
        layout, pieces = self.layout, self.pieces
        y, z, lam = layout.arguments(xi), layout.split(xi)[1], layout.selections(xi)
        out = []
        for b, block in enumerate(layout.blocks):
            if block.size != 1:
                out.append(DistanceSides(block.coords, [self._side_terms(pieces.state_sphere(block, y, z))]))
                continue
            maxes = [pieces.max_group(block, group, y) for group in block.max_groups]
            point = (not block.min_groups and (layout.p or not block.signs)
                     and all(f.shape[1] == 1 for f, _ in maxes))
            selections = layout.block_selections(b, lam)
            ones = np.ones((y.shape[0], 1))
            sides = [self._side_terms(pieces.side(block, y, z, psi, maxes, selections))
                     for psi in ((ones,) if point else (ones, -ones))]  # a point: the ψ = +1 side alone
            out.append(DistanceSides(block.coords, sides, point))
        return out

    def _side_terms(self, side) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ℓ, ∂ℓ/∂y, ψ) of a side, the side's pieces let go."""
        return side.ell, side.gradient(self.layout.width), side.psi

    def cost_pieces(self, xi: np.ndarray) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]:
        """The cost's max-groups and min-groups: lists of (values (N, m), gradients (N, m, n + m))."""
        y = self.layout.arguments(xi)
        return (
            [self.pieces.scalar_pieces(fn, y, "cost max-group") for fn in self.cost.max_groups],  # type: ignore[union-attr]
            [self.pieces.scalar_pieces(fn, y, "cost min-group") for fn in self.cost.min_groups],  # type: ignore[union-attr]
        )
