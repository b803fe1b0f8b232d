"""The discretized functional I = φ + χ + ω + υ (+ cost) and its quasidifferential.

Unknowns ξ are stored per node as one row [x (n) | z (n) | u (m) | λ (p)], ξ of shape
(N, 2n + m + p), u the model's unknown controls (m = 0 without) and λ the selections of
its p sign terms a·Sgn(s) (p = 0 with ``signs="band"``). The sets' pieces are functions
of y = (x, u). The value x(t_0) = x0 is known, so it is not an unknown: it is fixed at
node 0 and the quasidifferential is projected onto the remaining free unknowns.

Terms (paper (3.13), (3.14), (3.14'), (3.17)), with the scheme's weights w_k and
cumulative integral Z = ∫_0^t z (:class:`~qdframe.grid.Grid`):

    φ = ½ Σ_k w_k Σ_b h_b(x_k, z_k)²      χ = ½ Σ_{j∈J} (x0_j + Z_{N−1,j} − xT_j)²
    ω = ½ Σ_k w_k ‖e(x_k)‖²               υ = ½ Σ_k w_k ‖x_k − x0 − Z_k‖²
    σ = ½ Σ_k w_k Σ_i (λ_ik − clip(λ_ik + c·s_i(y_k), −1, 1))²

σ is the natural map of the complementarity λ ∈ Sgn(s) (as in contact mechanics, Alart
and Curnier): it is zero exactly when λ = sign s for s ≠ 0 and λ ∈ [−1, 1] for s = 0, so
with σ = 0 the sign term a·Sgn(s) contributes the point a·λ of Filippov's set, and
sticking and sliding come out of the equations, not out of a smoothing band.

With a cost the objective is ∫cost + λ·I (Example 7.1), otherwise I.

The quasidifferential [A_k, B_k] per node is expressed in the L² metric: the
integrand's quasidifferential (formulas (4.5), (4.555), (4.6)) plus the discrete
gradient of the coupled terms χ, υ divided by w_k (formulas (4.44), (4.55)).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .errors import InputError, ModelOutputError
from .grid import Grid
from .model import InclusionModel, SetBlock
from .psi import maximize_on_sphere
from .quasidifferential import Quasidifferential, SimplexSum


@dataclass(frozen=True)
class Terms:
    """Values of the functional's terms at one iterate."""

    phi: float
    chi: float
    omega: float
    upsilon: float
    sigma: float  # the selections' natural-map term (0 without exact sign terms)
    cost: float
    I: float
    objective: float


@dataclass(frozen=True)
class Residuals:
    """Checks of a trajectory that do not depend on the functional's weighting."""

    boundary_error: float  # max_j |x_j(T) − xT_j| and max_i |x_i(T) − x_i(0)| (periodic), read from x itself
    inclusion_residual: float  # max_k max_b h_b(x_k, z_k)
    surface_error: float | None  # max_k ‖e(x_k)‖_∞
    consistency_error: float  # max_k |x_k − x0 − Z_k|
    selection_residual: float | None  # max |λ − clip(λ + s, −1, 1)|: λ ∈ Sgn(s) to this (None: no selections)


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


@dataclass
class _Piece:
    """One group of pieces at ψ: values (N, m) and gradients (N, m, n + m)."""

    values: np.ndarray
    grads: np.ndarray


@dataclass
class _SignPart:
    """A sign term at ψ: κ = c(Sgn, ψ) (ψλ with a selection), its gradient, the amplitude a."""

    kappa: np.ndarray  # (N,)
    kappa_grad: np.ndarray  # (N, n + m + p): dκ/dy (the band's slope·∇s, or ψ on λ's column)
    amplitude: np.ndarray  # (N,) a(y)
    groups: list[_Piece]  # a = Σ_i max_q a_iq


