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

The functional is composed of parts, each in its own module with its state declared, that
call each other only through public methods (:class:`Functional` builds them and keeps
its outside surface: it delegates to them):

* :mod:`.layout` — where each unknown sits in ξ's row (:class:`~.layout.Layout`,
  Functional's base);
* :mod:`.pieces` — the model's pieces at ψ, ℓ(ψ) = <z_b, ψ> − c(F_b, ψ) and ψ*, checked
  (:class:`~.pieces.Pieces`, which keeps the ψ* memo);
* :mod:`.terms` — the terms' values (paper (3.13)–(3.17)), the objective, the ray a line
  search minimizes, the pointwise residuals (:class:`~.terms.Values`);
* :mod:`.assembly` — the quasidifferential [A_k, B_k] (paper Section 4) for the paper's
  direction (:class:`~.assembly.Quasidifferentials`);
* :mod:`.jacobians` — residuals with generalized-Jacobian elements for gauss-newton
  (:class:`~.jacobians.Jacobians`).

What depends on the scheme (the points, quadrature weights w_k, the cumulative integral
Z = ∫_0^t z and its adjoint) comes from the grid, built from the scheme's own rule
(:class:`~qdframe.schemes.grid.Grid`, :mod:`qdframe.schemes`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np

from ..errors import InputError, ModelOutputError
from ..schemes.grid import Grid
from ..model import Cost, InclusionModel, SetBlock, Surface
from .quasidifferential import Quasidifferential
from ..registry import plugin_code
from .assembly import Quasidifferentials
from .held import HeldChoices
from .jacobians import DistanceSides, Jacobians
from .layout import Layout, SelectionGroup
from .pieces import Pieces
from .shifts import Shifts
from .terms import Bounds, Residuals, Terms, Values

__all__ = ["INPUT_MODES", "SIGN_MODES", "DistanceSides", "Functional", "Residuals", "SelectionGroup", "Terms"]

SIGN_MODES = ("exact", "band")
INPUT_MODES = ("free", "held")


class Functional(Layout):
    """The discretized objective of a model on a grid: the layout of ξ (its base,
    :class:`~.layout.Layout`) and four parts it owns, each job in its own module: `pieces`
    (the model's pieces at ψ, :mod:`.pieces`), `values` (values, the ray and residuals:
    :mod:`.terms`), `assembly` (the quasidifferential: :mod:`.assembly`) and `jacobians`
    (residuals with Jacobian elements: :mod:`.jacobians`). Its methods delegate to them."""

    model: InclusionModel
    grid: Grid
    signs: str  # "exact" or "band"
    pieces: Pieces
    values: Values
    assembly: Quasidifferentials
    jacobians: Jacobians

    def __init__(
        self,
        model: InclusionModel,
        grid: Grid,
        psi_samples: int = 128,
        signs: str = "exact",
        selection_scale: float = 1.0,
        inputs: str = "free",
    ) -> None:
        """`signs`: "exact" (a selection λ ∈ Sgn(s) per sign term and node, tied by σ) or
        "band" (the C¹ band of :class:`~qdframe.model.SignTerm`, no selections);
        `selection_scale` is c in σ's natural map; `inputs`: "free" (each point's own choice
        in the sets) or "held" (one per mesh interval in each fixed set: η, :mod:`.held`)."""
        if signs not in SIGN_MODES:
            raise InputError("signs", " or ".join(f'"{mode}"' for mode in SIGN_MODES), signs)
        if inputs not in INPUT_MODES:
            raise InputError("inputs", " or ".join(f'"{mode}"' for mode in INPUT_MODES), inputs)
        if not (isinstance(selection_scale, (int, float)) and np.isfinite(selection_scale) and selection_scale > 0):
            raise InputError("selection_scale", "a positive finite number", selection_scale)
        super().__init__(model, signs, grid.nodes)
        self.model = model
        self.grid = grid
        self.signs = signs
        with plugin_code(model, "surface()"):
            surface = model.surface()
        with plugin_code(model, "cost()"):
            cost = model.cost()
        self.pieces = Pieces(model, grid, self.n, self.args, self.width, psi_samples)
        self.inputs = inputs
        # (a model with unknown T or parameters is held through the model solve() wraps it in)
        held = HeldChoices(self, grid, self.pieces) if inputs == "held" and signs == "exact" \
            and not model.has_unknowns else None
        if held is not None:
            probe = np.concatenate([np.nan_to_num(model.x0), np.zeros(self.m)])[None, :]
            held = held if held.pairs.size and held.coords(probe) else None
        self.held = held
        self.values = Values(
            layout=self, grid=grid, pieces=self.pieces, surface=surface, cost=cost,
            penalty=float(cost.weight) if cost is not None else 1.0,
            end=np.asarray(model.end_indices, dtype=int), periodic=np.asarray(model.periodic, dtype=int),
            end_values=model.end_values, selection_scale=float(selection_scale), held=self.held,
            bounds=_bounds(model))
        self.assembly = Quasidifferentials(layout=self, grid=grid, pieces=self.pieces, values=self.values)
        self.jacobians = Jacobians(layout=self, pieces=self.pieces, cost=cost)

    @property
    def weights(self) -> np.ndarray:
        return self.grid.weights

    @property
    def shifts(self) -> Shifts | None:
        """The augmented Lagrangian's shifts on this grid (:mod:`.shifts`), or None."""
        return self.values.shifts

    @property
    def bounds(self) -> Bounds | None:
        """The finite sides of the model's state and control bounds (:class:`~.terms.Bounds`), or None."""
        return self.values.bounds

    def set_multipliers(self, shifts: Shifts | None, weight: float) -> None:
        """The augmented Lagrangian's shifts (on this grid's nodes) and penalty λ from here on
        (:mod:`qdframe.descent.multipliers`)."""
        self.values.shifts = shifts
        self.values.penalty = float(weight)

    @contextmanager
    def without_cost(self) -> Iterator[None]:
        """The functional as if the model had no cost (I alone, λ = 1) inside the block: a
        feasibility solve before the cost's optimum (:mod:`qdframe.descent.multipliers`)."""
        cost, penalty, shifts = self.values.cost, self.values.penalty, self.values.shifts
        self.values.cost, self.jacobians.cost, self.values.penalty, self.values.shifts = None, None, 1.0, None
        try:
            yield
        finally:
            self.values.cost, self.jacobians.cost, self.values.penalty, self.values.shifts = cost, cost, penalty, shifts

    def take_multipliers(self, other: "Functional") -> None:
        """Another functional's λ and shifts (interpolated to this grid), where it has a cost
        and moved them: a finer grid starts from a coarser one's multipliers."""
        if self.cost is not None and other.cost is not None and (other.shifts is not None
                                                                 or other.penalty != self.penalty):
            same = other.shifts is not None and other.signs == self.signs  # (a band start's sets are not ours)
            self.set_multipliers(other.shifts.at(self.grid.t) if same else None, other.penalty)

    def constraint_residuals(self, xi: np.ndarray) -> Shifts:
        """Every residual behind I, unshifted (:meth:`.terms.Values.constraint_residuals`)."""
        x, z = self.split(xi)
        return self.values.constraint_residuals(x, self.arguments(xi), z, self.selections(xi))

    # the problem's data, kept by the parts that use them
    @property
    def surface(self) -> Surface | None:
        return self.values.surface

    @property
    def cost(self) -> Cost | None:
        return self.values.cost

    @property
    def penalty(self) -> float:
        """λ of the objective ∫cost + λ·I (1 without a cost)."""
        return self.values.penalty

    @property
    def end(self) -> np.ndarray:
        """J: x_j(T) = xT_j."""
        return self.values.end

    @property
    def periodic(self) -> np.ndarray:
        """P: x_i(T) = x_i(0)."""
        return self.values.periodic

    @property
    def selection_scale(self) -> float:
        """c of σ's natural map."""
        return self.values.selection_scale

    @property
    def psi_samples(self) -> int:
        return self.pieces.psi_samples

    # the parts' jobs, as Functional's methods
    def terms(self, xi: np.ndarray) -> Terms:
        """φ, χ, ω, υ, σ, the cost, I and the objective at ξ."""
        return self.values.terms(xi)

    def objective(self, xi: np.ndarray) -> float:
        return self.terms(xi).objective

    def ray(self, xi: np.ndarray, direction: np.ndarray) -> Callable[[float], float]:
        """γ ↦ the objective at ξ + γG, what a line search minimizes (:meth:`.terms.Values.ray`)."""
        return self.values.ray(xi, direction)

    def residuals(self, xi: np.ndarray) -> Residuals:
        return self.values.residuals(xi)

    def boundary_error(self, xi: np.ndarray) -> float:
        """max |x_j(T) − xT_j| over J and |x_i(T) − x_i(0)| over the periodic P, read from x."""
        return self.values.boundary_error(xi)

    def consistency(self, xi: np.ndarray) -> np.ndarray:
        """x − x0 − ∫_0^t z at every node, (N, n)."""
        return self.values.consistency(*self.split(xi))

    def end_residual(self, xi: np.ndarray) -> np.ndarray:
        """x_j(0) + ∫_0^T z_j − xT_j for j ∈ J, then ∫_0^T z_i (= x_i(T) − x_i(0)) for i ∈ P."""
        return self.values.end_residual(*self.split(xi))

    def surface_values(self, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """e(x) (N, o) and ∂e/∂x (N, o, n); requires a surface."""
        return self.values.surface_at(self.split(xi)[0])

    def selection_residual(self, xi: np.ndarray, scale: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """σ's natural map r = λ − P(λ + c·s(y)) (N, p) and a Jacobian element (:meth:`.terms.Values.selection_residual`)."""
        return self.values.selection_residual(xi, scale)

    def left_limits(self, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The left-limit selections (:meth:`.terms.Values.left_limits`)."""
        return self.values.left_limits(lam)

    def project(self, values: np.ndarray) -> np.ndarray:
        """P of every selection's columns (N, p): the clip to [−1, 1], a vector sign's onto B."""
        return self.values.project(values)

    def switch_values(self, y: np.ndarray, gradients: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """s (N, p) of every selection column and, with `gradients`, ∇s (N, p, n + m), checked."""
        return self.values.switch_values(y, gradients)

    def set_bounds(self, xi: np.ndarray) -> list[tuple[np.ndarray, np.ndarray] | None]:
        """For each one-coordinate block the interval [lo, hi] of F_b(x(t_k)); None for S_k blocks."""
        return self.values.set_bounds(xi)

    def quasidifferential(self, xi: np.ndarray, delta: float) -> Quasidifferential:
        """[A_k, B_k] for every node, δ-active pieces, L² metric (paper Section 4)."""
        return self.assembly.quasidifferential(xi, delta)

    def distance_sides(self, xi: np.ndarray) -> list[DistanceSides]:
        """Every block's sides: ℓ and a generalized-Jacobian element each (:meth:`.jacobians.Jacobians.distance_sides`)."""
        return self.jacobians.distance_sides(xi)

    def cost_pieces(self, xi: np.ndarray) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]:
        """The cost's max-groups and min-groups: lists of (values (N, m), gradients (N, m, n + m))."""
        return self.jacobians.cost_pieces(xi)

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


def _bounds(model: InclusionModel) -> Bounds | None:
    """The model's `state_bounds` and `control_bounds` (its checked `bounds_table`) as the
    finite sides of y = (x, u), or None without bounds."""
    table = getattr(model, "bounds_table", None) or {}
    names = [*model.state_names, *model.control_names]
    columns, sense, limit, labels = [], [], [], []
    for name, (lo, hi) in table.items():
        column = names.index(name)
        for side, value, label in ((1.0, hi, f"{name} ≤ {hi:g}"), (-1.0, lo, f"{name} ≥ {lo:g}")):
            if np.isfinite(value):
                columns.append(column)
                sense.append(side)
                limit.append(value)
                labels.append(label)
    if not columns:
        return None
    return Bounds(np.asarray(columns, dtype=int), np.asarray(sense), np.asarray(limit), tuple(labels))
