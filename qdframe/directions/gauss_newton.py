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
implicit Euler or Radau IIA: :class:`~qdframe.schemes.grid.Grid`), a banded equality
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

One step, in parts: :class:`~.linearized_system.LinearizedSystem` assembles r, J, E, the
hinge rows and the cost's pieces at ξ and evaluates the model at a step;
:class:`ActiveSetIteration` minimizes the model, :class:`QPStep` states it as a QP for a
general backend (and polishes that backend's step); :class:`Step` runs the one, then the other.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import BackendError, QdframeError
from .base import Direction, DirectionSolver, OptionError, number_rule
from .kkt import Bordered, KKTSolver, solve_kkt
from .linearized_system import LinearizedSystem, Skeleton
from .step_qp import (KKT_TOL, ActiveSetStep, SparseQP, StepQPSolver, StepSolution, make_step_qp,
                      step_qp_expected)

if TYPE_CHECKING:
    from ..functional import Functional


@dataclass(frozen=True)
class GaussNewtonState:
    """What gauss-newton keeps between the iterations of one solve, replaced (never changed)
    by each step: the damping μ and the step's predicted decrease, objective, iterate and step
    (for the next μ), the active set and QP solution it warm-starts from, the ξ-independent
    part of the linearized system (`skeleton`) and the KKT solver with its analysis."""

    backend: StepQPSolver
    mu: float | None = None
    previous_value: float | None = None
    predicted: float | None = None
    xi: np.ndarray | None = None
    step: np.ndarray | None = None
    active_set: object = None
    qp_solution: object = None
    skeleton: Skeleton | None = None
    kkt: KKTSolver | None = None


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
    state: GaussNewtonState | None = field(default=None, init=False, repr=False)  # of the solve at hand
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
            self.state = GaussNewtonState(self.qp)
            return
        try:
            self.state = GaussNewtonState(make_step_qp(str(self.qp)))
        except QdframeError:
            raise OptionError(type(self).__name__, "qp", step_qp_expected(str(self.qp)), self.qp) from None

    @property
    def label(self) -> str:
        backend = None if self.state is None else self.state.backend
        name = getattr(backend, "label", None) or getattr(self.qp, "label", str(self.qp))
        options = ([] if name == ActiveSetStep.name else [f"qp={name}"]) + ([] if self.qp_polish else ["qp_polish=false"])
        return self.name + (f"[{','.join(options)}]" if options else "")

    def compute(self, functional: "Functional", xi: np.ndarray, delta: float) -> Direction:
        value = functional.objective(xi)
        state = self.state
        state = dataclasses.replace(state, mu=self._damping(state, xi, value))
        if state.skeleton is None or state.skeleton.f is not functional:  # the ξ-independent part: once per functional
            state = dataclasses.replace(state, skeleton=Skeleton(functional))
        if state.kkt is None:
            state = dataclasses.replace(state, kkt=KKTSolver())
        system = LinearizedSystem(functional, xi, delta, value, state.skeleton)
        solver = Step(system, state.kkt)
        found = solver.solve(state.mu, warm=state.active_set, backend=state.backend, polish=self.qp_polish,
                             previous=state.qp_solution)
        step = system.unknowns_step(found.d)
        self.state = dataclasses.replace(state, previous_value=value, predicted=found.predicted, xi=xi, step=step,
                                         active_set=found.settled, qp_solution=solver.qp_solution)
        per_node = np.linalg.norm(step, axis=1)
        return Direction(step=step, deviation=per_node, slope=found.slope,
                         stationary=bool(found.predicted <= 1e-14 * max(value, 1e-300) or not np.any(per_node)))

    def start(self, functional: "Functional") -> None:
        self.state = GaussNewtonState(self.state.backend)  # its backend made by check_options

    @property
    def factorizations(self) -> int:
        """KKT factorizations since the solve began (one per guess of the active-set iteration)."""
        kkt = None if self.state is None else self.state.kkt
        return kkt.factorizations if kkt is not None else 0

    def _damping(self, state: GaussNewtonState, xi: np.ndarray, value: float) -> float:
        """μ for the step from ξ: the option's at a solve's first iteration, then as the last
        step fared (Levenberg–Marquardt: the line search's cut and the decrease's ratio to the
        predicted)."""
        if state.step is None:  # the first iteration of a solve
            return self.mu
        predicted = state.predicted
        ratio = (state.previous_value - value) / predicted if predicted > 0 else 0.0
        step = state.step
        norm2 = float(np.sum(step**2))
        gamma = float(np.sum((xi - state.xi) * step)) / norm2 if norm2 > 0 else 1.0
        if gamma < 0.5:  # the line search cut the step: the LM step scales like 1/μ
            return min(state.mu * 2.0 / max(gamma, 1e-6), self.mu_max)
        if ratio > 0.75:
            return max(state.mu / 10.0, self.mu_min)
        if ratio < 0.25:
            return min(state.mu * 2.0, self.mu_max)
        return state.mu


MAX_GUESSES = 30  # KKT solves of the active-set iteration before Clarabel takes over
ACTIVE_SET_TOL = 1e-3  # violations a guess leaves out may change its model by this × the predicted decrease
ROUNDING = 1e-12  # a side or piece within this × the largest predicted value of its kind counts as either state
THETA_TOL = 1e-9  # a tie weight θ above −this counts as ≥ 0
TIE_SOFTNESS = 1e-14  # ε of the tie rows (kkt.solve_kkt's soft): a tie on a fixed x_i(0) repeats a row of E
IDENTIFY_TOL = 1e-7  # what counts as violated or tied in the QP's step (an interior point's precision)


@dataclass(frozen=True)
class ActiveSet:
    """What a step's active-set iteration settled on: the hinge sides taken as violated
    (one flag per row of :meth:`LinearizedSystem.hinges`) and, per cost max-group, the pieces tied
    at the maximum at each node ((N, m) flags). The next step starts from it."""

    sides: np.ndarray
    ties: list[np.ndarray]

    def fits(self, values: np.ndarray, max_groups: list) -> bool:
        return self.sides.shape == values.shape and len(self.ties) == len(max_groups) and all(
            tie.shape == piece_values.shape for tie, (piece_values, _) in zip(self.ties, max_groups))

class StepFound(NamedTuple):
    """A step of the model: d (extended), the predicted decrease of the objective, the slope
    along d, and the active set it settled on or points to (None: none to start the next from)."""

    d: np.ndarray
    predicted: float
    slope: float
    settled: ActiveSet | None


class Step:
    """One gauss-newton step at ξ: the active-set iteration on the linearized system, and a
    general QP backend where that does not settle or where the option `qp` names one."""

    def __init__(self, system: LinearizedSystem, kkt: KKTSolver | None = None) -> None:
        self.system = system
        self.kkt = kkt or KKTSolver()  # the solve's KKT factorizer: its symbolic analysis is reused
        self.active_set = ActiveSetIteration(system, self.kkt)
        self.qp = QPStep(system, self.active_set)

    @property
    def qp_solution(self) -> StepSolution | None:
        """The general backend's raw solution (its next step's warm start); None if none ran."""
        return self.qp.solution

    def solve(self, mu: float, warm: ActiveSet | None = None, backend: StepQPSolver | None = None,
              polish: bool = True, previous: StepSolution | None = None) -> StepFound:
        """The step with damping μ (extended), its predicted decrease, slope and active set.

        warm: the active set the previous step settled on (same grid), the first guess of
        this one. backend: the step-QP backend (:mod:`.step_qp`; None or ``active-set``: the
        active-set iteration, Clarabel where it does not settle); `previous` its last solution
        (a warm start), this step's in :attr:`qp_solution`."""
        system = self.system
        gradient = system.gradient()
        cache: dict[bool, sp.csc_matrix] = {}

        def hessian(reduced: bool) -> sp.csc_matrix:
            """λJᵀJ + μW, on the constant states' reduced columns (R) if `reduced`; the
            active-set systems' H (reduced where there are constant states) is the QP's too."""
            reduced = reduced and system.R is not None
            if reduced not in cache:
                cache[reduced] = system.hessian(mu, reduced)
            return cache[reduced]

        backend = backend if backend is not None else make_step_qp(ActiveSetStep.name)
        if backend.structured:
            found = self.active_set.solve(hessian(True), gradient, warm)
            if found is not None:
                return found
        return self.qp.solve(hessian, gradient, backend, polish, previous)


class ActiveSetIteration:
    """The step model (the QP of :meth:`QPStep.statement`) minimized by a primal-dual
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
    """

    def __init__(self, system: LinearizedSystem, kkt: KKTSolver) -> None:
        self.system = system
        self.kkt = kkt  # the solve's KKT factorizer (its analysis reused through the guesses and the steps)

    def solve(self, hessian: sp.csc_matrix, gradient: np.ndarray, warm: ActiveSet | None) -> StepFound | None:
        """The model's minimizer from the first guess `warm` (its own where None or of another
        shape: :meth:`_cold_start`), with hessian λJᵀJ + μW and gradient λJᵀr. None if no guess
        is accepted in MAX_GUESSES solves, a guess comes back (the next guess is a function of
        this one: from there the guesses cycle), or a tie system is singular (a general QP
        backend takes over: :meth:`QPStep.solve`)."""
        system = self.system
        lam, w = system.penalty, system.f.weights
        matrix, values = system.hinges()
        max_groups = system.max_groups
        gradient = gradient + system.min_linear()
        guess = warm if warm is not None and warm.fits(values, max_groups) else self._cold_start(values)
        active, ties = guess.sides, [tie.copy() for tie in guess.ties]
        seen = set()  # the guesses so far
        for _ in range(MAX_GUESSES):
            key = hash((active.tobytes(), *(tie.tobytes() for tie in ties)))
            if key in seen:  # a cycle: it would never settle (block-time-optimal: 30 guesses, 9–15 distinct)
                return None
            seen.add(key)
            try:
                d, thetas = self._guess_step(hessian, gradient, active, ties)
            except BackendError:  # a singular tie system (dependent ties): the QP decides
                return None
            predicted_sides = values + matrix @ d
            decrease = system.decrease(d, predicted_sides)
            # how far the guess is from its own step, beyond rounding: sides in the wrong state
            # and pieces above the tie (the model's error from them), and tie weights θ below 0
            rounding = ROUNDING * max(np.abs(values).max(initial=0.0), np.abs(predicted_sides).max(initial=0.0))
            wrong = np.where(active, np.minimum(predicted_sides + rounding, 0.0), np.maximum(predicted_sides - rounding, 0.0))
            error = 0.5 * lam * float(wrong @ wrong)
            exact_where_needed = not np.any(active & (wrong != 0.0))  # no side pulled onto its boundary
            new_ties = []
            for (piece_values, _), predicted, tie, theta in zip(max_groups, system.max_pieces(d), ties, thetas):
                top = np.max(np.where(tie, predicted, -np.inf), axis=1, keepdims=True)
                above = predicted - top - ROUNDING * max(np.abs(piece_values).max(), np.abs(predicted).max())
                error += float(w @ np.maximum(np.max(np.where(tie, -np.inf, above), axis=1), 0.0))
                exact_where_needed = exact_where_needed and bool(np.all(theta[tie] >= -THETA_TOL))
                keep = tie & (theta >= 0.0)
                keep[np.arange(system.nodes), np.argmax(np.where(tie, theta, -np.inf), axis=1)] = True  # S ≠ ∅
                new_ties.append(keep | (~tie & (above > 0.0)))
            if exact_where_needed and error <= ACTIVE_SET_TOL * max(decrease, 0.0):
                break
            active, ties = np.where(wrong != 0.0, predicted_sides > 0.0, active), new_ties
        else:
            return None
        return StepFound(d, decrease, system.slope(d, gradient), ActiveSet(active, ties))

    def _cold_start(self, values: np.ndarray) -> ActiveSet:
        """The first guess without a previous step: the sides violated now, and each cost
        max-group's largest piece at every node."""
        ties = []
        for piece_values, _ in self.system.max_groups:
            tie = np.zeros(piece_values.shape, dtype=bool)
            tie[np.arange(self.system.nodes), np.argmax(piece_values, axis=1)] = True
            ties.append(tie)
        return ActiveSet(values > 0, ties)

    def _guess_step(self, hessian: sp.csc_matrix, gradient: np.ndarray, active: np.ndarray,
                    ties: list[np.ndarray]) -> tuple[np.ndarray, list[np.ndarray]]:
        """The minimizer of the model with the sides `active` taken as violated and the cost's
        pieces tied as `ties` say (one KKT solve), and each max-group's weights θ (N, m)."""
        system = self.system
        lam, w, y_cols, E = system.penalty, system.f.weights, system.y_cols(), system.constraints
        matrix, values = system.hinges()
        A = matrix[active]
        if system.R is not None:  # H on the reduced columns: A and g too (the tie rows are reduced with C)
            A, gradient, g_cols = A @ system.R, system.R.T @ gradient, system.columns[y_cols]
        else:
            g_cols = y_cols
        if A.shape[0]:
            H = hessian.plus(A, lam) if isinstance(hessian, Bordered) else (hessian + lam * (A.T @ A)).tocsc()
            g = gradient + lam * (A.T @ values[active])
        else:  # no side violated: H as it is (a copy of H is ~150 MB on paper-7.3 at N = 1e5)
            H, g = hessian, gradient.copy()
        nodes, p = system.nodes, y_cols.shape[1]
        every = np.arange(nodes)
        rows, rhs, softness, others = [], [], [], []
        for (piece_values, grads), tie in zip(system.max_groups, ties):
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
                                       np.arange(0, nodes * count * p + 1, p)), shape=(nodes * count, system.size)))
            rhs.append(np.where(tied, piece_values[every, ref][:, None] - piece_values[every[:, None], other], 0.0).ravel())
            softness.append(np.where(tied, TIE_SOFTNESS, 1.0).ravel())
            others.append((other, tied, ref))
        with np.errstate(all="ignore"):
            soft = np.concatenate([np.zeros(E.shape[0]), *softness])
            d, nu = self._solve_kkt(H, rows, g, np.concatenate([np.zeros(E.shape[0]), *rhs]), soft)
        thetas, offset = [], E.shape[0]
        for tie, (other, tied, ref) in zip(ties, others):
            theta = np.zeros(tie.shape)
            size = other.size
            theta[every[:, None], other] = np.where(tied, nu[offset : offset + size].reshape(other.shape), 0.0) / w[:, None]
            offset += size
            theta[every, ref] = 1.0 - theta.sum(axis=1)
            thetas.append(theta)
        return d, thetas

    def _solve_kkt(self, H: sp.spmatrix, ties: list[sp.csr_matrix], g: np.ndarray, rhs: np.ndarray,
                   soft: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """d and ν of the KKT system with C = [E; ties]. With constant states H and g are on the
        reduced columns (:meth:`LinearizedSystem.reduced`), the ties on all: C is reduced here (E's
        reduction kept from step to step), and d comes back on every column (a constant state's
        x_i the same at every node, its z_i and Z_i 0)."""
        R, E = self.system.R, self.system.constraints
        if R is None:
            C = sp.vstack([E, *ties], format="csr") if ties else E
            return solve_kkt(H, C, g, rhs, soft, solver=self.kkt)
        Cr, live = self.system.reduced(sp.vstack(ties, format="csr") if ties else None)
        d, nu = solve_kkt(H, Cr, g, rhs[live], soft[live], solver=self.kkt)
        multipliers = np.zeros(live.size)
        multipliers[live] = nu
        return R @ d, multipliers


class QPStep:
    """The step by a general QP backend (:mod:`.step_qp`): the step model stated as a sparse QP,
    the backend's raw solution, and its polish by the active-set iteration."""

    def __init__(self, system: LinearizedSystem, polish_by: ActiveSetIteration) -> None:
        self.system = system
        self.polish_by = polish_by
        self.solution: StepSolution | None = None  # the backend's raw solution (the next step's warm start)

    def statement(self, hessian: sp.csc_matrix, gradient: np.ndarray) -> SparseQP:
        """The step model as a sparse QP in v = [d | t | s] (the same model as the active-set
        iteration's: one slack per side of every block):

        min ½dᵀHd + gᵀd + Σ_k w_k t_k + (λ/2)·Σ s² + Σ_k w_k ∇b_p*·d_k
        s.t. E d = 0;  a_q + ∇a_q·d_k ≤ t_k (every piece q of each cost max-group);
             √w_k(ℓ_side + ∇ℓ_side·d_k) ≤ s and 0 ≤ s (every side of every block).

        The objective is divided by max(I(ξ), 1e-6), so that it is near O(1) for solvers
        whose tolerances are absolute."""
        system = self.system
        nodes, w, lam, size = system.nodes, system.f.weights, system.penalty, system.size
        y_cols = system.y_cols()
        matrix, values = system.hinges()
        max_groups = system.max_groups
        n_t, n_s = nodes * len(max_groups), values.size
        t0, s0 = size, size + n_t
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
        hinges = sp.hstack([matrix, sp.csr_matrix((n_s, total - size))]) + slack
        E = system.constraints
        scale = 1.0 / max(system.value, 1e-6)
        P = sp.block_diag([hessian, sp.csc_matrix((n_t, n_t)), lam * sp.eye(n_s)], format="csc")
        q = np.concatenate([gradient + system.min_linear(), np.tile(w, len(max_groups)), np.zeros(n_s)])
        return SparseQP(
            P=(scale * P).tocsc(), q=scale * q,
            A=sp.hstack([E, sp.csr_matrix((E.shape[0], total - size))], format="csc"), b=np.zeros(E.shape[0]),
            G=sp.vstack([part for part, _ in pieces] + [hinges, slack], format="csc"),
            h=np.concatenate([bound for _, bound in pieces] + [-values, np.zeros(n_s)]),
        )

    def solve(self, hessian: Callable[[bool], sp.csc_matrix], gradient: np.ndarray, backend: StepQPSolver,
              polish: bool, previous: StepSolution | None) -> StepFound:
        """The step by `backend` on :meth:`statement`: its raw solution, polished by the
        active-set iteration from the active set it points to where `polish` (the exact step
        where that settles), else kept where its KKT error is ≤ KKT_TOL; a backend that ran
        out of progress at its own precision gives no step. hessian(reduced): λJᵀJ + μW, on
        the constant states' reduced columns if `reduced` (:meth:`Step.solve`)."""
        system = self.system
        qp = self.statement(hessian(False), gradient)
        fits = previous is not None and (previous.v.size, previous.y.size, previous.z.size) == (
            qp.size, qp.b.size, qp.h.size)
        solution = backend.solve(qp, previous if fits else None)
        self.solution = solution
        d = solution.v[: system.size]
        matrix, values = system.hinges()
        if polish and np.isfinite(d).all():
            found = self.polish_by.solve(hessian(True), gradient, self.identify(d, values + matrix @ d))
            if found is not None:
                return found
        error = qp.kkt_error(solution.v, solution.y, solution.z)
        if not error <= KKT_TOL:
            if "InsufficientProgress" in solution.status:  # at the backend's precision: no further step
                return StepFound(np.zeros(system.size), 0.0, 0.0, None)
            raise BackendError(f"direction 'gauss-newton': the step QP ({backend.label}) ended with status "
                               f"{solution.status} and KKT error {error:.1e} > {KKT_TOL:g}")
        predicted_sides = values + matrix @ d
        return StepFound(d, system.decrease(d, predicted_sides), system.slope(d, gradient + system.min_linear()),
                         self.identify(d, predicted_sides))

    def identify(self, d: np.ndarray, predicted_sides: np.ndarray) -> ActiveSet:
        """The active set a step found by the QP points to (the next step's first guess):
        the sides it leaves violated and the pieces within IDENTIFY_TOL of its maximum."""
        tol = IDENTIFY_TOL * np.abs(predicted_sides).max(initial=0.0)
        ties = []
        for (piece_values, _), predicted in zip(self.system.max_groups, self.system.max_pieces(d)):
            top = predicted.max(axis=1, keepdims=True)
            ties.append(predicted >= top - IDENTIFY_TOL * max(np.abs(predicted).max(), np.abs(piece_values).max()))
        return ActiveSet(predicted_sides > tol, ties)
