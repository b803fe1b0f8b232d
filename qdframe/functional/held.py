"""η: the sets' choices held across the stages of each mesh interval (``inputs="held"``).

A collocation scheme with s ≥ 2 stages inside each mesh interval (Radau IIA) has one
velocity z per stage, so where a block's set F_b is not a point, and for the controls u,
each stage makes its own choice: x' on the interval is the polynomial through them. With
inputs held, the choice is one per interval, as direct collocation holds a control on
each control stage (nosnoc): where the motion between switches is a polynomial of the
scheme's degree under a constant choice (a mass pushed by a constant force against
Coulomb friction), the collocation polynomial is that motion itself, and the trajectory
is a true motion of the inclusion, not an approximation of one.

The choice is held where the block's set proper is a fixed set U moved by the state,
f(y) + U (a bounded input: v' ∈ −k·p + [−U, U] − F·Sgn(v)), and for the controls; a set
whose shape changes with the state (x' ∈ [0.5·x, 1.5·x]) keeps each point's choice, since a
choice held across a bound that moves would leave the set between the points. The choice
of a set block b at point p is its place in U: its velocity less f_b(y_p) (each max-group's
first piece) and its sign terms' Filippov points, c_{p,b} = z_{p,b} − f_b(y_p) −
Σ sense·a(y_p)·λ_p, and of the controls, u_p. With the stages (k, 1) … (k, s) of interval k,

    η = ½ Σ_k Σ_{i<s} w_{k,i} ‖c_{k,i} − c_{k,s}‖²,

a term of I like υ: I = 0 exactly when the trajectory is a discrete solution whose choices
are held. Schemes with one point per interval (implicit Euler) hold every choice already;
a rule whose velocity on an interval reads its first mesh point (the trapezoid rule) ties
neighbouring intervals, so there is nothing to hold within one, and η ≡ 0 for both.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelOutputError
from ..grid import Grid
from .layout import Layout
from .pieces import Pieces


def held_pairs(grid: Grid) -> np.ndarray:
    """(P, 2) point indices (stage i, last stage) of every mesh interval and stage i < s;
    none where the scheme has one stage or its velocity reads the interval's first point."""
    scheme = grid.scheme
    if scheme.stages < 2 or 0 in scheme.velocity_points:
        return np.zeros((0, 2), dtype=int)
    start = grid.mesh[:-1, None]
    stages = np.arange(1, scheme.stages)[None, :]
    return np.stack([(start + stages).ravel(), np.repeat(grid.mesh[1:], scheme.stages - 1)], axis=1)


