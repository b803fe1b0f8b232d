"""The functional's values: φ, χ, ω, υ, σ, the cost, I and the objective; the ray.

Paper (3.13), (3.14), (3.14'), (3.17), with the scheme's weights w_k and cumulative
integral Z = ∫_0^t z (:class:`~qdframe.schemes.grid.Grid`, from the scheme's rule):

    φ = ½ Σ_k w_k Σ_b h_b(x_k, z_k)²      χ = ½ Σ_{j∈J} (x0_j + Z_{N−1,j} − xT_j)²
    ω = ½ Σ_k w_k ‖e(x_k)‖²               υ = ½ Σ_k w_k ‖x_k − x0 − Z_k‖²
    σ = ½ Σ_k w_k Σ_i (λ_ik − clip(λ_ik + c·s_i(y_k), −1, 1))²   (a vector sign: λ − P_B(λ + c·s))

I = φ + χ + ω + υ + σ; the objective is ∫cost + λ·I with a cost (Example 7.1), else I.
:meth:`Values.ray` is the objective along a ray, what a line search minimizes.
:meth:`Values.residuals` are the pointwise checks of a trajectory behind `solved`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..schemes.grid import Grid
from ..model import Cost, Surface
from .held import HeldChoices
from .layout import Layout
from .pieces import Pieces, _reduce_last
from .shifts import Shifts, equation_part, shifted_sums

SATURATED = 1e-6  # |λ| ≥ 1 − this: a selection at an end of its set, off its surface (as qdframe.certificates.switches)


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
    eta: float = 0.0  # the held choices' term (qdframe.functional.held; 0 with inputs free)


@dataclass(frozen=True)
class Bounds:
    """The finite sides of the bounds lo_j ≤ y_j ≤ hi_j on the states and controls, y = (x, u):
    side i is sense_i·(y_{column_i} − limit_i) ≤ 0 (an upper bound: +1 and hi, a lower: −1 and lo)."""

    columns: np.ndarray  # (q,) int
    sense: np.ndarray  # (q,) ±1.0
    limit: np.ndarray  # (q,)
    names: tuple[str, ...] = ()  # "u ≤ 2", … (what binds, in messages)


@dataclass(frozen=True)
class Residuals:
    """Checks of a trajectory that do not depend on the functional's weighting."""

    boundary_error: float  # max_j |x_j(T) − xT_j| and max_i |x_i(T) − x_i(0)| (periodic), read from x itself
    inclusion_residual: float  # max_k max_b h_b(x_k, z_k)
    surface_error: float | None  # max_k ‖e(x_k)‖_∞
    consistency_error: float  # max_k |x_k − x0 − Z_k|
    selection_residual: float | None  # max |λ − clip(λ + s, −1, 1)|: λ ∈ Sgn(s) to this (None: no selections)


