"""The quasidifferential [A_k, B_k] of the functional at every node (paper Section 4).

In the L² metric: the integrand's quasidifferential, formulas (4.5) (−max <f, ψ*> is
concave: a superdifferential; in a block of k ≥ 2 coordinates, where ψ* exposes a face of
several vertices, the one gradient of the λ-weighted vertices, :func:`.pieces._faces`),
(4.555) (−min g is convex: a subdifferential) and (4.6) (the surface), plus the discrete gradient of the coupled terms χ and υ divided by w_k
(formulas (4.44), (4.55)), and σ's natural map. Pieces within δ of their group's
extreme are active (Section 6). x(t_0) = x0, where given, is not an unknown: the sets
are projected onto the free unknowns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..schemes.grid import Grid
from .quasidifferential import Quasidifferential, SimplexSum
from .layout import Layout
from .pieces import Pieces
from .terms import Values


@dataclass(eq=False)
class Quasidifferentials:
    """[A_k, B_k] at ξ: one of the parts of :class:`~qdframe.functional.Functional`, from its
    `values` (the smooth residuals, and the problem's surface, cost and end conditions) and
    the model's pieces evaluated by its `pieces`."""

    layout: Layout
    grid: Grid
    pieces: Pieces
    values: Values

    def quasidifferential(self, xi: np.ndarray, delta: float) -> Quasidifferential:
        """[A_k, B_k] for every node, δ-active pieces, L² metric (paper Section 4)."""
        layout = self.layout
        x, z = layout.split(xi)
        y, lam = layout.arguments(xi), layout.selections(xi)
        smooth = self._smooth(xi, x, z)
        sub_groups: list[tuple[np.ndarray, np.ndarray]] = []
        sup_groups: list[tuple[np.ndarray, np.ndarray]] = []
        for b, block in enumerate(layout.blocks):
            side = self.pieces.state(block, y, z, layout.block_selections(b, lam))
            self._add_block(block.coords, side, delta, smooth, sub_groups, sup_groups)
        sub = _assemble(smooth, sub_groups).scaled(self.values.penalty)
        sup = _assemble(np.zeros_like(smooth), sup_groups).scaled(self.values.penalty)
        if self.values.cost is not None:
            cost_sub, cost_sup = self._cost_quasidifferential(y, delta)
            sub, sup = sub + cost_sub, sup + cost_sup
        return Quasidifferential(_project(_tie(sub, layout), layout.free), _project(_tie(sup, layout), layout.free))

    def _smooth(self, xi: np.ndarray, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """The gradient (N, dim) of the smooth terms υ, χ, ω and σ, each divided by w_k."""
        layout, grid = self.layout, self.grid
        nodes, n = x.shape
        w = grid.weights
        smooth = np.zeros((nodes, layout.dim))
        # υ (4.55): x-part r_k (and −Σ w_k r_k / w_0 on a free x_i(0)), z-part −(Cᵀ w r)_k / w_k
        r = self.values.consistency(x, z)
        smooth[:, :n] += r
        smooth[0, :n] -= ~layout.start_given * (w @ r) / w[0]
        smooth[:, n : 2 * n] -= grid.cumulative_adjoint(w[:, None] * r) / w[:, None]
        # χ (4.44): each end residual on its coordinate's z at every node (the integral's
        # weights over w_k), and on a free x_j(0)
        end = self.values.end_residual(x, z)
        if end.size:
            fixed = self.values.end  # J, then the periodic P
            coords = np.concatenate([fixed, self.values.periodic])
            np.add.at(smooth, (slice(None), n + coords), (grid.integral_weights / w)[:, None] * end)
            starts = end[: fixed.size] * ~layout.start_given[fixed]
            np.add.at(smooth[0], fixed, starts / w[0])
        # ω (4.6)
        if self.values.surface is not None:
            e, de = self.values.surface_at(x)
            smooth[:, :n] += np.einsum("ko,kon->kn", e, de)
        # σ: the natural map's residual times an element of its generalized Jacobian
        if layout.p:
            r, dr = self.values.selection_residual(xi)
            gradient = np.einsum("ki,kid->kd", r, dr)
            left, held = self.values.left_limits(layout.selections(xi))  # r_k = λ_k − λ_{k−1}: −r_k on λ_{k−1}
            if left.size:
                gradient[left - 1, layout.args :] -= np.where(held, r[left], 0.0)
            smooth += layout.embed(gradient)
        if self.values.held is not None:  # η: the held choices
            smooth += self.values.held.gradient(xi) / w[:, None]
        return smooth

    def _add_block(self, coords: tuple[int, ...], side, delta: float, smooth: np.ndarray,
                   sub_groups: list[tuple[np.ndarray, np.ndarray]], sup_groups: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """φ's part of a block at its ψ* (`side`): h ψ* on z_b into `smooth`, the δ-active pieces'
        groups into `sub_groups` and `sup_groups`."""
        embed, n = self.layout.embed, self.layout.n
        h = side.h
        positive = h > 0
        smooth[:, n + np.asarray(coords)] += h[:, None] * side.psi  # h ψ* e_z
        for part in side.min_parts:  # −min g is convex: subdifferential (4.555)
            mask = _delta_active(-part.values, delta, positive)
            sub_groups.append((embed(-h[:, None, None] * part.grads), mask))
        for index, part in enumerate(side.max_parts):  # −max <f, ψ*> is concave: superdifferential (4.5)
            mask, grads = _delta_active(part.values, delta, positive), part.grads
            if side.faces is not None:  # k ≥ 2, a face of several vertices: h is smooth there
                at, weights = side.faces
                grads, mask = grads.copy(), mask.copy()
                grads[at, 0] = np.einsum("nq,nqd->nd", weights[index], part.grads[at])
                mask[at] = False
                mask[at, 0] = True
            sup_groups.append((embed(-h[:, None, None] * grads), mask))
        for sign in side.sign_parts:  # −κ·a(y) − smooth in s: by the sign of κ
            smooth -= embed(h[:, None] * sign.amplitude[:, None] * sign.kappa_grad)
            for piece in sign.groups:
                mask = _delta_active(piece.values, delta, positive)
                scale = (h * sign.kappa)[:, None, None]
                sup_groups.append((embed(-np.maximum(scale, 0.0) * piece.grads), mask))
                sub_groups.append((embed(np.maximum(-scale, 0.0) * piece.grads), mask))

    def _cost_quasidifferential(self, x: np.ndarray, delta: float) -> tuple[SimplexSum, SimplexSum]:
        everywhere = np.ones(x.shape[0], dtype=bool)
        cost, embed, pieces = self.values.cost, self.layout.embed, self.pieces
        sub = [(embed(g), _delta_active(v, delta, everywhere))
               for v, g in (pieces.scalar_pieces(fn, x, "cost max-group") for fn in cost.max_groups)]  # type: ignore[union-attr]
        sup = [(embed(g), _delta_active(-v, delta, everywhere))
               for v, g in (pieces.scalar_pieces(fn, x, "cost min-group") for fn in cost.min_groups)]  # type: ignore[union-attr]
        zero = np.zeros((x.shape[0], self.layout.dim))
        return _assemble(zero, sub), _assemble(zero, sup)


def _tie(polytope: SimplexSum, layout: Layout) -> SimplexSum:
    """The chain rule of z_i ≡ x_j: a z_i-component moves onto x_j."""
    if not layout.resolved:
        return polytope
    center, generators = polytope.center.copy(), polytope.generators.copy()
    for i, j in layout.resolved.items():
        for array in (center, generators):
            array[..., j] += array[..., layout.n + i]
            array[..., layout.n + i] = 0.0
    return SimplexSum(center, generators, polytope.mask)


def _delta_active(values: np.ndarray, delta: float, spread: np.ndarray) -> np.ndarray:
    """Pieces within δ of the group's maximum (paper Section 6); only the best where not `spread`."""
    top = values.max(axis=1, keepdims=True)
    active = values >= top - delta
    best = np.zeros_like(active)
    best[np.arange(values.shape[0]), np.argmax(values, axis=1)] = True
    return np.where(spread[:, None], active, best)


def _assemble(center: np.ndarray, groups: list[tuple[np.ndarray, np.ndarray]]) -> SimplexSum:
    """center + Σ co{generators} from a list of (generators (N, m, d), mask (N, m))."""
    if not groups:
        return SimplexSum.point(center)
    width = max(g.shape[1] for g, _ in groups)
    nodes, dim = center.shape
    generators = np.zeros((nodes, len(groups), width, dim))
    mask = np.zeros((nodes, len(groups), width), dtype=bool)
    for index, (g, m) in enumerate(groups):
        generators[:, index, : g.shape[1]] = g
        mask[:, index, : m.shape[1]] = m
    return SimplexSum(center, generators, mask).compact()


def _project(polytope: SimplexSum, free: np.ndarray) -> SimplexSum:
    """Restrict to the free unknowns (fixed components set to 0)."""
    return SimplexSum(
        polytope.center * free, polytope.generators * free[:, None, None, :], polytope.mask
    ).compact()
