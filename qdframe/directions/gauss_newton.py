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
it; the model is exact for piecewise-linear sets. A nonsmooth cost (Example 7.1) enters
as the max of the linearizations of all pieces of each max-group, so the model is exact
for piecewise-linear costs such as |x1|, and the linearized active piece of each
min-group.

The step minimizes that model (a convex QP) by a primal-dual active-set iteration: a
guess of the violated sides and of the pieces tied at each node's maximum, one sparse
KKT solve (:mod:`.kkt`) per guess, until the guess agrees with its own step to within
ACTIVE_SET_TOL of the predicted decrease. The first guess is the set the previous step
settled on, so near a solution one solve per step is the rule. Where the iteration does
not settle, Clarabel solves the same model as a QP (the hinges and the max-pieces as
inequalities), and its active set becomes the next step's first guess. The option
``qp`` names another backend of that QP (:mod:`.step_qp`: clarabel, osqp, cvxpy,
qpsolvers:NAME), which then solves every step; its solution is polished by the
active-set iteration from the active set it points to (``qp_polish``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from ..errors import BackendError, QdframeError
from .base import Direction, DirectionSolver, OptionError, number_rule
from .kkt import KKTSolver, solve_kkt
from .sparse_rows import RowBlocks
from .step_qp import (KKT_TOL, ActiveSetStep, SparseQP, StepQPSolver, StepSolution, make_step_qp,
                      step_qp_expected)

if TYPE_CHECKING:
    from ..functional import Functional


@dataclass
class GaussNewton(DirectionSolver):
    """Levenberg–Marquardt steps on the residuals behind I, in the L² metric.

    mu: the initial damping μ; mu_min/mu_max bound it. The solver keeps μ between
    iterations (`start` resets it for each solve): it shrinks by 10 after a full step
    that achieved more than 3/4 of the predicted decrease, doubles after one below 1/4,
    and grows by 2/γ when the line search cut the step to γ < 1/2.

    qp: the step QP's backend, by name (`qdframe list`, step_qps: "active-set", the default,
    or a general QP solver, :mod:`.step_qp`) or as a :class:`~.step_qp.StepQPSolver` instance;
    qp_polish: polish a general backend's step by the active-set iteration from the active
    set it points to (exact where it settles). `label` names a backend other than the
    default: "gauss-newton[qp=osqp]" (the result's `direction`).
    """

    name = "gauss-newton"
    default_line_search = "armijo"  # a Newton-type step: try γ = 1 first
    # a grid ladder 101, 301, 1001, … below N: semismooth Newton then finds each switch from
    # the coarser grid's, a few nodes off, instead of from the model's start
    default_continuation = "auto"
    coarsest_nodes = 101
    ladder_steps = (1, 3)  # 101, 301, 1001, 3001, …
    full_steps = True  # a Levenberg–Marquardt step
    mu: float = 1e-10
    mu_min: float = 1e-12
    mu_max: float = 1e8
    qp: str | StepQPSolver = ActiveSetStep.name
    qp_polish: bool = True
    _state: dict = field(default_factory=dict, repr=False)
    option_rules = {name: number_rule(above=0.0, why="a damping") for name in ("mu", "mu_min", "mu_max")}

    def __post_init__(self) -> None:
        self.check_options()

    def check_options(self) -> None:
        super().check_options()
        if self.mu_min > self.mu_max:
            raise OptionError(type(self).__name__, "mu_max", f"a number ≥ mu_min = {self.mu_min:g}", self.mu_max)
        if not self.mu_min <= self.mu <= self.mu_max:
            raise OptionError(type(self).__name__, "mu", f"a number in [mu_min, mu_max] = [{self.mu_min:g}, "
                                                         f"{self.mu_max:g}]", self.mu)
        if not isinstance(self.qp_polish, bool):
            raise OptionError(type(self).__name__, "qp_polish", "True or False", self.qp_polish)
        if isinstance(self.qp, StepQPSolver):  # an instance: a backend of one's own, registered or not
            self._state["backend"] = self.qp
            return
        try:
            self._state["backend"] = make_step_qp(str(self.qp))
        except QdframeError:
            raise OptionError(type(self).__name__, "qp", step_qp_expected(str(self.qp)), self.qp) from None

    @property
    def label(self) -> str:
        backend = self._state.get("backend")
        name = getattr(backend, "label", None) or getattr(self.qp, "label", str(self.qp))
        options = ([] if name == ActiveSetStep.name else [f"qp={name}"]) + ([] if self.qp_polish else ["qp_polish=false"])
        return self.name + (f"[{','.join(options)}]" if options else "")

    def compute(self, functional: "Functional", xi: np.ndarray, delta: float) -> Direction:
        value = functional.objective(xi)
        self._adapt(xi, value)
        system = _System(functional, xi, delta, self._state.setdefault("kkt", KKTSolver()))
        mu = self._state["mu"]
        step_ext, predicted, slope = system.solve(mu, warm=self._state.get("active_set"), backend=self._state["backend"],
                                                  polish=self.qp_polish, previous=self._state.get("qp_solution"))
        step = system.unknowns_step(step_ext)
        self._state.update(previous_value=value, predicted=predicted, xi=xi, step=step, active_set=system.settled,
                           qp_solution=system.qp_solution)
        per_node = np.linalg.norm(step, axis=1)
        return Direction(step=step, deviation=per_node, slope=slope,
                         stationary=bool(predicted <= 1e-14 * max(value, 1e-300) or not np.any(per_node)))

    def start(self, functional: "Functional") -> None:
        self._state = {"backend": self._state["backend"]}  # made by check_options

    @property
    def factorizations(self) -> int:
        """KKT factorizations since the solve began (one per guess of the active-set iteration)."""
        kkt = self._state.get("kkt")
        return kkt.factorizations if kkt is not None else 0

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


MAX_GUESSES = 30  # KKT solves of the active-set iteration before Clarabel takes over
ACTIVE_SET_TOL = 1e-3  # violations a guess leaves out may change its model by this × the predicted decrease
ROUNDING = 1e-12  # a side or piece within this × the largest predicted value of its kind counts as either state
THETA_TOL = 1e-9  # a tie weight θ above −this counts as ≥ 0
TIE_SOFTNESS = 1e-14  # ε of the tie rows (kkt.solve_kkt's soft): a tie on a fixed x_i(0) repeats a row of E
IDENTIFY_TOL = 1e-7  # what counts as violated or tied in the QP's step (an interior point's precision)


@dataclass(frozen=True)
class ActiveSet:
    """What a step's active-set iteration settled on: the hinge sides taken as violated
    (one flag per row of :meth:`_System._hinges`) and, per cost max-group, the pieces tied
    at the maximum at each node ((N, m) flags). The next step starts from it."""

    sides: np.ndarray
    ties: list[np.ndarray]

    def fits(self, values: np.ndarray, max_groups: list) -> bool:
        return self.sides.shape == values.shape and len(self.ties) == len(max_groups) and all(
            tie.shape == piece_values.shape for tie, (piece_values, _) in zip(self.ties, max_groups))


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
        self.sides = [block for block in blocks if not block.equation]  # sets: one-sided hinges
        # z_b = f_b(y): least squares, their sides not kept past J (at N = 1e5 on 7.3, 46 MB)
        self.residual, self.jacobian = self._least_squares(xi, [block for block in blocks if block.equation])
        del blocks
        self.constraints = self._constraints()
        self.cost = functional.cost_pieces(xi) if functional.cost is not None else None
        self.columns = self._constant_columns()
        self.R = None if self.columns is None else self._reduction()
        self._hinge_rows: tuple[sp.csr_matrix, np.ndarray] | None = None  # :meth:`_hinges`

    def _constant_columns(self) -> np.ndarray | None:
        """Where each column of the extended unknowns goes in the KKT systems: a constant state
        (the model's `constant_states`, x_i' = 0: an unknown T or parameter) is one unknown
        x_i(t_0) for every node, its z_i and Z_i none (−1); None without constant states."""
        constant = [i for i in self.f.model.constant_states if i not in self.f.resolved]
        if not constant:
            return None
        target = np.arange(self.size)
        x_cols, z_cols, Z_cols = self.x_cols(), self.z_cols(), self.Z_cols()
        target[x_cols[:, constant]] = x_cols[0, constant]
        target[z_cols[:, constant]] = -1
        target[Z_cols[:, constant]] = -1
        own = target == np.arange(self.size)  # the columns that stay, in order
        index = np.cumsum(own) - 1
        return np.where(target >= 0, index[np.maximum(target, 0)], -1)

    def _reduction(self) -> sp.csr_matrix:
        """R (size × reduced): d = R·d_r, a constant state's x_i(t_k) all the column of x_i(t_0)."""
        kept = self.columns >= 0
        return sp.csr_matrix((np.ones(int(kept.sum())), (np.flatnonzero(kept), self.columns[kept])),
                             shape=(self.size, int(self.columns.max()) + 1))

    def _reduced(self, matrix: sp.spmatrix) -> tuple[sp.csr_matrix, np.ndarray]:
        """matrix · R (R: the columns' map of :meth:`_constant_columns`), explicit zeros kept, and
        which rows lost every entry they had (a constant state's own recursion rows)."""
        matrix = sp.csr_matrix(matrix)
        rows = matrix.shape[0]
        row_of = np.repeat(np.arange(rows), np.diff(matrix.indptr))
        target = self.columns[matrix.indices]
        keep = target >= 0
        reduced = sp.csr_matrix((matrix.data[keep], (row_of[keep], target[keep])),
                                shape=(rows, int(self.columns.max()) + 1))
        emptied = (np.diff(matrix.indptr) > 0) & (np.bincount(row_of[keep], minlength=rows) == 0)
        return reduced, emptied

    def _solve_kkt(self, H: sp.spmatrix, C: sp.spmatrix, g: np.ndarray, rhs: np.ndarray,
                   soft: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d and ν of the KKT system. With constant states H and g are on the reduced columns
        (:meth:`_reduction`), C on all: C is reduced here, and d comes back on every column (a
        constant state's x_i the same at every node, its z_i and Z_i 0)."""
        if self.R is None:
            return solve_kkt(H, C, g, rhs, soft, solver=self.kkt)
        Cr, emptied = self._reduced(C)
        live = ~emptied
        d, nu = solve_kkt(H, Cr[live], g, rhs[live], soft[live], solver=self.kkt)
        multipliers = np.zeros(C.shape[0])
        multipliers[live] = nu
        return self.R @ d, multipliers

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

    def _least_squares(self, xi: np.ndarray, equations: list) -> tuple[np.ndarray, sp.csr_matrix]:
        """The residuals r and J (one generalized-Jacobian element) of υ, χ, ω, the point
        sets' φ (`equations`) and σ, row blocks in that order."""
        f, nodes = self.f, self.nodes
        root_w = np.sqrt(f.weights)
        rows = RowBlocks(self.size)  # J, its exactly-zero entries left out (:mod:`.sparse_rows`)
        residuals = []

        def add(res: np.ndarray, col: np.ndarray, val: np.ndarray) -> None:
            """res: (R,), col/val: (R, E) entries of R new rows."""
            rows.add(col, val)
            residuals.append(res)

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
        for block in equations:  # φ of a point set: √w·(z_b − f_b(y)), a plain residual
            (ell, dell_dy, psi), = block.sides
            add(root_w * ell, np.concatenate([y_cols, z_cols[:, list(block.coords)]], axis=1),
                root_w[:, None] * np.concatenate([dell_dy, psi], axis=1))
        if f.p:  # σ: the selections' natural map
            r, dr = f.selection_residual(xi)
            cols = np.repeat(y_cols[:, None, :], f.p, axis=1)  # (N, p, width)
            vals = root_w[:, None, None] * dr
            left, held = f.left_limits(f.selections(xi))  # r_k = λ_k − λ_{k−1}: a −1 on λ_{k−1}
            if left.size:
                lam_cols = self.u_cols()[:, f.m :]  # (N, p)
                extra_cols = lam_cols.copy()[:, :, None]  # elsewhere a zero on the row's own λ (left out)
                extra_vals = np.zeros((nodes, f.p, 1))
                extra_cols[left, :, 0] = lam_cols[left - 1]
                extra_vals[left, :, 0] = np.where(held, -root_w[left, None], 0.0)
                cols = np.concatenate([cols, extra_cols], axis=2)
                vals = np.concatenate([vals, extra_vals], axis=2)
            add((root_w[:, None] * r).ravel(), cols.reshape(nodes * f.p, -1), vals.reshape(nodes * f.p, -1))
        return np.concatenate(residuals), rows.matrix()

    def _constraints(self) -> sp.csr_matrix:
        """E d = 0: dx_0 = 0 where x(t_0) is given, dZ_0 = 0, dz_i = dx_j for resolved states,
        dZ_p − dZ_{base(p)} − Σ_j A_pj dz_j = 0 (the scheme's rule)."""
        n = self.n
        x_cols, z_cols, Z_cols = self.x_cols(), self.z_cols(), self.Z_cols()
        rows = RowBlocks(self.size)
        fixed = np.concatenate([x_cols[0, self.f.start_given], Z_cols[0]])
        rows.add(fixed[:, None], np.ones((fixed.size, 1)))
        for i, j in self.f.resolved.items():  # dz_i = dx_j at every node
            rows.add(np.stack([z_cols[:, i], x_cols[:, j]], axis=1),
                     np.broadcast_to([1.0, -1.0], (self.nodes, 2)))
        points, base, increments = self.f.grid.recursion()
        # one row per point p ≥ 1 and state: dZ_p − dZ_{base(p)} − Σ_j A_pj dz_j, the row p − 1 of the
        # restricted A padded with zeros to its longest row (a zero entry is left out)
        increments = sp.csr_matrix(increments)
        counts = np.diff(increments.indptr)
        width = int(counts.max(initial=0))
        place = np.arange(increments.nnz) - np.repeat(increments.indptr[:-1], counts)
        terms = np.zeros((points.size, width), dtype=increments.indices.dtype)
        weights = np.zeros((points.size, width))
        row_of = np.repeat(np.arange(points.size), counts)
        terms[row_of, place] = increments.indices
        weights[row_of, place] = -increments.data
        cols = np.concatenate([Z_cols[points][:, :, None], Z_cols[base][:, :, None],
                               np.moveaxis(z_cols[terms], 1, 2)], axis=2)  # (points, n, 2 + width)
        vals = np.concatenate([np.ones((points.size, 1)), -np.ones((points.size, 1)), weights], axis=1)
        rows.add(cols.reshape(points.size * n, 2 + width),
                 np.repeat(vals, n, axis=0))
        return rows.matrix()

    def _damping(self) -> np.ndarray:
        """L² weights w_k on x, z, u (none on Z, which the constraints determine)."""
        weights = np.zeros((self.nodes, self.width))
        weights[:, : 2 * self.n + self.m] = self.f.weights[:, None]
        return weights.ravel()

    def _hinges(self) -> tuple[sp.csr_matrix, np.ndarray]:
        """The one-sided residuals of φ: rows √w_k·(ℓ_side + ∇ℓ_side·d) for every block,
        side and node (h_b = max(0, max_side ℓ)), as a matrix and the values √w_k·ℓ (built
        once per step: the active-set iteration, the QP and its polish all read them)."""
        if self._hinge_rows is None:
            self._hinge_rows = self._assemble_hinges()
        return self._hinge_rows

    def _assemble_hinges(self) -> tuple[sp.csr_matrix, np.ndarray]:
        root_w = np.sqrt(self.f.weights)
        y_cols, z_cols = self.y_cols(), self.z_cols()
        rows = RowBlocks(self.size)  # exactly-zero coefficients left out (:mod:`.sparse_rows`)
        values = []
        for block in self.sides:
            block_cols = np.concatenate([y_cols, z_cols[:, list(block.coords)]], axis=1)
            for ell, dell_dy, psi in block.sides:
                rows.add(block_cols, root_w[:, None] * np.concatenate([dell_dy, psi], axis=1))
                values.append(root_w * ell)
        if not rows.rows:
            return sp.csr_matrix((0, self.size)), np.zeros(0)
        return rows.matrix(), np.concatenate(values)

    def solve(self, mu: float, warm: "ActiveSet | None" = None, backend: StepQPSolver | None = None,
              polish: bool = True, previous: StepSolution | None = None) -> tuple[np.ndarray, float, float]:
        """The step (extended), the predicted decrease of the objective, and its slope.

        warm: the active set the previous step settled on (same grid), the first guess of
        this one; the set this step settles on is left in `self.settled`. backend: the
        step-QP backend (:mod:`.step_qp`; None or ``active-set``: the active-set iteration,
        Clarabel where it does not settle); `previous` its last solution (a warm start),
        this step's in `self.qp_solution`."""
        J, r, lam = self.jacobian, self.residual, self.penalty
        gradient = lam * (J.T @ r)
        self.settled, self.qp_solution = None, None
        cache: dict[bool, sp.csc_matrix] = {}

        def hessian(reduced: bool) -> sp.csc_matrix:
            """λJᵀJ + μW, on the constant states' reduced columns (R) if `reduced`; the
            active-set systems' H (reduced where there are constant states) is the QP's too."""
            reduced = reduced and self.R is not None
            if reduced not in cache:
                JR, damping = ((J @ self.R).tocsr(), self.R.T @ self._damping()) if reduced else (J, self._damping())
                cache[reduced] = (lam * (JR.T @ JR) + mu * sp.diags(damping)).tocsc()
            return cache[reduced]

        backend = backend if backend is not None else make_step_qp(ActiveSetStep.name)
        if backend.structured:
            step = self._solve_active_set(hessian(True), gradient, warm)
            if step is not None:
                return step
        return self._solve_qp(hessian, gradient, backend, polish, previous)

    def _cold_start(self, values: np.ndarray) -> "ActiveSet":
        """The first guess without a previous step: the sides violated now, and each cost
        max-group's largest piece at every node."""
        max_groups = self.cost[0] if self.cost is not None else []
        ties = []
        for piece_values, _ in max_groups:
            tie = np.zeros(piece_values.shape, dtype=bool)
            tie[np.arange(self.nodes), np.argmax(piece_values, axis=1)] = True
            ties.append(tie)
        return ActiveSet(values > 0, ties)

    def _solve_active_set(self, hessian: sp.csc_matrix, gradient: np.ndarray,
                          warm: "ActiveSet | None") -> tuple[np.ndarray, float, float] | None:
        """The step model (the QP of :meth:`_step_qp`) minimized by a primal-dual
        active-set (semismooth Newton) iteration, one sparse KKT solve per guess.

        A guess has two parts. Hinges: the sides taken as violated, each adding
        (λ/2)·(v + A d)² to the model (h_b² = Σ_side max(0, ℓ_side)²; a block has at most one
        violated side unless its set is empty). Cost: per node and max-group the set S of
        pieces tied at the maximum; a reference piece q₀ ∈ S adds w_k ∇a_q₀·d and the others
        the ties (∇a_q − ∇a_q₀)·d_k = a_q₀ − a_q as constraint rows, whose multipliers ν give
        the subgradient's weights θ_q = ν_q / w_k, θ_q₀ = 1 − Σ θ_q.

        A guess is accepted when its own step agrees with it where that matters: no side it
        takes as violated is predicted satisfied (beyond ROUNDING) — that would pull z onto
        the boundary of F, which the one-sided hinge exists to avoid — and every θ ≥ −THETA_TOL;
        the violations it leaves out and the pieces above the tie may change the model by at
        most ACTIVE_SET_TOL × its predicted decrease (they under-count, and the next step sees
        them). With both parts exact the step is the model's minimizer (KKT; the model is
        convex). Otherwise the sides are re-chosen by their predicted sign, pieces with θ < 0
        leave S and pieces above the tie join it. Why not exact everywhere: on 7.1 (the
        solution on the kink of |x1| and z1 on a side of F at every node) the guesses
        otherwise chatter, one side per guess, for 30 guesses.

        None if no guess is accepted in MAX_GUESSES solves, or a tie system is singular (a
        general QP backend takes over: :meth:`_solve_qp`)."""
        lam, w = self.penalty, self.f.weights
        matrix, values = self._hinges()
        max_groups, min_groups = self.cost if self.cost is not None else ([], [])
        min_linear = self._min_linear(min_groups)
        guess = warm if warm is not None and warm.fits(values, max_groups) else self._cold_start(values)
        active, ties = guess.sides, [tie.copy() for tie in guess.ties]
        y_cols = self.y_cols()
        for _ in range(MAX_GUESSES):
            try:
                d, thetas = self._guess_step(hessian, gradient + min_linear, matrix, values, active, ties, max_groups)
            except BackendError:  # a singular tie system (dependent ties): the QP decides
                return None
            predicted_sides = values + matrix @ d
            decrease = self._decrease(d, predicted_sides, min_linear, max_groups, min_groups)
            # how far the guess is from its own step, beyond rounding: sides in the wrong state
            # and pieces above the tie (the model's error from them), and tie weights θ below 0
            rounding = ROUNDING * max(np.abs(values).max(initial=0.0), np.abs(predicted_sides).max(initial=0.0))
            wrong = np.where(active, np.minimum(predicted_sides + rounding, 0.0), np.maximum(predicted_sides - rounding, 0.0))
            error = 0.5 * lam * float(wrong @ wrong)
            exact_where_needed = not np.any(active & (wrong != 0.0))  # no side pulled onto its boundary
            dy = d[y_cols]
            new_ties = []
            for (piece_values, grads), tie, theta in zip(max_groups, ties, thetas):
                predicted = piece_values + np.einsum("kqp,kp->kq", grads, dy)
                top = np.max(np.where(tie, predicted, -np.inf), axis=1, keepdims=True)
                above = predicted - top - ROUNDING * max(np.abs(piece_values).max(), np.abs(predicted).max())
                error += float(w @ np.maximum(np.max(np.where(tie, -np.inf, above), axis=1), 0.0))
                exact_where_needed = exact_where_needed and bool(np.all(theta[tie] >= -THETA_TOL))
                keep = tie & (theta >= 0.0)
                keep[np.arange(self.nodes), np.argmax(np.where(tie, theta, -np.inf), axis=1)] = True  # S ≠ ∅
                new_ties.append(keep | (~tie & (above > 0.0)))
            if exact_where_needed and error <= ACTIVE_SET_TOL * max(decrease, 0.0):
                break
            active, ties = np.where(wrong != 0.0, predicted_sides > 0.0, active), new_ties
        else:
            return None
        self.settled = ActiveSet(active, ties)
        return d, decrease, self._slope(d, gradient + min_linear, max_groups, matrix, values)

    def _guess_step(self, hessian: sp.csc_matrix, gradient: np.ndarray, matrix: sp.csr_matrix, values: np.ndarray,
                    active: np.ndarray, ties: list[np.ndarray], max_groups: list) -> tuple[np.ndarray, list[np.ndarray]]:
        """The minimizer of the model with the sides `active` taken as violated and the cost's
        pieces tied as `ties` say (one KKT solve), and each max-group's weights θ (N, m)."""
        lam, w, y_cols, E = self.penalty, self.f.weights, self.y_cols(), self.constraints
        A = matrix[active]
        if self.R is not None:  # H on the reduced columns: A and g too (the tie rows are reduced with C)
            A, gradient, g_cols = A @ self.R, self.R.T @ gradient, self.columns[y_cols]
        else:
            g_cols = y_cols
        if A.shape[0]:
            H = (hessian + lam * (A.T @ A)).tocsc()
            g = gradient + lam * (A.T @ values[active])
        else:  # no side violated: H as it is (a copy of H is ~150 MB on paper-7.3 at N = 1e5)
            H, g = hessian, gradient.copy()
        nodes, p = self.nodes, y_cols.shape[1]
        every = np.arange(nodes)
        rows, rhs, softness, others = [], [], [], []
        for (piece_values, grads), tie in zip(max_groups, ties):
            # one row per node and piece other than q₀, tied or not, so that C keeps one pattern
            # through the guesses of a step (and the KKT solver its analysis): an untied row is
            # 0·d − ν = 0 (ν = 0), a tied one (∇a_q − ∇a_q₀)·d_k − εν = a_q₀ − a_q
            ref = np.argmax(tie, axis=1)  # q₀: the first piece of S
            np.add.at(g, g_cols.ravel(), (w[:, None] * grads[every, ref]).ravel())
            count = tie.shape[1] - 1
            other = np.arange(count)[None, :] + (np.arange(count)[None, :] >= ref[:, None])  # (N, m − 1)
            tied = tie[every[:, None], other]
            coefficients = np.where(tied[:, :, None], grads[every[:, None], other] - grads[every, ref][:, None, :], 0.0)
            rows.append(sp.csr_matrix((coefficients.ravel(), np.repeat(y_cols, count, axis=0).ravel(),
                                       np.arange(0, nodes * count * p + 1, p)), shape=(nodes * count, self.size)))
            rhs.append(np.where(tied, piece_values[every, ref][:, None] - piece_values[every[:, None], other], 0.0).ravel())
            softness.append(np.where(tied, TIE_SOFTNESS, 1.0).ravel())
            others.append((other, tied, ref))
        C = sp.vstack([E, *rows], format="csr") if rows else E
        with np.errstate(all="ignore"):
            soft = np.concatenate([np.zeros(E.shape[0]), *softness])
            d, nu = self._solve_kkt(H, C, g, np.concatenate([np.zeros(E.shape[0]), *rhs]), soft)
        thetas, offset = [], E.shape[0]
        for tie, (other, tied, ref) in zip(ties, others):
            theta = np.zeros(tie.shape)
            size = other.size
            theta[every[:, None], other] = np.where(tied, nu[offset : offset + size].reshape(other.shape), 0.0) / w[:, None]
            offset += size
            theta[every, ref] = 1.0 - theta.sum(axis=1)
            thetas.append(theta)
        return d, thetas

    def _identify(self, d: np.ndarray, predicted_sides: np.ndarray, max_groups: list) -> "ActiveSet":
        """The active set a step found by the QP points to (the next step's first guess):
        the sides it leaves violated and the pieces within IDENTIFY_TOL of its maximum."""
        tol = IDENTIFY_TOL * np.abs(predicted_sides).max(initial=0.0)
        dy = d[self.y_cols()]
        ties = []
        for piece_values, grads in max_groups:
            predicted = piece_values + np.einsum("kqp,kp->kq", grads, dy)
            top = predicted.max(axis=1, keepdims=True)
            ties.append(predicted >= top - IDENTIFY_TOL * max(np.abs(predicted).max(), np.abs(piece_values).max()))
        return ActiveSet(predicted_sides > tol, ties)

    def _min_linear(self, min_groups: list) -> np.ndarray:
        """Σ_k w_k ∇b_p*·d_k: each cost min-group (concave) linearized at its active piece."""
        min_linear = np.zeros(self.size)
        y_cols = self.y_cols()
        for values, grads in min_groups:
            pick = grads[np.arange(self.nodes), np.argmin(values, axis=1)]
            np.add.at(min_linear, y_cols.ravel(), (self.f.weights[:, None] * pick).ravel())
        return min_linear

    def _decrease(self, d: np.ndarray, predicted_sides: np.ndarray, min_linear: np.ndarray,
                  max_groups: list, min_groups: list) -> float:
        """I(ξ) minus the step model at d: (λ/2)(‖r + Jd‖² + Σ max(0, v + Ad)²) plus the cost's
        max-groups at their linearized maximum and min-groups at their linearized active piece."""
        w, dy = self.f.weights, d[self.y_cols()]
        model = 0.5 * self.penalty * (np.sum((self.residual + self.jacobian @ d) ** 2)
                                      + np.sum(np.maximum(predicted_sides, 0.0) ** 2))
        model += sum(float(w @ (values + np.einsum("kqp,kp->kq", grads, dy)).max(axis=1)) for values, grads in max_groups)
        model += float(min_linear @ d) + sum(float(w @ values.min(axis=1)) for values, _ in min_groups)
        return float(self.value - model)

    def _slope(self, d: np.ndarray, gradient: np.ndarray, max_groups: list, matrix: sp.csr_matrix,
               values: np.ndarray) -> float:
        """The objective's one-sided derivative along d: the smooth part, the cost's δ-active
        max-pieces and the violated sides (values are the sides' √w·ℓ)."""
        w, dy = self.f.weights, d[self.y_cols()]
        slope = float(gradient @ d) + self.penalty * float(np.maximum(values, 0.0) @ (matrix @ d))
        for piece_values, grads in max_groups:
            active = piece_values >= piece_values.max(axis=1, keepdims=True) - self.delta
            slope += float(w @ np.max(np.where(active, np.einsum("kqp,kp->kq", grads, dy), -np.inf), axis=1))
        return slope

    def _step_qp(self, hessian: sp.csc_matrix, gradient: np.ndarray) -> SparseQP:
        """The step model as a sparse QP in v = [d | t | s] (the same model as the active-set
        iteration's: one slack per side of every block):

        min ½dᵀHd + gᵀd + Σ_k w_k t_k + (λ/2)·Σ s² + Σ_k w_k ∇b_p*·d_k
        s.t. E d = 0;  a_q + ∇a_q·d_k ≤ t_k (every piece q of each cost max-group);
             √w_k(ℓ_side + ∇ℓ_side·d_k) ≤ s and 0 ≤ s (every side of every block).

        The objective is divided by max(I(ξ), 1e-6), so that it is near O(1) for solvers
        whose tolerances are absolute."""
        nodes, w, lam = self.nodes, self.f.weights, self.penalty
        y_cols = self.y_cols()
        matrix, values = self._hinges()
        max_groups, min_groups = self.cost if self.cost is not None else ([], [])
        n_t, n_s = nodes * len(max_groups), values.size
        t0, s0 = self.size, self.size + n_t
        total = s0 + n_s
        pieces = []
        for g, (piece_values, grads) in enumerate(max_groups):  # the max of every piece's linearization
            node, piece = np.nonzero(np.ones_like(piece_values, dtype=bool))
            count = node.size
            pieces.append((sp.csr_matrix(
                (np.concatenate([grads[node, piece], -np.ones((count, 1))], axis=1).ravel(),
                 (np.repeat(np.arange(count), y_cols.shape[1] + 1),
                  np.concatenate([y_cols[node], (t0 + g * nodes + node)[:, None]], axis=1).ravel())),
                shape=(count, total)), -piece_values[node, piece]))
        slack = sp.hstack([sp.csr_matrix((n_s, s0)), -sp.eye(n_s)])
        hinges = sp.hstack([matrix, sp.csr_matrix((n_s, total - self.size))]) + slack
        E = self.constraints
        scale = 1.0 / max(self.value, 1e-6)
        P = sp.block_diag([hessian, sp.csc_matrix((n_t, n_t)), lam * sp.eye(n_s)], format="csc")
        q = np.concatenate([gradient + self._min_linear(min_groups), np.tile(w, len(max_groups)), np.zeros(n_s)])
        qp = SparseQP(
            P=(scale * P).tocsc(), q=scale * q,
            A=sp.hstack([E, sp.csr_matrix((E.shape[0], total - self.size))], format="csc"), b=np.zeros(E.shape[0]),
            G=sp.vstack([part for part, _ in pieces] + [hinges, slack], format="csc"),
            h=np.concatenate([bound for _, bound in pieces] + [-values, np.zeros(n_s)]),
        )
        return qp

    def _solve_qp(self, hessian: Callable[[bool], sp.csc_matrix], gradient: np.ndarray, backend: StepQPSolver,
                  polish: bool, previous: StepSolution | None) -> tuple[np.ndarray, float, float]:
        """The step by a general QP backend (:mod:`.step_qp`) on :meth:`_step_qp`: its raw
        solution, polished by the active-set iteration from the active set it points to where
        `polish` (the exact step where that settles), else kept where its KKT error is ≤
        KKT_TOL; a backend that ran out of progress at its own precision gives no step."""
        qp = self._step_qp(hessian(False), gradient)
        fits = previous is not None and (previous.v.size, previous.y.size, previous.z.size) == (
            qp.size, qp.b.size, qp.h.size)
        solution = backend.solve(qp, previous if fits else None)
        self.qp_solution = solution
        d = solution.v[: self.size]
        matrix, values = self._hinges()
        max_groups, min_groups = self.cost if self.cost is not None else ([], [])
        min_linear = self._min_linear(min_groups)
        if polish and np.isfinite(d).all():
            step = self._solve_active_set(hessian(True), gradient, self._identify(d, values + matrix @ d, max_groups))
            if step is not None:
                return step
        error = qp.kkt_error(solution.v, solution.y, solution.z)
        if not error <= KKT_TOL:
            if "InsufficientProgress" in solution.status:  # at the backend's precision: no further step
                return np.zeros(self.size), 0.0, 0.0
            raise BackendError(f"direction 'gauss-newton': the step QP ({backend.label}) ended with status "
                               f"{solution.status} and KKT error {error:.1e} > {KKT_TOL:g}")
        predicted_sides = values + matrix @ d
        self.settled = self._identify(d, predicted_sides, max_groups)
        return (d, self._decrease(d, predicted_sides, min_linear, max_groups, min_groups),
                self._slope(d, gradient + min_linear, max_groups, matrix, values))

    def unknowns_step(self, step: np.ndarray) -> np.ndarray:
        """The step on ξ = [x | z | u] per node (dropping Z)."""
        return step.reshape(self.nodes, self.width)[:, : 2 * self.n + self.m].copy()