@dataclass(eq=False)
class Values:
    """The terms' values at ξ, the ray and the pointwise residuals: one of the parts of
    :class:`~qdframe.functional.Functional`, the model's pieces evaluated by its `pieces`."""

    layout: Layout
    grid: Grid
    pieces: Pieces
    surface: Surface | None  # e(x) = 0 of ω
    cost: Cost | None
    penalty: float  # λ of the objective ∫cost + λ·I (1 without a cost)
    end: np.ndarray  # J: x_j(T) = xT_j
    periodic: np.ndarray  # P: x_i(T) = x_i(0)
    end_values: np.ndarray  # xT_j, j ∈ J
    selection_scale: float  # c of σ's natural map
    held: "HeldChoices | None" = None  # η, with inputs="held" (:mod:`.held`)
    shifts: Shifts | None = None  # the augmented Lagrangian's, on the grid's nodes (:mod:`.shifts`)
    bounds: "Bounds | None" = None  # lo ≤ y_j ≤ hi of the bounded states and controls (β)

    def terms(self, xi: np.ndarray) -> Terms:
        """φ, χ, ω, υ, σ, the cost, I and the objective at ξ (with shifts: the terms and I
        unshifted, what the checks read, and the objective shifted, :func:`.shifts.shifted_sums`)."""
        if self.shifts is not None:
            return _shifted_terms(self, xi)
        x, z = self.layout.split(xi)
        phi, omega, sigma, cost, eta = self._set_terms(xi)
        chi = 0.5 * float(np.sum(self.end_residual(x, z) ** 2))
        upsilon = 0.5 * self.integral(np.sum(self.consistency(x, z) ** 2, axis=1))
        total = phi + chi + omega + upsilon + sigma + eta
        objective = cost + self.penalty * total if self.cost is not None else total
        return Terms(phi, chi, omega, upsilon, sigma, cost, total, objective, eta)

    def ray(self, xi: np.ndarray, direction: np.ndarray) -> Callable[[float], float]:
        """γ ↦ the objective at ξ + γG, what a line search minimizes (paper (180)).

        χ + υ is quadratic in γ (the end residual x0 + ∫z − xT and the consistency residual
        x − x0 − Z are affine in ξ): it is found here once, and each trial γ evaluates only
        the set pieces, φ's distances h, ω's surface, σ's natural map and the cost. Equal to
        `objective(ξ + γG)` to rounding; a trial where the model is NaN/inf raises as
        `objective` does.
        """
        x, z = self.layout.split(xi)
        dx, dz = self.layout.split(direction)
        zero = np.zeros_like(dx)
        terms = ((self.consistency(x, z), self.consistency(dx, dz), self.grid.weights[:, None]),
                 (self.end_residual(x, z), self.end_residual(dx, dz) - self.end_residual(zero, zero), 1.0))
        quadratic = _Parabola.along(*terms)  # υ and χ: each (r(ξ), r's change per unit γ, w)
        linear = (0.0, 0.0)  # with shifts s, Σ w·s·r(ξ + γG) (r·(½r + s), :meth:`terms`): its value and slope
        if self.shifts is not None:
            (r, d, w), (end, end_d, _) = terms
            s, s_end = self.shifts.consistency, self.shifts.end
            linear = (float(np.sum(w * s * r)) + float(np.sum(s_end * end)),
                      float(np.sum(w * s * d)) + float(np.sum(s_end * end_d)))

        def objective(gamma: float) -> float:
            phi, omega, sigma, cost, eta = self._set_terms(xi + gamma * direction)
            total = phi + quadratic(gamma) + linear[0] + gamma * linear[1] + omega + sigma + eta
            return cost + self.penalty * total if self.cost is not None else total

        return objective

    def _set_terms(self, xi: np.ndarray) -> tuple[float, float, float, float, float]:
        """φ, ω, σ, the cost and η at ξ, the terms not quadratic in ξ, from the pieces' values."""
        x, z = self.layout.split(xi)
        y, lam = self.layout.arguments(xi), self.layout.selections(xi)
        if self.shifts is not None:
            return self._shifted_set_terms(xi, x, y, z, lam)
        phi = 0.5 * self.integral(sum(h**2 for h in self._distances(y, z, lam)))
        if self.bounds is not None:  # β: the bounds' sides, one-sided like φ's
            phi += 0.5 * self.integral(np.sum(np.maximum(self.bound_sides(y), 0.0) ** 2, axis=1))
        omega = 0.5 * self.integral(np.sum(self.surface_at(x)[0] ** 2, axis=1)) if self.surface is not None else 0.0
        sigma = 0.5 * self.integral(np.sum(self._natural_map(y, lam) ** 2, axis=1)) if self.layout.p else 0.0
        cost = self.cost_value(x, y) if self.cost is not None else 0.0
        eta = self.held.eta(xi) if self.held is not None else 0.0
        return phi, omega, sigma, cost, eta

    def _shifted_set_terms(self, xi: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray,
                           lam: np.ndarray) -> tuple[float, float, float, float, float]:
        """φ (with the bounds' β), ω, σ, the cost and η with the augmented Lagrangian's shifts
        (:func:`.shifts.shifted_sums`)."""
        phi, omega, sigma = shifted_sums(self.constraint_residuals(x, y, z, lam), self.shifts, self.integral)
        cost = self.cost_value(x, y) if self.cost is not None else 0.0
        eta = self.held.eta(xi) if self.held is not None else 0.0  # (η: no multipliers)
        return phi, omega, sigma, cost, eta

    def constraint_residuals(self, x: np.ndarray, y: np.ndarray, z: np.ndarray, lam: np.ndarray) -> Shifts:
        """Every residual behind I, unshifted, in the form of :class:`~.shifts.Shifts` (on the
        grid's nodes): υ, χ, e(x), each block's sides ℓ(+1), ℓ(−1) (a point set: its equation
        z_b − f_b(y) and 0; an S_k block: ℓ(ψ*) and 0), σ's natural map, the bounds' sides."""
        nodes, blocks = y.shape[0], self.layout.blocks
        sides = np.zeros((nodes, len(blocks), 2))
        point = np.zeros(len(blocks), dtype=bool)
        for b, block in enumerate(blocks):
            if block.size != 1:
                sides[:, b, 0] = self.pieces.state_sphere(block, y, z).ell
                continue
            plus, minus, point[b] = self.pieces.interval_sides(block, y, z, self.layout.block_selections(b, lam))
            sides[:, b, 0] = plus
            sides[:, b, 1] = 0.0 if point[b] else minus
        surface = self.surface_at(x)[0] if self.surface is not None else np.zeros((nodes, 0))
        return Shifts(t=self.grid.t, consistency=self.consistency(x, z), end=self.end_residual(x, z),
                      surface=surface, blocks=sides,
                      selections=self._natural_map(y, lam) if self.layout.p else np.zeros((nodes, 0)),
                      bounds=self.bound_sides(y), point=point)

    def bound_sides(self, y: np.ndarray) -> np.ndarray:
        """The bounds' sides sense_i·(y_i − limit_i) (N, q) (:class:`Bounds`); q = 0 without."""
        bounds = self.bounds
        if bounds is None:
            return np.zeros((y.shape[0], 0))
        return bounds.sense * (y[:, bounds.columns] - bounds.limit)

    def _distances(self, y: np.ndarray, z: np.ndarray, lam: np.ndarray) -> list[np.ndarray]:
        """h_b (N,) of every block from the pieces' values (no gradients): an interval's in
        closed form, an S_k block's at its ψ*."""
        return [self.pieces.interval_distance(block, y, z, self.layout.block_selections(b, lam)) if block.size == 1
                else self.pieces.state_sphere(block, y, z).h for b, block in enumerate(self.layout.blocks)]

    def integral(self, values: np.ndarray) -> float:
        """Σ_k w_k·values_k (an elementwise sum: a BLAS dot goes multi-threaded above ~1e4 nodes)."""
        return float(np.sum(self.grid.weights * values))

    def boundary_error(self, xi: np.ndarray) -> float:
        """max |x_j(T) − xT_j| over J and |x_i(T) − x_i(0)| over the periodic P, read from the
        trajectory x itself (0 if both are empty). χ measures x0 + ∫z instead; the two differ
        by the consistency error at T."""
        x = xi[:, : self.layout.n]
        end = np.concatenate([x[-1, self.end] - self.end_values, x[-1, self.periodic] - x[0, self.periodic]])
        return float(np.max(np.abs(end))) if end.size else 0.0

    def residuals(self, xi: np.ndarray) -> Residuals:
        x, z = self.layout.split(xi)
        distances = self._distances(self.layout.arguments(xi), z, self.layout.selections(xi))
        h = np.max([np.max(h) for h in distances])
        surface_error = None
        if self.surface is not None:
            surface_error = float(np.max(np.abs(self.surface_at(x)[0])))
        return Residuals(
            boundary_error=self.boundary_error(xi),
            inclusion_residual=float(h),
            surface_error=surface_error,
            consistency_error=float(np.max(np.abs(self.consistency(x, z)))),
            selection_residual=float(np.max(np.abs(self.selection_residual(xi, scale=1.0)[0]))) if self.layout.p else None,
        )

    def selection_kinks(self, xi: np.ndarray, reach: np.ndarray) -> np.ndarray:
        """(N, p): the scalar selections whose natural map is within `reach` (N, p) of its kink,
        |λ + c·s| = 1 (its two branches, −c·s and λ ∓ 1, there both in play); not a vector sign's
        columns nor a held left limit."""
        y, lam = self.layout.arguments(xi), self.layout.selections(xi)
        moved = lam + self.selection_scale * self.switch_values(y, gradients=False)[0]
        kinks = np.abs(1.0 - np.abs(moved)) <= reach
        for first, width in self.layout.balls:
            kinks[:, first : first + width] = False
        rows, cols = self._hold_left_limits(np.zeros_like(lam), lam)
        kinks[rows, cols] = False
        return kinks

    def selection_residual(self, xi: np.ndarray, scale: float | None = None,
                           flip: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The natural map r = λ − P(λ + c·s(y)) of every selection, (N, p), and one element of
        its generalized Jacobian in y = (x, u, λ), (N, p, n + m + p). P is the clip to [−1, 1]
        for a scalar Sgn(s) and the projection onto the unit ball B for a vector sign's k
        columns (second-order-cone complementarity). r = 0 exactly when λ ∈ Sgn(s). `scale` is
        c (default: the functional's `selection_scale`)."""
        c = self.selection_scale if scale is None else scale
        y, lam = self.layout.arguments(xi), self.layout.selections(xi)
        args, p = self.layout.args, self.layout.p
        s, ds = self.switch_values(y)
        moved = lam + c * s
        residual = lam - self.project(moved)
        jacobian = np.zeros((y.shape[0], p, self.layout.width))
        inside = (moved > -1.0) & (moved < 1.0)  # the clip is the identity there
        if flip is not None:  # the other branch's element where asked (a kink: :meth:`selection_kinks`)
            inside = inside ^ flip
        jacobian[:, :, :args] = -c * inside[:, :, None] * ds
        columns = np.arange(p)
        jacobian[:, columns, args + columns] = 1.0 - inside
        for first, width in self.layout.balls:  # P_B's Jacobian: I inside the ball, (I − ŵŵᵀ)/|w| outside
            block = slice(first, first + width)
            derivative = _ball_projection_jacobian(moved[:, block])
            jacobian[:, block, :args] = -c * derivative @ ds[:, block]
            jacobian[:, block, args + first : args + first + width] = np.eye(width) - derivative
        rows, cols = self._hold_left_limits(residual, lam)  # its −1 on λ_{k−1} is the caller's (:meth:`left_limits`)
        jacobian[rows, cols, :] = 0.0
        jacobian[rows, cols, args + cols] = 1.0
        return residual, jacobian

    def _hold_left_limits(self, residual: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`residual` (N, p) with λ_k − λ_{k−1} at the held left-limit entries (:meth:`left_limits`),
        in place; returns those entries' (points, columns)."""
        left, held = self.left_limits(lam)
        points, cols = np.nonzero(held)
        rows = left[points]
        residual[rows, cols] = lam[rows, cols] - lam[rows - 1, cols]
        return rows, cols

    def left_limits(self, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The left-limit selections: the mesh points on a switch time (:attr:`Grid.left_limits`)
        and, (L, p), the columns there whose selection at the point before is at an end of its
        set (|λ| = 1: the interval ends off that surface). Such a selection is the point
        before's, λ_k = λ_{k−1}, in place of the natural map: a Filippov selection at a point
        on the switch is any of Sgn(0), and the one that keeps the interval's polynomial
        accurate is the regime the interval ends in (a crossing's or a stop's side before
        it). Columns on the surface before the point (sliding, sticking), and a vector sign's,
        keep the natural map."""
        left = self.grid.left_limits if self.layout.p else np.zeros(0, dtype=int)
        if not left.size:
            return left, np.zeros((0, self.layout.p), dtype=bool)
        held = np.abs(lam[left - 1]) >= 1.0 - SATURATED
        for first, width in self.layout.balls:  # a vector sign keeps its natural map (λ_k = λ_{k−1} at a curved
            held[:, first : first + width] = False  # stop left the isotropic puck unsolved)
        return left, held

    def _natural_map(self, y: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """σ's r = λ − P(λ + c·s(y)), (N, p): :meth:`selection_residual` without its Jacobian."""
        residual = lam - self.project(lam + self.selection_scale * self.switch_values(y, gradients=False)[0])
        if y.shape[0] == self.grid.nodes:
            self._hold_left_limits(residual, lam)
        return residual

    def project(self, values: np.ndarray) -> np.ndarray:
        """P of every selection's columns (N, p): the clip to [−1, 1], a vector sign's k columns
        projected onto the unit ball (w/max(1, |w|))."""
        out = np.clip(values, -1.0, 1.0)
        for first, width in self.layout.balls:
            block = values[:, first : first + width]
            out[:, first : first + width] = block / np.maximum(1.0, np.linalg.norm(block, axis=1))[:, None]
        return out

    def switch_values(self, y: np.ndarray, gradients: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """s (N, p) of every selection column (a vector sign's k components in its k columns) and,
        with `gradients`, ∇s (N, p, n + m), checked."""
        nodes, p, args = y.shape[0], self.layout.p, self.layout.args
        s = np.empty((nodes, p))
        ds = np.empty((nodes, p, args)) if gradients else None
        for group in self.layout.selection_groups:
            value, grad = self.pieces.switch(self.layout.blocks[group.block], group.term, y)
            s[:, group.columns] = value.reshape(nodes, group.width)
            if ds is not None:
                ds[:, group.columns] = grad.reshape(nodes, group.width, args)
        return s, ds

    def set_bounds(self, xi: np.ndarray) -> list[tuple[np.ndarray, np.ndarray] | None]:
        """For each one-coordinate block the interval [lo, hi] of F_b(x(t_k)); None for S_k blocks."""
        y, lam = self.layout.arguments(xi), self.layout.selections(xi)
        bounds: list[tuple[np.ndarray, np.ndarray] | None] = []
        for b, block in enumerate(self.layout.blocks):
            if block.size != 1:
                bounds.append(None)
                continue
            zero = np.zeros((y.shape[0], self.layout.n))
            selections = self.layout.block_selections(b, lam)
            plus, minus = self.pieces.sides_1d(block, y, zero, selections)  # ℓ(ψ) = −c(F, ψ) at z = 0
            bounds.append((minus.ell, -plus.ell))
        return bounds

    def end_residual(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """x_j(0) + ∫_0^T z_j − xT_j for j ∈ J, then ∫_0^T z_i (= x_i(T) − x_i(0)) for i ∈ P."""
        if not (self.end.size or self.periodic.size):
            return np.zeros(0)
        fixed = x[0, self.end] + self.grid.integral(z[:, self.end]) - self.end_values
        return np.concatenate([fixed, self.grid.integral(z[:, self.periodic])])

    def consistency(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """x_k − x(t_0) − ∫_0^{t_k} z (x(t_0) = x0 where given)."""
        return x - x[:1] - self.grid.cumulative(z)

    def surface_at(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """e(x) (N, o) and ∂e/∂x (N, o, n), checked; requires a surface."""
        e, de = self.surface.function(x)  # type: ignore[union-attr]
        self.pieces.check("surface", e, (x.shape[0], None))
        self.pieces.check("surface Jacobian", de, (x.shape[0], e.shape[1], self.layout.n))
        return e, de

    def cost_value(self, x: np.ndarray, y: np.ndarray, quadrature: bool = False) -> float:
        """𝒥 = Σ_k w_k c(y_k) (+ the terminal cost M(x(T))), the objective's; with `quadrature`,
        Σ_k b_k c(y_k), b the scheme's own rule for ∫z (`Grid.integral_weights`), what the user is
        given: w keeps a weight at t_0 (h/4 for Radau IIA, h/2 for implicit Euler) for the velocity
        in F(x_0), which the integral has not (on block-time-optimal ∫1 dt read 1.653 for T = 1.633).
        The two differ by w_0·c(y_0), which the solve cannot change where x(t_0) is given and u(t_0)
        enters nothing else."""
        weights = self.grid.integral_weights if quadrature else self.grid.weights
        value = float(np.sum(weights * self._cost_integrand(y)))
        if self.cost.terminal is not None:  # type: ignore[union-attr]
            value += float(self.cost.terminal(x[-1])[0])  # type: ignore[union-attr]
        return value

    def _cost_integrand(self, x: np.ndarray) -> np.ndarray:
        total = np.zeros(x.shape[0])
        for fn in self.cost.max_groups:  # type: ignore[union-attr]
            total += _reduce_last(np.maximum, self.pieces.scalar_pieces(fn, x, "cost max-group")[0])
        for fn in self.cost.min_groups:  # type: ignore[union-attr]
            total += _reduce_last(np.minimum, self.pieces.scalar_pieces(fn, x, "cost min-group")[0])
        return total


def _shifted_terms(self: Values, xi: np.ndarray) -> Terms:
    """:meth:`terms` with the augmented Lagrangian's shifts, every residual evaluated once."""
    x, z = self.layout.split(xi)
    y, lam = self.layout.arguments(xi), self.layout.selections(xi)
    shifts, r = self.shifts, self.constraint_residuals(x, y, z, lam)
    phi, omega, sigma = shifted_sums(r, shifts.cleared(), self.integral)  # no shift: ½r², ½max(0, ℓ)²
    chi, upsilon = 0.5 * float(np.sum(r.end**2)), 0.5 * self.integral(np.sum(r.consistency**2, axis=1))
    cost = self.cost_value(x, y) if self.cost is not None else 0.0
    eta = self.held.eta(xi) if self.held is not None else 0.0
    moved = shifted_sums(r, shifts, self.integral)
    shifted = sum(moved) + float(np.sum(equation_part(r.end, shifts.end))) + self.integral(
        np.sum(equation_part(r.consistency, shifts.consistency), axis=1)) + eta
    total = phi + chi + omega + upsilon + sigma + eta
    return Terms(phi, chi, omega, upsilon, sigma, cost, total, cost + self.penalty * shifted, eta)


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


def _ball_projection_jacobian(w: np.ndarray) -> np.ndarray:
    """One element of the generalized Jacobian of P_B(w) = w/max(1, |w|), (N, k, k): I where
    |w| ≤ 1, (I − ŵŵᵀ)/|w| where |w| > 1."""
    radius = np.linalg.norm(w, axis=1)
    outside = radius > 1.0
    identity = np.broadcast_to(np.eye(w.shape[1]), (w.shape[0], w.shape[1], w.shape[1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = w / radius[:, None]
        tangent = (identity - unit[:, :, None] * unit[:, None, :]) / radius[:, None, None]
    return np.where(outside[:, None, None], tangent, identity)
