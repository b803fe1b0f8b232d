"""`gauss-newton`: a semismooth Levenberg–Marquardt direction (beyond the paper).

I is half a sum of squares of residuals, each with a generalized Jacobian taken
from the active pieces (:meth:`Functional.distance_sides`):

    φ: √w_k · h_b(y_k, z_k)        υ: √w_k · (x_k − x0 − Z_k)
    χ: x0_j + Z_{N−1,j} − xT_j      ω: √w_k · e(x_k)
    σ: √w_k · (λ_k − clip(λ_k + c·s(y_k), −1, 1))   (the sign terms' selections)

σ's natural map is semismooth: its Jacobian element is that of the active branch of
the clip, so with the selections the step is a semismooth Newton step (LM-damped; with
μ → μ_min it is the exact Newton step where the system is square).

The cumulative integral Z = ∫_0^t z stays sparse: Z is an extra unknown per node tied
to z by the scheme's rule Z_p = Z_{base(p)} + Σ_j A_pj z_j (the trapezoid rule,
implicit Euler or Radau IIA: :class:`~qdframe.grid.Grid`), a banded equality
constraint, and x(t_0) = x0, Z_0 = 0 are constraints too. The step d minimizes

    λ/2·‖r + J d‖² + [cost model] + μ/2·Σ_k w_k ‖d_k‖²   subject to  E d = 0,

with μ adapted to the success of the previous step (ratio of actual to predicted
decrease). The distance residuals h_b = max(0, ℓ) are kept one-sided: each side of each
set enters as a squared hinge max(0, ℓ_side + ∇ℓ_side·d)², so a z on (or inside) the
boundary of F is neither ignored (the Jacobian element of h is 0 there) nor pulled onto
it; the model is exact for piecewise-linear sets. Without a cost the step is found by a
primal active-set iteration, a few sparse symmetric KKT solves (SuperLU). With a
nonsmooth cost (Example 7.1) the cost model is the max of the linearizations of all
pieces of each max-group — the δ-active ones and those that become active within the
step, so the model is exact for piecewise-linear costs such as |x1| — and the
linearized active piece of each min-group, and
the step is a sparse QP solved with Clarabel (the hinges as slacks s ≥ 0,
s ≥ ℓ_side + ∇ℓ_side·d).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from ..errors import BackendError
from .base import Direction, DirectionSolver
from .kkt import KKTSolver, solve_kkt

if TYPE_CHECKING:
    from ..functional import Functional


@dataclass
class GaussNewton(DirectionSolver):
    """Levenberg–Marquardt steps on the residuals behind I, in the L² metric.

    mu: the initial damping μ; mu_min/mu_max bound it. The solver keeps μ between
    iterations (`start` resets it for each solve): it shrinks by 10 after a full step
    that achieved more than 3/4 of the predicted decrease, doubles after one below 1/4,
    and grows by 2/γ when the line search cut the step to γ < 1/2.
    """

    name = "gauss-newton"
    default_line_search = "armijo"  # a Newton-type step: try γ = 1 first
    # a grid ladder 101, 301, 1001, … below N: semismooth Newton then finds each switch from
    # the coarser grid's, a few nodes off, instead of from the model's start
    default_continuation = "auto"
    coarsest_nodes = 101
    ladder_steps = (1, 3)  # 101, 301, 1001, 3001, …
    mu: float = 1e-10
    mu_min: float = 1e-12
    mu_max: float = 1e8
    _state: dict = field(default_factory=dict, repr=False)

    def compute(self, functional: "Functional", xi: np.ndarray, delta: float) -> Direction:
        value = functional.objective(xi)
        self._adapt(xi, value)
        system = _System(functional, xi, delta, self._state.setdefault("kkt", KKTSolver()))
        mu = self._state["mu"]
        step_ext, predicted, slope = system.solve(mu)
        step = system.unknowns_step(step_ext)
        self._state.update(previous_value=value, predicted=predicted, xi=xi, step=step)
        per_node = np.linalg.norm(step, axis=1)
        return Direction(step=step, deviation=per_node, slope=slope,
                         stationary=bool(predicted <= 1e-14 * max(value, 1e-300) or not np.any(per_node)))

    def start(self, functional: "Functional") -> None:
        self._state.clear()

    def _adapt(self, xi: np.ndarray, value: float) -> None:
        state = self._state
        if "step" not in state:  # the first iteration of a solve
            state["mu"] = self.mu
            return
        predicted = state["predicted"]
        ratio = (state["previous_value"] - value) / predicted if predicted > 0 else 0.0
        step = state["step"]
        norm2 = float(np.sum(step**2))
        gamma = float(np.sum((xi - state["xi"]) * step)) / norm2 if norm2 > 0 else 1.0
        if gamma < 0.5:  # the line search cut the step: the LM step scales like 1/μ
            state["mu"] = min(state["mu"] * 2.0 / max(gamma, 1e-6), self.mu_max)
        elif ratio > 0.75:
            state["mu"] = max(state["mu"] / 10.0, self.mu_min)
        elif ratio < 0.25:
            state["mu"] = min(state["mu"] * 2.0, self.mu_max)


QP_TOL = 1e-12  # Clarabel's gap and feasibility tolerances for the step QP
QP_RETRY_TOL = 1e-10  # the second try after InsufficientProgress at QP_TOL


class _System:
    """The linearized problem at ξ in the extended unknowns [x | z | u | Z] per node."""

    def __init__(self, functional: "Functional", xi: np.ndarray, delta: float,
                 kkt: KKTSolver | None = None) -> None:
        self.f = functional
        self.kkt = kkt or KKTSolver()  # the solve's KKT factorizer: its symbolic analysis is reused
        n, m = functional.n, functional.m + functional.p  # u and the selections λ: both enter y
        nodes = functional.grid.nodes
        self.n, self.m, self.nodes = n, m, nodes
        self.width = 3 * n + m  # per node: x, z, u, λ, Z
        self.size = nodes * self.width
        self.delta = delta
        self.penalty = functional.penalty
        self.value = functional.objective(xi)
        blocks = functional.distance_sides(xi)
        self.equations = [block for block in blocks if block.equation]  # z_b = f_b(y): least squares
        self.sides = [block for block in blocks if not block.equation]  # sets: one-sided hinges
        self.residual, self.jacobian = self._least_squares(xi)
        self.constraints = self._constraints()
        self.cost = functional.cost_pieces(xi) if functional.cost is not None else None

    # column indices of each variable at every node: (N, width)
    def _columns(self, start: int, count: int) -> np.ndarray:
        base = np.arange(self.nodes)[:, None] * self.width
        return base + start + np.arange(count)[None, :]

    def x_cols(self) -> np.ndarray:
        return self._columns(0, self.n)

    def z_cols(self) -> np.ndarray:
        return self._columns(self.n, self.n)

    def u_cols(self) -> np.ndarray:
        return self._columns(2 * self.n, self.m)

    def Z_cols(self) -> np.ndarray:
        return self._columns(2 * self.n + self.m, self.n)

    def y_cols(self) -> np.ndarray:
        return np.concatenate([self.x_cols(), self.u_cols()], axis=1)

    def _least_squares(self, xi: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        f, nodes = self.f, self.nodes
        root_w = np.sqrt(f.weights)
        rows, cols, vals, residuals = [], [], [], []
        count = 0

        def add(res: np.ndarray, col: np.ndarray, val: np.ndarray) -> None:
            """res: (R,), col/val: (R, E) entries of R new rows."""
            nonlocal count
            index = count + np.arange(res.size)
            rows.append(np.repeat(index, col.shape[1]))
            cols.append(col.ravel())
            vals.append(val.ravel())
            residuals.append(res)
            count += res.size

        consistency = f.consistency(xi)  # υ, one row per node and state: x_k − x_0 − Z_k
        x_cols, Z_cols = self.x_cols(), self.Z_cols()
        start_free = np.tile(~f.start_given, nodes)  # −√w_k on a free x_i(0) (0 where it is given)
        add((root_w[:, None] * consistency).ravel(),
            np.stack([x_cols.ravel(), Z_cols.ravel(), np.tile(x_cols[0], nodes)], axis=1),
            np.stack([np.repeat(root_w, self.n), -np.repeat(root_w, self.n), -np.repeat(root_w, self.n) * start_free],
                     axis=1))
        end = f.end_residual(xi)  # χ: x_j(0) + Z_{N−1,j} − xT_j (j ∈ J), then Z_{N−1,i} (i ∈ P)
        if end.size:
            coords = np.concatenate([f.end, f.periodic])
            starts = np.concatenate([~f.start_given[f.end], np.zeros(f.periodic.size, dtype=bool)])
            add(end, np.stack([Z_cols[-1, coords], x_cols[0, coords]], axis=1),
                np.stack([np.ones(end.size), starts.astype(float)], axis=1))
        if f.surface is not None:  # ω
            e, de = f.surface_values(xi)
            o = e.shape[1]
            add((root_w[:, None] * e).ravel(),
                np.repeat(x_cols[:, None, :], o, axis=1).reshape(nodes * o, self.n),
                (root_w[:, None, None] * de).reshape(nodes * o, self.n))
        y_cols, z_cols = self.y_cols(), self.z_cols()
        for block in self.equations:  # φ of a point set: √w·(z_b − f_b(y)), a plain residual
            (ell, dell_dy, psi), = block.sides
            add(root_w * ell, np.concatenate([y_cols, z_cols[:, list(block.coords)]], axis=1),
                root_w[:, None] * np.concatenate([dell_dy, psi], axis=1))
        if f.p:  # σ: the selections' natural map
            r, dr = f.selection_residual(xi)
            add((root_w[:, None] * r).ravel(),
                np.repeat(y_cols[:, None, :], f.p, axis=1).reshape(nodes * f.p, -1),
                (root_w[:, None, None] * dr).reshape(nodes * f.p, -1))
        jacobian = sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(count, self.size)
        )
        return np.concatenate(residuals), jacobian

    def _constraints(self) -> sp.csr_matrix:
        """E d = 0: dx_0 = 0 where x(t_0) is given, dZ_0 = 0, dz_i = dx_j for resolved states,
        dZ_p − dZ_{base(p)} − Σ_j A_pj dz_j = 0 (the scheme's rule)."""
        n = self.n
        x_cols, z_cols, Z_cols = self.x_cols(), self.z_cols(), self.Z_cols()
        fixed = np.concatenate([x_cols[0, self.f.start_given], Z_cols[0]])
        rows = [np.arange(fixed.size)]
        cols = [fixed]
        vals = [np.ones(fixed.size)]
        count = fixed.size
        for i, j in self.f.resolved.items():  # dz_i = dx_j at every node
            tie = count + np.arange(self.nodes)
            rows += [tie, tie]
            cols += [z_cols[:, i], x_cols[:, j]]
            vals += [np.ones(self.nodes), -np.ones(self.nodes)]
            count += self.nodes
        points, base, increments = self.f.grid.recursion()
        recursion = count + np.arange(points.size * n).reshape(points.size, n)  # one row per point p ≥ 1 and state
        for col, val in ((Z_cols[points], 1.0), (Z_cols[base], -1.0)):
            rows.append(recursion.ravel())
            cols.append(col.ravel())
            vals.append(np.full(recursion.size, val))
        coo = increments.tocoo()  # −A_pj dz_j, row p − 1 of the restricted A
        rows.append(recursion[coo.row].ravel())
        cols.append(z_cols[coo.col].ravel())
        vals.append(np.repeat(-coo.data, n))
        return sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(count + recursion.size, self.size),
        )

    def _damping(self) -> np.ndarray:
        """L² weights w_k on x, z, u (none on Z, which the constraints determine)."""
        weights = np.zeros((self.nodes, self.width))
        weights[:, : 2 * self.n + self.m] = self.f.weights[:, None]
        return weights.ravel()

    def _hinges(self) -> tuple[sp.csr_matrix, np.ndarray]:
        """The one-sided residuals of φ: rows √w_k·(ℓ_side + ∇ℓ_side·d) for every block,
        side and node (h_b = max(0, max_side ℓ)), as a matrix and the values √w_k·ℓ."""
        root_w = np.sqrt(self.f.weights)
        y_cols, z_cols = self.y_cols(), self.z_cols()
        rows, cols, vals, values = [], [], [], []
        count = 0
        for block in self.sides:
            block_cols = np.concatenate([y_cols, z_cols[:, list(block.coords)]], axis=1)
            for ell, dell_dy, psi in block.sides:
                coefficients = root_w[:, None] * np.concatenate([dell_dy, psi], axis=1)
                rows.append(np.repeat(count + np.arange(self.nodes), block_cols.shape[1]))
                cols.append(block_cols.ravel())
                vals.append(coefficients.ravel())
                values.append(root_w * ell)
                count += self.nodes
        if not count:
            return sp.csr_matrix((0, self.size)), np.zeros(0)
        matrix = sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(count, self.size)
        )
        return matrix, np.concatenate(values)

    def solve(self, mu: float) -> tuple[np.ndarray, float, float]:
        """The step (extended), the predicted decrease of the objective, and its slope."""
        J, r, lam = self.jacobian, self.residual, self.penalty
        hessian = (lam * (J.T @ J) + mu * sp.diags(self._damping())).tocsc()
        gradient = lam * (J.T @ r)
        if self.cost is None:
            step = self._solve_hinged(hessian, gradient)
            if step is not None:
                return step
        return self._solve_cost_qp(hessian, gradient)

    def _solve_hinged(self, hessian: sp.csc_matrix, gradient: np.ndarray) -> tuple[np.ndarray, float, float] | None:
        """min ½dᵀHd + gᵀd + (λ/2)·Σ max(0, v + A d)² s.t. E d = 0, by a primal active-set
        (semismooth Newton) iteration: one sparse KKT solve per guess of the violated
        sides, until the guess repeats. None if it does not settle (the QP takes over)."""
        lam = self.penalty
        matrix, values = self._hinges()
        active = values > 0
        for _ in range(30):
            A = matrix[active]
            d = self._solve_kkt((hessian + lam * (A.T @ A)).tocsc(), gradient + lam * (A.T @ values[active]))
            predicted_sides = values + matrix @ d
            settled = predicted_sides > 0
            if np.array_equal(settled, active):
                break
            active = settled
        else:
            return None
        J = self.jacobian
        model = 0.5 * lam * (np.sum((self.residual + J @ d) ** 2) + np.sum(np.maximum(predicted_sides, 0.0) ** 2))
        slope = float(gradient @ d) + lam * float(np.maximum(values, 0.0) @ (matrix @ d))
        return d, float(self.value - model), slope

    def _solve_kkt(self, hessian: sp.csc_matrix, gradient: np.ndarray) -> np.ndarray:
        return solve_kkt(hessian, self.constraints, gradient, solver=self.kkt)[0]

    def _solve_cost_qp(self, hessian: sp.csc_matrix, gradient: np.ndarray) -> tuple[np.ndarray, float, float]:
        """The step as a sparse QP in [d | t | s] (Clarabel):

        min ½dᵀHd + gᵀd + Σ_k w_k t_k + (λ/2)·Σ w_k s_bk² + Σ_k w_k ∇b_p*·d_k
        s.t. E d = 0;  a_q + ∇a_q·d_k ≤ t_k (every piece q of each cost max-group);
             ℓ_side + ∇ℓ_side·d_k ≤ s_bk and 0 ≤ s_bk (every side of every block).
        """
        import clarabel

        nodes, w, lam = self.nodes, self.f.weights, self.penalty
        y_cols, z_cols = self.y_cols(), self.z_cols()
        max_groups, min_groups = self.cost if self.cost is not None else ([], [])
        min_linear = np.zeros(self.size)
        for values, grads in min_groups:  # concave: linearize the active piece
            pick = grads[np.arange(nodes), np.argmin(values, axis=1)]
            np.add.at(min_linear, y_cols.ravel(), (w[:, None] * pick).ravel())
        n_t, n_s = nodes * len(max_groups), nodes * len(self.sides)
        t0, s0 = self.size, self.size + n_t
        total = s0 + n_s
        rows, cols, vals, rhs = [], [], [], []
        count = 0

        def inequality(col: np.ndarray, val: np.ndarray, bound: np.ndarray) -> None:
            """Rows col/val (R, E) with Σ val·v ≤ bound (R,)."""
            nonlocal count
            rows.append(np.repeat(count + np.arange(bound.size), col.shape[1]))
            cols.append(col.ravel())
            vals.append(val.ravel())
            rhs.append(bound)
            count += bound.size

        for g, (values, grads) in enumerate(max_groups):  # the max of every piece's linearization
            node, piece = np.nonzero(np.ones_like(values, dtype=bool))
            inequality(np.concatenate([y_cols[node], (t0 + g * nodes + node)[:, None]], axis=1),
                       np.concatenate([grads[node, piece], -np.ones((node.size, 1))], axis=1),
                       -values[node, piece])
        for b, block in enumerate(self.sides):
            s_cols = (s0 + b * nodes + np.arange(nodes))[:, None]
            for ell, dell_dy, psi in block.sides:
                inequality(np.concatenate([y_cols, z_cols[:, list(block.coords)], s_cols], axis=1),
                           np.concatenate([dell_dy, psi, -np.ones((nodes, 1))], axis=1), -ell)
            inequality(s_cols, -np.ones((nodes, 1)), np.zeros(nodes))
        slack_weights = lam * np.tile(w, len(self.sides))
        P = sp.block_diag([hessian, sp.csc_matrix((n_t, n_t)), sp.diags(slack_weights)], format="csc")
        q = np.concatenate([gradient + min_linear, np.tile(w, len(max_groups)), np.zeros(n_s)])
        E = self.constraints
        A = sp.vstack([
            sp.hstack([E, sp.csr_matrix((E.shape[0], total - self.size))]),
            sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(count, total)),
        ], format="csc")
        b_vec = np.concatenate([np.zeros(E.shape[0])] + rhs)
        scale = 1.0 / max(self.value, 1e-6)  # the QP objective near O(1): Clarabel's gap tolerances are absolute

        def clarabel_solve(tol: float):
            settings = clarabel.DefaultSettings()
            settings.verbose = False
            for name in ("tol_gap_abs", "tol_gap_rel", "tol_feas"):
                setattr(settings, name, tol)
            return clarabel.DefaultSolver(
                sp.triu(scale * P, format="csc"), scale * q, A, b_vec,
                [clarabel.ZeroConeT(E.shape[0]), clarabel.NonnegativeConeT(count)], settings,
            ).solve()

        solution = clarabel_solve(QP_TOL)
        if str(solution.status) == "InsufficientProgress":
            # near a solution (objective ~1e-15) 1e-12 can be below Clarabel's reach; whether it then
            # stalls depends on rounding-level details of ξ: try once more at QP_RETRY_TOL (the line
            # search checks the step's actual decrease)
            solution = clarabel_solve(QP_RETRY_TOL)
            if str(solution.status) not in ("Solved", "AlmostSolved"):  # at Clarabel's precision: no further step
                return np.zeros(self.size), 0.0, 0.0
        if str(solution.status) not in ("Solved", "AlmostSolved"):
            raise BackendError(f"direction 'gauss-newton': the step QP (Clarabel) ended with status {solution.status}")
        v = np.asarray(solution.x)
        d, t, slack = v[: self.size], v[t0:s0], v[s0:]
        J = self.jacobian
        model = (
            0.5 * lam * np.sum((self.residual + J @ d) ** 2)
            + 0.5 * float(slack_weights @ slack**2)
            + float(np.tile(w, len(max_groups)) @ t)
            + float(min_linear @ d)
            + sum(float(w @ values.min(axis=1)) for values, _ in min_groups)
        )
        # slope of the objective along d (the cost's and φ's one-sided derivatives)
        dy = d[y_cols]
        slope = float(gradient @ d + min_linear @ d)
        for values, grads in max_groups:
            active = values >= values.max(axis=1, keepdims=True) - self.delta
            slope += float(w @ np.max(np.where(active, np.einsum("kqp,kp->kq", grads, dy), -np.inf), axis=1))
        for block in self.sides:
            h = block.h
            ells = np.array([side[0] for side in block.sides])
            dz = d[z_cols[:, list(block.coords)]]
            rates = np.array([np.einsum("kp,kp->k", dy_, dy) + np.einsum("kc,kc->k", psi, dz)
                              for _, dy_, psi in block.sides])
            rate = np.max(np.where(ells >= h[None, :] - 1e-14, rates, -np.inf), axis=0)
            slope += lam * float(w @ np.where(h > 0, h * np.where(np.isfinite(rate), rate, 0.0), 0.0))
        return d, float(self.value - model), slope

    def unknowns_step(self, step: np.ndarray) -> np.ndarray:
        """The step on ξ = [x | z | u] per node (dropping Z)."""
        return step.reshape(self.nodes, self.width)[:, : 2 * self.n + self.m].copy()
