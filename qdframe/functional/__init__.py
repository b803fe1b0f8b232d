"""The discretized functional I = φ + χ + ω + υ + σ (+ cost) and its quasidifferential.

Unknowns ξ are stored per node as one row [x (n) | z (n) | u (m) | λ (p)], ξ of shape
(N, 2n + m + p), u the model's unknown controls (m = 0 without) and λ the selections of
its p sign terms a·Sgn(s) (p = 0 with ``signs="band"``). The sets' pieces are functions
of y = (x, u). The value x(t_0) = x0 is known, so it is not an unknown: it is fixed at
node 0 and the quasidifferential is projected onto the remaining free unknowns.

σ is the natural map of the complementarity λ ∈ Sgn(s) (as in contact mechanics, Alart
and Curnier): it is zero exactly when λ = sign s for s ≠ 0 and λ ∈ [−1, 1] for s = 0, so
with σ = 0 the sign term a·Sgn(s) contributes the point a·λ of Filippov's set, and
sticking and sliding come out of the equations, not out of a smoothing band. A vector
sign Sgn(s), s ∈ R^k (:class:`~qdframe.model.BallSwitch`, isotropic friction), has one
selection vector λ ∈ B (the closed unit ball) per node, k columns, tied by the natural map
of the second-order-cone complementarity, λ − P_B(λ + c·s) = 0: λ = s/|s| where s ≠ 0.

One job per module, each mixed into :class:`Functional`:

* :mod:`.terms` — the terms' values (paper (3.13)–(3.17)), the objective, the ray a line
  search minimizes, the pointwise residuals;
* :mod:`.assembly` — the quasidifferential [A_k, B_k] (paper Section 4) for the paper's
  direction;
* :mod:`.jacobians` — residuals with generalized-Jacobian elements for gauss-newton;
* :mod:`.pieces` — the model's pieces at ψ, ℓ(ψ) = <z_b, ψ> − c(F_b, ψ) and ψ*.

What depends on the scheme (the points, quadrature weights w_k, the cumulative integral
Z = ∫_0^t z and its adjoint) comes from the grid, built from the scheme's own rule
(:class:`~qdframe.grid.Grid`, :mod:`qdframe.schemes`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, ModelOutputError
from ..grid import Grid
from ..model import InclusionModel, SetBlock, SignTerm
from ..registry import plugin_code
from .assembly import Quasidifferentials
from .jacobians import DistanceSides, Jacobians
from .pieces import Pieces
from .terms import Residuals, Terms, Values

__all__ = ["SIGN_MODES", "DistanceSides", "Functional", "Residuals", "SelectionGroup", "Terms"]

SIGN_MODES = ("exact", "band")


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


class Functional(Values, Quasidifferentials, Jacobians, Pieces):
    """The discretized objective of a model on a grid: the layout of ξ here, each job in its
    own module (values and the ray: :mod:`.terms`; the quasidifferential: :mod:`.assembly`;
    residuals with Jacobian elements: :mod:`.jacobians`; the model's pieces at ψ: :mod:`.pieces`)."""

    def __init__(
        self,
        model: InclusionModel,
        grid: Grid,
        psi_samples: int = 128,
        signs: str = "exact",
        selection_scale: float = 1.0,
    ) -> None:
        """`signs`: "exact" (a selection λ ∈ Sgn(s) per sign term and node, tied by σ) or
        "band" (the C¹ band of :class:`~qdframe.model.SignTerm`, no selections);
        `selection_scale` is c in σ's natural map."""
        if signs not in SIGN_MODES:
            raise InputError("signs", " or ".join(f'"{mode}"' for mode in SIGN_MODES), signs)
        if not (isinstance(selection_scale, (int, float)) and np.isfinite(selection_scale) and selection_scale > 0):
            raise InputError("selection_scale", "a positive finite number", selection_scale)
        self.model = model
        self.grid = grid
        self.signs = signs
        self.selection_scale = float(selection_scale)
        self.n = model.n_states
        self.m = model.n_controls
        with plugin_code(model, "blocks()"):
            self.blocks: tuple[SetBlock, ...] = tuple(model.blocks())
        # the sign terms in block order, (block index, term), and each one's selection column:
        # terms with the same `switch` callable share one λ (one surface, one Filippov selection);
        # a vector sign's BallSwitch has one selection vector λ ∈ B, k consecutive columns, and
        # each of its terms the column of its component
        self.sign_terms = [] if signs == "band" else [
            (b, term) for b, block in enumerate(self.blocks) for term in block.signs
        ]
        first: dict[int, int] = {}
        self.selection_groups: list[SelectionGroup] = []
        self.sign_columns = []
        for b, term in self.sign_terms:
            if id(term.switch) not in first:
                width = term.ball.dim if term.ball is not None else 1
                first[id(term.switch)] = sum(group.width for group in self.selection_groups)
                self.selection_groups.append(SelectionGroup(first[id(term.switch)], width, b, term))
            self.sign_columns.append(first[id(term.switch)] + (term.component or 0))
        # per column: the (block, term) of its switch (a vector sign's first term, for each of its
        # columns) and its name (a vector sign's columns: name[0], name[1], …)
        self.selection_terms = [(group.block, group.term) for group in self.selection_groups for _ in range(group.width)]
        self.selection_names = [name for group in self.selection_groups for name in group.names]
        self.balls = [(group.first, group.width) for group in self.selection_groups if group.width > 1]
        self.p = len(self.selection_terms)
        self.dim = 2 * self.n + self.m + self.p
        self.args = self.n + self.m  # width of y = (x, u), the pieces' argument
        self.width = self.args + self.p  # width of the sides' gradients: (x, u, λ)
        with plugin_code(model, "surface()"):
            self.surface = model.surface()
        with plugin_code(model, "cost()"):
            self.cost = model.cost()
        self.penalty = float(self.cost.weight) if self.cost is not None else 1.0
        self.end = np.asarray(model.end_indices, dtype=int)  # J: x_j(T) = xT_j
        self.periodic = np.asarray(model.periodic, dtype=int)  # P: x_i(T) = x_i(0)
        self.start_given = np.isfinite(model.x0)  # x_i(0) = x0_i given; NaN: free
        self.psi_samples = psi_samples
        self._psi_memo: dict[int, list[tuple[bytes, np.ndarray]]] = {}  # per S_k block: recent (inputs, ψ*)
        self._values_checked: set[int] = set()  # min-groups whose `values` agreed with their pieces once
        self.free = np.ones((grid.nodes, self.dim), dtype=bool)
        self.free[0, : self.n] = ~self.start_given  # a given x_i(t_0) = x0_i is not an unknown
        self.resolved = dict(model.resolved)  # z_i ≡ x_j: z_i is not an unknown
        for i in self.resolved:
            self.free[:, self.n + i] = False

    @property
    def weights(self) -> np.ndarray:
        return self.grid.weights

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

    def pack(self, x: np.ndarray, z: np.ndarray, u: np.ndarray | None = None,
             selections: np.ndarray | None = None) -> np.ndarray:
        """ξ from its parts; selections default to the band's, clip(s(y)/β, −1, 1) per term."""
        nodes = x.shape[0]
        parts = [x, z, np.zeros((nodes, self.m)) if u is None else u, np.zeros((nodes, self.p))]
        xi = np.concatenate(parts, axis=1).astype(float)
        xi[0, : self.n] = np.where(self.start_given, self.model.x0, xi[0, : self.n])
        for i, j in self.resolved.items():
            xi[:, self.n + i] = xi[:, j]
        if self.p:
            if selections is None:  # the band's: P(s/β), the clip to [−1, 1] or the projection onto B
                s = self.switch_values(self.arguments(xi))[0]
                bands = np.array([group.term.band for group in self.selection_groups for _ in range(group.width)])
                with np.errstate(divide="ignore", invalid="ignore"):
                    selections = np.nan_to_num(self.project(s / bands))
            xi[:, 2 * self.n + self.m :] = selections
        return xi

    def initial_point(self) -> np.ndarray:
        t = self.grid.t
        with plugin_code(self.model, "initial_guess()"):
            x, z = self.model.initial_guess(t)
        with plugin_code(self.model, "initial_controls()"):
            u = self.model.initial_controls(t)
        for label, array, width in (("x", x, self.n), ("z", z, self.n), ("u", u, self.m)):
            if np.shape(array) != (t.size, width):
                raise ModelOutputError(
                    f"model {self.model.name!r}: initial {label} has shape {np.shape(array)}, expected {(t.size, width)}"
                )
            finite = np.isfinite(np.asarray(array, dtype=float))
            if not finite.all():
                node, column = (int(i) for i in np.argwhere(~finite)[0])
                method = "initial_controls()" if label == "u" else "initial_guess()"
                names = self.model.control_names if label == "u" else self.model.state_names
                raise ModelOutputError(
                    f"model {self.model.name!r}: {method} returned a non-finite {label} "
                    f"({names[column]}{'′' if label == 'z' else ''} = {np.asarray(array, float)[node, column]}) at node "
                    f"{node} (t = {t[node]:.6g}); a starting guess must be finite everywhere (a free x_i(0) too)",
                    label=f"initial {label}", node=node, nonfinite=True)
        return self.pack(np.asarray(x, float), np.asarray(z, float), np.asarray(u, float))
