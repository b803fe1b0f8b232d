"""The layout of the unknowns ξ: one row per node, [x (n) | z (n) | u (m) | λ (p)].

u are the model's unknown controls (m = 0 without) and λ the selections of its p sign
terms a·Sgn(s) (p = 0 with ``signs="band"``). The sets' pieces are functions of y = (x, u),
their gradients (with a selection's column, of (x, u, λ)) are placed into ξ's row by
:meth:`Layout.embed`. A given x_i(t_0) = x0_i and a resolved z_i ≡ x_j are not unknowns
(:attr:`Layout.free`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import InclusionModel, SetBlock, SignTerm
from ..registry import plugin_code


@dataclass(frozen=True)
class SelectionGroup:
    """One switch's selection: `width` columns of λ from `first` (1 for a scalar Sgn(s), k for a
    vector sign's λ ∈ B ⊂ R^k), and the first sign term on it with its block."""

    first: int
    width: int
    block: int
    term: SignTerm

    @property
    def columns(self) -> slice:
        return slice(self.first, self.first + self.width)

    @property
    def names(self) -> list[str]:
        if self.width == 1:
            return [self.term.name]
        base = self.term.ball.name  # type: ignore[union-attr]
        return [f"{base}[{j}]" for j in range(self.width)]


class Layout:
    """Where each unknown sits in ξ's row, and the model's blocks and sign terms it is built from."""

    n: int  # states
    m: int  # controls
    p: int  # selection columns
    dim: int  # 2n + m + p, the width of ξ's row
    args: int  # n + m, the width of y = (x, u), the pieces' argument
    width: int  # n + m + p, the width of the sides' gradients: (x, u, λ)
    blocks: tuple[SetBlock, ...]
    sign_terms: list[tuple[int, SignTerm]]  # (block index, term), in block order ("exact" signs only)
    sign_columns: list[int]  # each sign term's λ column
    selection_groups: list[SelectionGroup]
    selection_terms: list[tuple[int, SignTerm]]  # per λ column: the (block, term) of its switch
    selection_names: list[str]  # per λ column (a vector sign's: name[0], name[1], …)
    selection_written: list[float]  # per λ column: the λ of the Sgn(s) its name writes over the column's, ±1
    balls: list[tuple[int, int]]  # (first column, width) of every vector sign's λ ∈ B
    start_given: np.ndarray  # (n,) x_i(0) = x0_i given; NaN in x0: free
    resolved: dict[int, int]  # z_i ≡ x_j: z_i is not an unknown
    free: np.ndarray  # (N, dim): the unknowns

    def __init__(self, model: InclusionModel, signs: str, nodes: int) -> None:
        self.n = model.n_states
        self.m = model.n_controls
        with plugin_code(model, "blocks()"):
            self.blocks = tuple(model.blocks())
        # terms with the same `switch` callable share one λ (one surface, one Filippov selection);
        # a vector sign's BallSwitch has one selection vector λ ∈ B, k consecutive columns, and
        # each of its terms the column of its component
        self.sign_terms = [] if signs == "band" else [
            (b, term) for b, block in enumerate(self.blocks) for term in block.signs
        ]
        first: dict[int, int] = {}
        self.selection_groups = []
        self.sign_columns = []
        for b, term in self.sign_terms:
            if id(term.switch) not in first:
                width = term.ball.dim if term.ball is not None else 1
                first[id(term.switch)] = sum(group.width for group in self.selection_groups)
                self.selection_groups.append(SelectionGroup(first[id(term.switch)], width, b, term))
            self.sign_columns.append(first[id(term.switch)] + (term.component or 0))
        self.selection_terms = [(group.block, group.term) for group in self.selection_groups for _ in range(group.width)]
        self.selection_names = [name for group in self.selection_groups for name in group.names]
        self.selection_written = [group.term.written for group in self.selection_groups for _ in range(group.width)]
        self.balls = [(group.first, group.width) for group in self.selection_groups if group.width > 1]
        self.p = len(self.selection_terms)
        self.dim = 2 * self.n + self.m + self.p
        self.args = self.n + self.m
        self.width = self.args + self.p
        self.start_given = np.isfinite(model.x0)
        self.free = np.ones((nodes, self.dim), dtype=bool)
        self.free[0, : self.n] = ~self.start_given  # a given x_i(t_0) = x0_i is not an unknown
        self.resolved = dict(model.resolved)
        for i in self.resolved:
            self.free[:, self.n + i] = False

    def split(self, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, z), each (N, n); a resolved state's z_i is x_j."""
        x, z = xi[:, : self.n], xi[:, self.n : 2 * self.n]
        if self.resolved:
            z = z.copy()
            for i, j in self.resolved.items():
                z[:, i] = x[:, j]
        return x, z

    def controls(self, xi: np.ndarray) -> np.ndarray:
        """u, shape (N, m)."""
        return xi[:, 2 * self.n : 2 * self.n + self.m]

    def selections(self, xi: np.ndarray) -> np.ndarray:
        """λ, shape (N, p): the selection of each sign term's Sgn(s) at every node."""
        return xi[:, 2 * self.n + self.m :]

    def arguments(self, xi: np.ndarray) -> np.ndarray:
        """y = (x, u), the pieces' argument, shape (N, n + m)."""
        return xi[:, : self.n] if self.m == 0 else np.concatenate([xi[:, : self.n], self.controls(xi)], axis=1)

    def block_selections(self, b: int, lam: np.ndarray) -> list[tuple[int, np.ndarray, float] | None]:
        """For each sign term of block b: (its selection's column in y = (x, u, λ), sense·λ,
        its sense), or None (band). Terms on one switch share the column (model.SignTerm)."""
        if not self.p:
            return [None] * len(self.blocks[b].signs)
        return [(self.args + k, term.sense * lam[:, k], term.sense)
                for k, (block, term) in zip(self.sign_columns, self.sign_terms) if block == b]

    def embed(self, grads: np.ndarray) -> np.ndarray:
        """Gradients in y = (x, u) or (x, u, λ) placed in the x-, u- (and λ-) slots of ξ's row."""
        out = np.zeros(grads.shape[:-1] + (self.dim,))
        out[..., : self.n] = grads[..., : self.n]
        out[..., 2 * self.n : self.n + grads.shape[-1]] = grads[..., self.n :]
        return out