@dataclass
class _Side:
    """A block evaluated at ψ (N, k): ℓ(ψ) = <z, ψ> − c(F_b, ψ) and its groups."""

    psi: np.ndarray
    ell: np.ndarray
    max_parts: list[_Piece]  # values <f_q, ψ>, gradients ψᵀ ∂f_q/∂y
    min_parts: list[_Piece]  # values g_p(y, ψ), gradients ∂g_p/∂y
    sign_parts: list[_SignPart]

    @property
    def h(self) -> np.ndarray:
        return np.maximum(0.0, self.ell)

    def gradient(self, width: int) -> np.ndarray:
        """∂ℓ/∂y (N, width) from the active piece of every group (a generalized-Jacobian
        element); y = (x, u, λ), the pieces' gradients fill the first n + m columns."""
        rows = np.arange(self.ell.size)
        grad = np.zeros((self.ell.size, width))
        for part in self.max_parts:
            grad[:, : part.grads.shape[-1]] -= part.grads[rows, np.argmax(part.values, axis=1)]
        for part in self.min_parts:
            grad[:, : part.grads.shape[-1]] -= part.grads[rows, np.argmin(part.values, axis=1)]
        for sign in self.sign_parts:
            grad -= sign.amplitude[:, None] * sign.kappa_grad
            for piece in sign.groups:
                grad[:, : piece.grads.shape[-1]] -= sign.kappa[:, None] * piece.grads[rows, np.argmax(piece.values, axis=1)]
        return grad

    @staticmethod
    def choose(upper: np.ndarray, a: "_Side", b: "_Side") -> "_Side":
        """Per node, side `a` where `upper` else side `b` (same block, same groups)."""

        def pick(u, v):
            mask = upper.reshape(upper.shape + (1,) * (u.ndim - 1))
            return np.where(mask, u, v)

        return _Side(
            pick(a.psi, b.psi),
            pick(a.ell, b.ell),
            [_Piece(pick(p.values, q.values), pick(p.grads, q.grads)) for p, q in zip(a.max_parts, b.max_parts)],
            [_Piece(pick(p.values, q.values), pick(p.grads, q.grads)) for p, q in zip(a.min_parts, b.min_parts)],
            [
                _SignPart(pick(p.kappa, q.kappa), pick(p.kappa_grad, q.kappa_grad), p.amplitude, p.groups)
                for p, q in zip(a.sign_parts, b.sign_parts)
            ],
        )


SIGN_MODES = ("exact", "band")


