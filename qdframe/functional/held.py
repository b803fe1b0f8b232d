"""η: the choices in fixed sets held across the stages of each mesh interval (``inputs="held"``).

A collocation scheme with s ≥ 2 stages inside each mesh interval (Radau IIA) has one
velocity z per stage, so where a block's set F_b is not a point each stage makes its own
choice in it: x' on the interval is the polynomial through them. With inputs held, the
choice is one per interval, as direct collocation holds a control on each control stage
(nosnoc): where the motion between switches is a polynomial of the scheme's degree under a
constant choice (a mass pushed by a bounded force against Coulomb friction), the
collocation polynomial is that motion itself, and the trajectory is a true motion of the
inclusion, not an approximation of one.

Only a block whose set proper (without its sign terms) is a fixed set is held: constant
pieces, more than one in some max-group, no min-groups (a bounded input v' ∈ [−U, U] −
F·Sgn(v)). Its choice at point p is its velocity less its sign terms' Filippov points,
c_{p,b} = z_{p,b} − Σ sense·a(y_p)·λ_p, exactly what the replay certificate
(:func:`qdframe.certificates.estimates.replay`) continues between the points, so the input the result
holds is the input its certificate drives. A set that moves with the state (v' ∈ −p +
[−2, 2], x' ∈ [0.5·x, 1.5·x]) and the controls u keep each point's choice: held, such a
choice is no longer the replay's input, and on the problems measured (docs/method.md) the
refinement took more points, not fewer. With the stages (k, 1) … (k, s) of interval k,

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
from ..schemes.grid import Grid
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


def less_sign_points(layout: Layout, pieces: Pieces, z: np.ndarray, y: np.ndarray, lam: np.ndarray,
                     gradients: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """z (N, n) less every sign term's Filippov point sense·a(y)·λ in its coordinate: the choice
    each velocity makes in its set proper (what the replay continues between the points); with
    `gradients`, its derivative in (x, u, λ), (N, n, n + m + p) (in z it is the identity)."""
    choice = z.copy()
    grads = np.zeros(choice.shape + (layout.width,)) if gradients else None
    for k, (b, term) in zip(layout.sign_columns, layout.sign_terms):
        i = layout.blocks[b].coords[0]
        amplitude, groups = pieces._amplitude(layout.blocks[b], term, y)
        choice[:, i] -= term.sense * amplitude * lam[:, k]
        if gradients:
            grads[:, i, layout.args + k] -= term.sense * amplitude
            for piece in groups:  # a(y) = Σ max_q a_q: the active piece's gradient
                top = piece.grads[np.arange(y.shape[0]), np.argmax(piece.values, axis=1)]
                grads[:, i, : layout.args] -= (term.sense * lam[:, k])[:, None] * top
    return choice, grads


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
        """The blocks whose set proper (without its sign terms) is a fixed set that is not a
        point: constant pieces, more than one in some max-group, no min-groups (found once, at
        y's first point and at that point moved by one in every argument)."""
        if self._blocks is None:
            probes = np.concatenate([y[:1], y[:1] + 1.0])
            self._blocks = [b for b, block in enumerate(self.layout.blocks) if self._fixed(block, probes)]
        return self._blocks

    def _fixed(self, block, probes: np.ndarray) -> bool:
        """Whether `block`'s set proper is a fixed set of more than one point."""
        if block.min_groups or not block.max_groups:
            return False
        try:
            groups = [self.pieces.max_group(block, group, probes) for group in block.max_groups]
        except ModelOutputError:  # not finite at a probe: kept free
            return False
        constant = all(np.array_equal(f[0], f[1]) and not np.any(jac) for f, jac in groups)
        return constant and any(f.shape[1] > 1 for f, _ in groups)

    def coords(self, y: np.ndarray) -> list[int]:
        """The z coordinates of the held blocks."""
        return [c for b in self.blocks(y) for c in self.layout.blocks[b].coords]

    def choices(self, xi: np.ndarray, gradients: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """c (N, H): the held blocks' choices (z_b less the sign terms' points); with `gradients`,
        ∂c/∂(x, u, λ) (N, H, n + m + p) (∂c/∂z is the identity on the held blocks' z)."""
        layout = self.layout
        y = layout.arguments(xi)
        coords = self.coords(y)
        choice, grads = less_sign_points(layout, self.pieces, layout.split(xi)[1], y, layout.selections(xi), gradients)
        return choice[:, coords], None if grads is None else grads[:, coords]

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
            z_part[:, layout.n + np.asarray(coords, dtype=int)] = sign * r
            np.add.at(out, points, z_part)
        return out