@dataclass(eq=False)
class HeldChoices:
    """η's choices, residuals and Jacobian elements: one of the parts of
    :class:`~qdframe.functional.Functional` (only with ``inputs="held"`` and exact signs)."""

    layout: Layout
    grid: Grid
    pieces: Pieces
    pairs: np.ndarray = field(init=False)
    _blocks: list[int] | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        self.pairs = held_pairs(self.grid)

    def blocks(self, y: np.ndarray) -> list[int]:
        """The blocks whose set proper (without its sign terms) is a fixed set U moved by the
        state, f(y) + U, and not a point: no min-groups, more than one piece in some max-group,
        and in each max-group pieces that differ by constants (found once, at y's first point
        and at that point moved by one in every argument)."""
        if self._blocks is None:
            probes = np.concatenate([y[:1], y[:1] + 1.0])
            self._blocks = [b for b, block in enumerate(self.layout.blocks) if self._translated(block, probes)]
        return self._blocks

    def _translated(self, block, probes: np.ndarray) -> bool:
        """Whether `block`'s set proper is f(y) + U, U fixed and not a point."""
        if block.min_groups or not block.max_groups:
            return False
        try:
            groups = [self.pieces.max_group(block, group, probes) for group in block.max_groups]
        except ModelOutputError:  # not finite at a probe: kept free
            return False
        fixed = all(np.allclose(f[0] - f[0, :1], f[1] - f[1, :1], rtol=0.0, atol=1e-12 * (1.0 + np.abs(f).max()))
                    and np.array_equal(jac - jac[:, :1], np.zeros_like(jac)) for f, jac in groups)
        return fixed and any(f.shape[1] > 1 for f, _ in groups)

    def _anchors(self, y: np.ndarray, gradients: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """f(y) of the held blocks (each max-group's first piece, summed), (N, H'), and with
        `gradients` its Jacobian in y = (x, u), (N, H', n + m)."""
        coords = self.coords(y)
        f = np.zeros((y.shape[0], len(coords)))
        jac = np.zeros((y.shape[0], len(coords), self.layout.args)) if gradients else None
        start = 0
        for b in self.blocks(y):
            block = self.layout.blocks[b]
            columns = slice(start, start + block.size)
            for group in block.max_groups:
                values, grads = self.pieces.max_group(block, group, y)
                f[:, columns] += values[:, 0]
                if gradients:
                    jac[:, columns] += grads[:, 0]
            start += block.size
        return f, jac

    def coords(self, y: np.ndarray) -> list[int]:
        """The z coordinates of the held blocks."""
        return [c for b in self.blocks(y) for c in self.layout.blocks[b].coords]

    def choices(self, xi: np.ndarray, gradients: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """c (N, H): the held blocks' choices in their fixed sets U (z_b less f_b(y) and the sign
        terms' points), then the controls; with `gradients`, ∂c/∂(x, u, λ) (N, H, n + m + p)
        (∂c/∂z is the identity on the held blocks' z, and 0 on the controls)."""
        layout = self.layout
        y, lam = layout.arguments(xi), layout.selections(xi)
        z = layout.split(xi)[1]
        coords = self.coords(y)
        anchor, anchor_grads = self._anchors(y, gradients)
        choice = np.concatenate([z[:, coords] - anchor, layout.controls(xi)], axis=1)
        grads = np.zeros(choice.shape + (layout.width,)) if gradients else None
        if gradients:
            grads[:, : len(coords), : layout.args] = -anchor_grads
            grads[:, len(coords):, layout.n: layout.args] = np.eye(layout.m)[None]  # ∂u/∂u
        place = {c: i for i, c in enumerate(coords)}
        for k, (b, term) in zip(layout.sign_columns, layout.sign_terms):
            i = place.get(layout.blocks[b].coords[0])
            if i is None:
                continue
            amplitude, groups = self.pieces._amplitude(layout.blocks[b], term, y)
            choice[:, i] -= term.sense * amplitude * lam[:, k]
            if gradients:
                grads[:, i, layout.args + k] -= term.sense * amplitude
                for piece in groups:  # a(y) = Σ max_q a_q: the active piece's gradient
                    top = piece.grads[np.arange(y.shape[0]), np.argmax(piece.values, axis=1)]
                    grads[:, i, : layout.args] -= (term.sense * lam[:, k])[:, None] * top
        return choice, grads

    def residual(self, xi: np.ndarray) -> np.ndarray:
        """c_{k,i} − c_{k,s} for every pair (P, H)."""
        choice = self.choices(xi)[0]
        return choice[self.pairs[:, 0]] - choice[self.pairs[:, 1]]

    def eta(self, xi: np.ndarray) -> float:
        """η = ½ Σ w_{k,i} ‖c_{k,i} − c_{k,s}‖²."""
        if not self.pairs.size:
            return 0.0
        r = self.residual(xi)
        return 0.5 * float(np.sum(self.grid.weights[self.pairs[:, 0]] * np.sum(r**2, axis=1)))

    def gradient(self, xi: np.ndarray) -> np.ndarray:
        """∂η/∂ξ (N, dim)."""
        layout = self.layout
        out = np.zeros((xi.shape[0], layout.dim))
        if not self.pairs.size:
            return out
        choice, grads = self.choices(xi, gradients=True)
        coords = self.coords(layout.arguments(xi))
        first, last = self.pairs[:, 0], self.pairs[:, 1]
        r = self.grid.weights[first][:, None] * (choice[first] - choice[last])  # (P, H)
        for points, sign in ((first, 1.0), (last, -1.0)):
            np.add.at(out, points, sign * layout.embed(np.einsum("ph,phd->pd", r, grads[points])))
            z_part = np.zeros((points.size, layout.dim))
            z_part[:, layout.n + np.asarray(coords, dtype=int)] = sign * r[:, : len(coords)]
            np.add.at(out, points, z_part)
        return out