class Functional:
    """The discretized objective of a model on a grid."""

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
        self.blocks: tuple[SetBlock, ...] = tuple(model.blocks())
        # the sign terms in block order, (block index, term), and each one's selection column:
        # terms with the same `switch` callable share one λ (one surface, one Filippov selection)
        self.sign_terms = [] if signs == "band" else [
            (b, term) for b, block in enumerate(self.blocks) for term in block.signs
        ]
        columns: dict[int, int] = {}
        self.sign_columns = [columns.setdefault(id(term.switch), len(columns)) for _, term in self.sign_terms]
        self.selection_terms = [self.sign_terms[self.sign_columns.index(k)] for k in range(len(columns))]
        self.p = len(columns)
        self.dim = 2 * self.n + self.m + self.p
        self.args = self.n + self.m  # width of y = (x, u), the pieces' argument
        self.width = self.args + self.p  # width of the sides' gradients: (x, u, λ)
        self.surface = model.surface()
        self.cost = model.cost()
        self.penalty = float(self.cost.weight) if self.cost is not None else 1.0
        self.end = np.asarray(model.end_indices, dtype=int)  # J: x_j(T) = xT_j
        self.periodic = np.asarray(model.periodic, dtype=int)  # P: x_i(T) = x_i(0)
        self.start_given = np.isfinite(model.x0)  # x_i(0) = x0_i given; NaN: free
        self.psi_samples = psi_samples
        self._psi_memo: dict[int, list[tuple[bytes, np.ndarray]]] = {}  # per S_k block: recent (inputs, ψ*)
        self.free = np.ones((grid.nodes, self.dim), dtype=bool)
        self.free[0, : self.n] = ~self.start_given  # a given x_i(t_0) = x0_i is not an unknown
        self.resolved = dict(model.resolved)  # z_i ≡ x_j: z_i is not an unknown
        for i in self.resolved:
            self.free[:, self.n + i] = False

    # ---------------------------------------------------------------- layout
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
            if selections is None:
                y = self.arguments(xi)
                with np.errstate(divide="ignore", invalid="ignore"):
                    selections = np.stack([np.nan_to_num(np.clip(self._switch(self.blocks[b], term, y)[0] / term.band,
                                                                 -1.0, 1.0)) for b, term in self.selection_terms], axis=1)
            xi[:, 2 * self.n + self.m :] = selections
        return xi

    def initial_point(self) -> np.ndarray:
        t = self.grid.t
        x, z = self.model.initial_guess(t)
        u = self.model.initial_controls(t)
        for label, array, width in (("x", x, self.n), ("z", z, self.n), ("u", u, self.m)):
            if np.shape(array) != (t.size, width):
                raise ModelOutputError(
                    f"model {self.model.name!r}: initial {label} has shape {np.shape(array)}, expected {(t.size, width)}"
                )
        return self.pack(np.asarray(x, float), np.asarray(z, float), np.asarray(u, float))

    # ---------------------------------------------------------------- values
    def terms(self, xi: np.ndarray) -> Terms:
        """φ, χ, ω, υ, σ, the cost, I and the objective at ξ."""
        x, z = self.split(xi)
        phi, omega, sigma, cost = self._set_terms(xi)
        chi = 0.5 * float(np.sum(self._end_residual(x, z) ** 2))
        upsilon = 0.5 * self._integral(np.sum(self._consistency(x, z) ** 2, axis=1))
        total = phi + chi + omega + upsilon + sigma
        objective = cost + self.penalty * total if self.cost is not None else total
        return Terms(phi, chi, omega, upsilon, sigma, cost, total, objective)

    def objective(self, xi: np.ndarray) -> float:
        return self.terms(xi).objective

    def ray(self, xi: np.ndarray, direction: np.ndarray) -> Callable[[float], float]:
        """γ ↦ the objective at ξ + γG, what a line search minimizes (paper (180)).

        χ + υ is quadratic in γ (the end residual x0 + ∫z − xT and the consistency residual
        x − x0 − Z are affine in ξ): it is found here once, and each trial γ evaluates only
        the set pieces, φ's distances h, ω's surface, σ's natural map and the cost. Equal to
        `objective(ξ + γG)` to rounding; a trial where the model is NaN/inf raises as
        `objective` does.
        """
        x, z = self.split(xi)
        dx, dz = self.split(direction)
        zero = np.zeros_like(dx)
        quadratic = _Parabola.along(  # υ and χ: each (r(ξ), r's change per unit γ, w)
            (self._consistency(x, z), self._consistency(dx, dz), self.weights[:, None]),
            (self._end_residual(x, z), self._end_residual(dx, dz) - self._end_residual(zero, zero), 1.0),
        )

        def objective(gamma: float) -> float:
            phi, omega, sigma, cost = self._set_terms(xi + gamma * direction)
            total = phi + quadratic(gamma) + omega + sigma
            return cost + self.penalty * total if self.cost is not None else total

        return objective

    def _set_terms(self, xi: np.ndarray) -> tuple[float, float, float, float]:
        """φ, ω, σ and the cost at ξ, the terms not quadratic in ξ, from the pieces' values."""
        x, z = self.split(xi)
        y, lam = self.arguments(xi), self.selections(xi)
        distances = [self._interval_distance(b, y, z, lam) if block.size == 1 else self._state_sphere(block, y, z).h
                     for b, block in enumerate(self.blocks)]
        phi = 0.5 * self._integral(sum(h**2 for h in distances))
        omega = 0.5 * self._integral(np.sum(self._surface(x)[0] ** 2, axis=1)) if self.surface is not None else 0.0
        sigma = 0.5 * self._integral(np.sum(self._natural_map(y, lam) ** 2, axis=1)) if self.p else 0.0
        cost = self._integral(self._cost_integrand(y)) if self.cost is not None else 0.0
        return phi, omega, sigma, cost

    def _integral(self, values: np.ndarray) -> float:
        """Σ_k w_k·values_k (an elementwise sum: a BLAS dot goes multi-threaded above ~1e4 nodes)."""
        return float(np.sum(self.weights * values))

    def boundary_error(self, xi: np.ndarray) -> float:
        """max |x_j(T) − xT_j| over J and |x_i(T) − x_i(0)| over the periodic P, read from the
        trajectory x itself (0 if both are empty). χ measures x0 + ∫z instead; the two differ
        by the consistency error at T."""
        x = xi[:, : self.n]
        end = np.concatenate([x[-1, self.end] - self.model.end_values, x[-1, self.periodic] - x[0, self.periodic]])
        return float(np.max(np.abs(end))) if end.size else 0.0

    def residuals(self, xi: np.ndarray) -> Residuals:
        x, z = self.split(xi)
        h = np.max([np.max(state.h) for state in self._block_states(self.arguments(xi), z, self.selections(xi))])
        surface_error = None
        if self.surface is not None:
            surface_error = float(np.max(np.abs(self._surface(x)[0])))
        return Residuals(
            boundary_error=self.boundary_error(xi),
            inclusion_residual=float(h),
            surface_error=surface_error,
            consistency_error=float(np.max(np.abs(self._consistency(x, z)))),
            selection_residual=float(np.max(np.abs(self.selection_residual(xi, scale=1.0)[0]))) if self.p else None,
        )

    def selection_residual(self, xi: np.ndarray, scale: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The natural map r = λ − clip(λ + c·s(y), −1, 1) of every sign term, (N, p), and one
        element of its generalized Jacobian in y = (x, u, λ), (N, p, n + m + p). r = 0 exactly
        when λ ∈ Sgn(s). `scale` is c (default: the functional's `selection_scale`)."""
        c = self.selection_scale if scale is None else scale
        y, lam = self.arguments(xi), self.selections(xi)
        nodes = y.shape[0]
        residual = np.empty((nodes, self.p))
        jacobian = np.zeros((nodes, self.p, self.width))
        for k, (b, term) in enumerate(self.selection_terms):
            s, ds = self._switch(self.blocks[b], term, y)
            moved = lam[:, k] + c * s
            inside = (moved > -1.0) & (moved < 1.0)  # the clip is the identity there
            residual[:, k] = lam[:, k] - np.clip(moved, -1.0, 1.0)
            jacobian[:, k, : self.args] = -c * inside[:, None] * ds
            jacobian[:, k, self.args + k] = 1.0 - inside
        return residual, jacobian

    def _natural_map(self, y: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """σ's r = λ − clip(λ + c·s(y), −1, 1), (N, p): :meth:`selection_residual` without its Jacobian."""
        c = self.selection_scale
        return np.stack([lam[:, k] - np.clip(lam[:, k] + c * self._switch(self.blocks[b], term, y)[0], -1.0, 1.0)
                         for k, (b, term) in enumerate(self.selection_terms)], axis=1)

    def set_bounds(self, xi: np.ndarray) -> list[tuple[np.ndarray, np.ndarray] | None]:
        """For each one-coordinate block the interval [lo, hi] of F_b(x(t_k)); None for S_k blocks."""
        y, lam = self.arguments(xi), self.selections(xi)
        bounds: list[tuple[np.ndarray, np.ndarray] | None] = []
        for b, block in enumerate(self.blocks):
            if block.size != 1:
                bounds.append(None)
                continue
            zero = np.zeros((y.shape[0], self.n))
            plus, minus = self._sides_1d(block, y, zero, self._block_selections(b, lam))  # ℓ(ψ) = −c(F, ψ) at z = 0
            bounds.append((minus.ell, -plus.ell))
        return bounds

    # ------------------------------------------------------ quasidifferential
    def quasidifferential(self, xi: np.ndarray, delta: float) -> Quasidifferential:
        """[A_k, B_k] for every node, δ-active pieces, L² metric (paper Section 4)."""
        x, z = self.split(xi)
        y = self.arguments(xi)
        nodes, n = x.shape
        w = self.weights
        smooth = np.zeros((nodes, self.dim))
        # υ (4.55): x-part r_k (and −Σ w_k r_k / w_0 on a free x_i(0)), z-part −(Cᵀ w r)_k / w_k
        r = self._consistency(x, z)
        smooth[:, :n] += r
        smooth[0, :n] -= ~self.start_given * (w @ r) / w[0]
        smooth[:, n : 2 * n] -= self.grid.cumulative_adjoint(w[:, None] * r) / w[:, None]
        # χ (4.44): each end residual on its coordinate's z at every node (the integral's
        # weights over w_k), and on a free x_j(0)
        end = self._end_residual(x, z)
        if end.size:
            coords = np.concatenate([self.end, self.periodic])
            np.add.at(smooth, (slice(None), n + coords), (self.grid.integral_weights / w)[:, None] * end)
            starts = end[: self.end.size] * ~self.start_given[self.end]
            np.add.at(smooth[0], self.end, starts / w[0])
        # ω (4.6)
        if self.surface is not None:
            e, de = self._surface(x)
            smooth[:, :n] += np.einsum("ko,kon->kn", e, de)
        # σ: the natural map's residual times an element of its generalized Jacobian
        if self.p:
            r, dr = self.selection_residual(xi)
            smooth += self._embed(np.einsum("ki,kid->kd", r, dr))
        sub_groups: list[tuple[np.ndarray, np.ndarray]] = []
        sup_groups: list[tuple[np.ndarray, np.ndarray]] = []
        for block, side in zip(self.blocks, self._block_states(y, z, self.selections(xi))):
            h = side.h
            positive = h > 0
            smooth[:, n + np.asarray(block.coords)] += h[:, None] * side.psi  # h ψ* e_z
            for part in side.min_parts:  # −min g is convex: subdifferential (4.555)
                mask = _delta_active(-part.values, delta, positive)
                sub_groups.append((self._embed(-h[:, None, None] * part.grads), mask))
            for part in side.max_parts:  # −max <f, ψ*> is concave: superdifferential (4.5)
                mask = _delta_active(part.values, delta, positive)
                sup_groups.append((self._embed(-h[:, None, None] * part.grads), mask))
            for sign in side.sign_parts:  # −κ·a(y) − smooth in s: by the sign of κ
                smooth -= self._embed(h[:, None] * sign.amplitude[:, None] * sign.kappa_grad)
                for piece in sign.groups:
                    mask = _delta_active(piece.values, delta, positive)
                    scale = (h * sign.kappa)[:, None, None]
                    sup_groups.append((self._embed(-np.maximum(scale, 0.0) * piece.grads), mask))
                    sub_groups.append((self._embed(np.maximum(-scale, 0.0) * piece.grads), mask))
        sub = _assemble(smooth, sub_groups).scaled(self.penalty)
        sup = _assemble(np.zeros_like(smooth), sup_groups).scaled(self.penalty)
        if self.cost is not None:
            cost_sub, cost_sup = self._cost_quasidifferential(y, delta)
            sub, sup = sub + cost_sub, sup + cost_sup
        return Quasidifferential(_project(self._tie(sub), self.free), _project(self._tie(sup), self.free))

    def _tie(self, polytope: SimplexSum) -> SimplexSum:
        """The chain rule of z_i ≡ x_j: a z_i-component moves onto x_j."""
        if not self.resolved:
            return polytope
        center, generators = polytope.center.copy(), polytope.generators.copy()
        for i, j in self.resolved.items():
            for array in (center, generators):
                array[..., j] += array[..., self.n + i]
                array[..., self.n + i] = 0.0
        return SimplexSum(center, generators, polytope.mask)

    # ------------------------------------------------ residuals and Jacobians
    def distance_sides(self, xi: np.ndarray) -> list[DistanceSides]:
        """For every block, h_b = max(0, max_side ℓ_side) with each side's signed ℓ and
        one element of its generalized Jacobian (:meth:`_Side.gradient`). One-coordinate
        blocks have two sides, ψ = +1 and ψ = −1 (the interval's ends); S_k blocks have
        one, ψ = ψ*."""
        y, z, lam = self.arguments(xi), self.split(xi)[1], self.selections(xi)
        out = []
        for b, block in enumerate(self.blocks):
            sides = (self._sides_1d(block, y, z, self._block_selections(b, lam)) if block.size == 1
                     else [self._state_sphere(block, y, z)])
            point = (block.size == 1 and not sides[0].min_parts and (self.p or not block.signs)
                     and all(part.values.shape[1] == 1 for part in sides[0].max_parts))
            out.append(DistanceSides(block.coords, [(side.ell, side.gradient(self.width), side.psi)
                                                    for side in sides[: 1 if point else None]], point))
        return out

    def cost_pieces(self, xi: np.ndarray) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[tuple[np.ndarray, np.ndarray]]]:
        """The cost's max-groups and min-groups: lists of (values (N, m), gradients (N, m, n + m))."""
        y = self.arguments(xi)
        return (
            [self._scalar_pieces(fn, y, "cost max-group") for fn in self.cost.max_groups],  # type: ignore[union-attr]
            [self._scalar_pieces(fn, y, "cost min-group") for fn in self.cost.min_groups],  # type: ignore[union-attr]
        )

    def surface_values(self, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """e(x) (N, o) and ∂e/∂x (N, o, n); requires a surface."""
        return self._surface(self.split(xi)[0])

    def consistency(self, xi: np.ndarray) -> np.ndarray:
        """x − x0 − ∫_0^t z at every node, (N, n)."""
        return self._consistency(*self.split(xi))

    def end_residual(self, xi: np.ndarray) -> np.ndarray:
        """x_j(0) + ∫_0^T z_j − xT_j for j ∈ J, then ∫_0^T z_i (= x_i(T) − x_i(0)) for i ∈ P."""
        return self._end_residual(*self.split(xi))

    # ---------------------------------------------------------------- pieces
    def _end_residual(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        if not (self.end.size or self.periodic.size):
            return np.zeros(0)
        fixed = x[0, self.end] + self.grid.integral(z[:, self.end]) - self.model.end_values
        return np.concatenate([fixed, self.grid.integral(z[:, self.periodic])])

    def _consistency(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """x_k − x(t_0) − ∫_0^{t_k} z (x(t_0) = x0 where given)."""
        return x - x[:1] - self.grid.cumulative(z)

    def _embed(self, grads: np.ndarray) -> np.ndarray:
        """Gradients in y = (x, u) or (x, u, λ) placed in the x-, u- (and λ-) slots of ξ's row."""
        out = np.zeros(grads.shape[:-1] + (self.dim,))
        out[..., : self.n] = grads[..., : self.n]
        out[..., 2 * self.n : self.n + grads.shape[-1]] = grads[..., self.n :]
        return out

    def _surface(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        e, de = self.surface.function(x)  # type: ignore[union-attr]
        self._check("surface", e, (x.shape[0], None))
        self._check("surface Jacobian", de, (x.shape[0], e.shape[1], self.n))
        return e, de

    def _cost_integrand(self, x: np.ndarray) -> np.ndarray:
        total = np.zeros(x.shape[0])
        for fn in self.cost.max_groups:  # type: ignore[union-attr]
            total += _reduce_last(np.maximum, self._scalar_pieces(fn, x, "cost max-group")[0])
        for fn in self.cost.min_groups:  # type: ignore[union-attr]
            total += _reduce_last(np.minimum, self._scalar_pieces(fn, x, "cost min-group")[0])
        return total

    def _cost_quasidifferential(self, x: np.ndarray, delta: float) -> tuple[SimplexSum, SimplexSum]:
        everywhere = np.ones(x.shape[0], dtype=bool)
        sub = [(self._embed(g), _delta_active(v, delta, everywhere))
               for v, g in (self._scalar_pieces(fn, x, "cost max-group") for fn in self.cost.max_groups)]  # type: ignore[union-attr]
        sup = [(self._embed(g), _delta_active(-v, delta, everywhere))
               for v, g in (self._scalar_pieces(fn, x, "cost min-group") for fn in self.cost.min_groups)]  # type: ignore[union-attr]
        zero = np.zeros((x.shape[0], self.dim))
        return _assemble(zero, sub), _assemble(zero, sup)

    def _scalar_pieces(self, fn, x: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
        values, grads = fn(x)
        self._check(label, values, (x.shape[0], None))
        self._check(f"{label} gradient", grads, (x.shape[0], values.shape[1], self.args))
        return values, grads

    def _max_group(self, block: SetBlock, group, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f, jac = group.pieces(x)
        label = f"block {block.name or block.coords} max-group {group.name!r}"
        self._check(label, f, (x.shape[0], None, block.size))
        self._check(f"{label} Jacobian", jac, (x.shape[0], f.shape[1], block.size, self.args))
        return f, jac

    def _min_group(self, block: SetBlock, group, x: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g, grad = group.pieces(x, psi)
        label = f"block {block.name or block.coords} min-group {group.name!r}"
        self._check(label, g, (x.shape[0], None))
        self._check(f"{label} gradient", grad, (x.shape[0], g.shape[1], self.args))
        return g, grad

    def _block_states(self, y: np.ndarray, z: np.ndarray, lam: np.ndarray) -> list[_Side]:
        """Every block at its ψ*."""
        return [
            self._state_1d(block, y, z, self._block_selections(b, lam)) if block.size == 1
            else self._state_sphere(block, y, z)
            for b, block in enumerate(self.blocks)
        ]

    def _block_selections(self, b: int, lam: np.ndarray) -> list[tuple[int, np.ndarray] | None]:
        """For each sign term of block b: (its column in y = (x, u, λ), its λ), or None (band)."""
        if not self.p:
            return [None] * len(self.blocks[b].signs)
        columns = [k for k, (block, _) in zip(self.sign_columns, self.sign_terms) if block == b]
        return [(self.args + k, lam[:, k]) for k in columns]

    def _side(self, block: SetBlock, y: np.ndarray, z: np.ndarray, psi: np.ndarray,
              maxes: list[tuple[np.ndarray, np.ndarray]] | None = None,
              selections: list | None = None) -> _Side:
        """All groups of `block` at ψ (N, k); `maxes` reuses evaluated max-groups."""
        if maxes is None:
            maxes = [self._max_group(block, group, y) for group in block.max_groups]
        ell = np.einsum("nk,nk->n", z[:, list(block.coords)], psi)
        max_parts = [_Piece(np.einsum("nqk,nk->nq", f, psi), np.einsum("nqkd,nk->nqd", jac, psi)) for f, jac in maxes]
        min_parts = [_Piece(*self._min_group(block, group, y, psi)) for group in block.min_groups]
        selections = selections or [None] * len(block.signs)
        sign_parts = [self._sign_part(block, term, y, psi[:, 0], sel) for term, sel in zip(block.signs, selections)]
        for part in max_parts:
            ell -= part.values.max(axis=1)
        for part in min_parts:
            ell -= part.values.min(axis=1)
        for part in sign_parts:
            ell -= part.kappa * part.amplitude
        return _Side(psi, ell, max_parts, min_parts, sign_parts)

    def _switch(self, block: SetBlock, term, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """s (N,) and ∇s (N, n + m) of a sign term of `block`, checked."""
        label = f"block {block.name or block.coords} sign term {term.name!r}"
        s, ds = term.switch(y)
        self._check(f"{label} switch", s, (y.shape[0],))
        self._check(f"{label} switch gradient", ds, (y.shape[0], self.args))
        return s, ds

    def _sign_part(self, block: SetBlock, term, y: np.ndarray, psi: np.ndarray,
                   selection: tuple[int, np.ndarray] | None = None) -> _SignPart:
        """c(a(y)·Sgn(s), ψ) = a(y)·κ of a sign term, ψ = ±1 per node (model.SignTerm):
        κ = ψλ with a selection (column, λ), else the band's κ_ψ(s)."""
        amplitude, groups = self._amplitude(block, term, y)
        kappa_grad = np.zeros((y.shape[0], self.width))
        if selection is not None:  # the point a·λ of Filippov's set: c = a·ψλ
            column, lam = selection
            kappa_grad[:, column] = psi
            return _SignPart(psi * lam, kappa_grad, amplitude, groups)
        s, ds = self._switch(block, term, y)
        kappa, slope = _band_kappa(term.band, s, psi)
        if slope is not None:
            kappa_grad[:, : self.args] = slope[:, None] * ds
        return _SignPart(kappa, kappa_grad, amplitude, groups)

    def _amplitude(self, block: SetBlock, term, y: np.ndarray) -> tuple[np.ndarray, list[_Piece]]:
        """A sign term's a(y) = Σ_i max_q a_iq(y) (N,) and its groups."""
        if isinstance(term.amplitude, (int, float)):
            return np.full(y.shape[0], float(term.amplitude)), []
        label = f"block {block.name or block.coords} sign term {term.name!r}"
        groups = [_Piece(*self._scalar_pieces(fn, y, f"{label} amplitude")) for fn in term.amplitude]
        return sum(_reduce_last(np.maximum, piece.values) for piece in groups), groups

    def _interval_distance(self, b: int, y: np.ndarray, z: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """h_b = max(0, ℓ(+1), ℓ(−1)) of a one-coordinate block from the pieces' values alone:
        :meth:`_state_1d`'s h, bit for bit, with the pieces that do not depend on ψ evaluated
        once, in its order (a NaN names the same piece)."""
        block, nodes = self.blocks[b], y.shape[0]

        def minima(psi: float) -> list[np.ndarray]:
            return [_reduce_last(np.minimum, self._min_group(block, group, y, np.full((nodes, 1), psi))[0])
                    for group in block.min_groups]

        maxes = [self._max_group(block, group, y)[0][:, :, 0] for group in block.max_groups]
        upper = minima(1.0)
        signs = [(term, selection, self._amplitude(block, term, y)[0],
                  None if selection is not None else self._switch(block, term, y)[0])
                 for term, selection in zip(block.signs, self._block_selections(b, lam))]
        lower = minima(-1.0)

        def ell(psi: float, mins: list[np.ndarray]) -> np.ndarray:
            """ℓ(ψ) = zψ − c(F_b, ψ), as :meth:`_side` sums it."""
            value = z[:, block.coords[0]] * psi
            for f in maxes:
                value -= _reduce_last(np.maximum, f * psi)
            for g in mins:
                value -= g
            for term, selection, amplitude, s in signs:
                value -= (psi * selection[1] if selection is not None else _band_kappa(term.band, s, psi)[0]) * amplitude
            return value

        return np.maximum(0.0, np.maximum(ell(1.0, upper), ell(-1.0, lower)))

    def _sides_1d(self, block: SetBlock, y: np.ndarray, z: np.ndarray, selections: list | None = None) -> list[_Side]:
        """A one-coordinate block at ψ = +1 and ψ = −1."""
        maxes = [self._max_group(block, group, y) for group in block.max_groups]
        ones = np.ones((y.shape[0], 1))
        return [self._side(block, y, z, ones, maxes, selections), self._side(block, y, z, -ones, maxes, selections)]

    def _state_1d(self, block: SetBlock, y: np.ndarray, z: np.ndarray, selections: list | None = None) -> _Side:
        """ψ ∈ {−1, +1}: ψ* in closed form (the nearer violated end of the interval)."""
        plus, minus = self._sides_1d(block, y, z, selections)
        return _Side.choose(plus.ell >= minus.ell, plus, minus)

    def _state_sphere(self, block: SetBlock, y: np.ndarray, z: np.ndarray) -> _Side:
        """ψ ∈ S_k: ψ* searched numerically, vectorized over nodes (Remark 5.1), once per
        iterate: the last few ψ* are kept per block under the exact bytes of their inputs
        (y, z_b and the sample count), so a repeated iterate reuses its ψ* and different
        inputs never do."""
        nodes, k = y.shape[0], block.size
        zb = z[:, list(block.coords)]
        maxes = [self._max_group(block, group, y) for group in block.max_groups]
        key = b"".join([np.int64([self.psi_samples, *y.shape, *zb.shape]).tobytes(),
                        np.ascontiguousarray(y, dtype=float).tobytes(), np.ascontiguousarray(zb, dtype=float).tobytes()])
        memo = self._psi_memo.setdefault(id(block), [])
        psi = next((found for inputs, found in memo if inputs == key), None)
        if psi is None:

            def ell(psi: np.ndarray) -> np.ndarray:  # psi (N, M, k) -> (N, M)
                count = psi.shape[1]
                value = np.einsum("nk,nmk->nm", zb, psi)
                for f, _ in maxes:
                    value -= _reduce_last(np.maximum, np.einsum("nqk,nmk->nmq", f, psi))
                if block.min_groups:
                    y_rep = y if count == 1 else np.repeat(y, count, axis=0)
                    flat = psi.reshape(nodes * count, k)
                    for group in block.min_groups:
                        g, _ = group.pieces(y_rep, flat)
                        value -= _reduce_last(np.minimum, g.reshape(nodes, count, -1))
                return value

            psi = maximize_on_sphere(ell, nodes, k, samples=self.psi_samples)
            memo.insert(0, (key, psi))
            del memo[4:]
        return self._side(block, y, z, psi.copy(), maxes)

    def _check(self, label: str, array: np.ndarray, shape: tuple[int | None, ...]) -> None:
        array = np.asarray(array)
        if array.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, array.shape)):
            expected = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
            raise ModelOutputError(
                f"model {self.model.name!r}: {label} returned shape {array.shape}, expected {expected}", label=label
            )
        finite = np.isfinite(array)
        if not finite.all():
            bad = np.argwhere(~finite)[0]
            node = int(bad[0])
            per_node = array.shape[0] == self.grid.nodes
            when = f" (t = {self.grid.t[node]:.6g})" if per_node else ""
            raise ModelOutputError(
                f"model {self.model.name!r}: {label} returned a non-finite value at node {node}{when}",
                label=label, node=node if per_node else None, nonfinite=True,
            )


def _reduce_last(ufunc: np.ufunc, values: np.ndarray) -> np.ndarray:
    """ufunc over the last (short) axis, one column at a time: `values.max(axis=-1)` for
    np.maximum, several times faster for a few pieces and many nodes, same values (NaN too)."""
    out = values[..., 0].copy()
    for column in range(1, values.shape[-1]):
        ufunc(out, values[..., column], out=out)
    return out


def _band_kappa(band: float, s: np.ndarray, psi: np.ndarray | float) -> tuple[np.ndarray, np.ndarray | None]:
    """κ_ψ(s) of a sign term without a selection (:class:`~qdframe.model.SignTerm`) and
    dκ/ds (None where it is 0): band β = inf, the whole interval a·[−1, 1] everywhere (a
    term on its own surface); β > 0, κ = 1 − 2·S(u), u = clip(−ψs/β, 0, 1), S(u) = 3u² − 2u³
    (C¹); β = 0, Filippov's exact sign, the whole interval only at s = 0."""
    if np.isinf(band):
        return np.ones_like(s), None
    if band > 0:
        u = np.clip(-psi * s / band, 0.0, 1.0)
        return 1.0 - 2.0 * u * u * (3.0 - 2.0 * u), 12.0 * u * (1.0 - u) * psi / band
    return np.where(psi * s >= 0, 1.0, -1.0), None


@dataclass(frozen=True)
class _Parabola:
    """q(γ) = ½ Σ w‖r + γs‖² of affine residuals along a ray, in vertex form
    q* + a·(γ − γ*)², a = ½ Σ w‖s‖²: both terms are ≥ 0, so q keeps the accuracy of a
    direct evaluation where it is small (a·γ² + b·γ + c loses it to cancellation)."""

    minimum: float  # q*
    curvature: float  # a
    vertex: float  # γ*

    @classmethod
    def along(cls, *terms: tuple[np.ndarray, np.ndarray, np.ndarray | float]) -> "_Parabola":
        """Σ over the terms (r, s, w) of ½ Σ w·(r + γs)², w broadcast to r's shape."""
        slope = sum(float(np.sum(w * r * s)) for r, s, w in terms)  # q'(0)
        second = sum(float(np.sum(w * s * s)) for _, s, w in terms)  # q''
        vertex = -slope / second if second > 0 else 0.0
        minimum = 0.5 * sum(float(np.sum(w * (r + vertex * s) ** 2)) for r, s, w in terms)
        return cls(minimum, 0.5 * second, vertex)

    def __call__(self, gamma: float) -> float:
        return self.minimum + self.curvature * (gamma - self.vertex) ** 2


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
