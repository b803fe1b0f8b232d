"""The step QP of `gauss-newton` and the backends that solve it (``--option qp=NAME``).

gauss-newton's step minimizes a convex model of I (:mod:`.gauss_newton`), stated for
a general backend as one sparse QP

    minimize ½vᵀPv + qᵀv   subject to   A v = b,   G v ≤ h,

with multipliers y (equalities) and z ≥ 0 (inequalities), and the KKT conditions

    P v + q + Aᵀy + Gᵀz = 0,   A v = b,   G v ≤ h,   z ≥ 0,   zᵀ(h − G v) = 0.

Backends (registry group ``qdframe.step_qps``, listed by ``qdframe list``):

* ``active-set`` (the default) is not a general QP solver: it is gauss-newton's own
  primal-dual active-set iteration on the model's structure (one sparse KKT solve per
  guess, the previous step's active set as the first guess), and where that does not
  settle, the ``clarabel`` backend on the general QP;
* ``clarabel``, ``osqp``, ``cvxpy`` and ``qpsolvers:NAME`` (``SPARSE_QPSOLVERS``) solve
  the general QP at every step.

Status discipline, as for the min-norm QPs (:mod:`.qp`): a backend returns its raw
(v, y, z) and status. gauss-newton then polishes it: the active set that v points to
is the first guess of the active-set iteration, whose exact KKT solve replaces v when it
settles (as OSQP polishes its own, done the same way for every
backend; ``--option qp_polish=false`` keeps the raw steps). A raw solution that is kept
must pass :meth:`SparseQP.kkt_error` ≤ ``kkt_tol`` (relative to the data), else the step
raises :class:`~qdframe.errors.BackendError` naming the backend, its status and the
residual. A bad step is never returned silently.
"""

from __future__ import annotations

import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import scipy.sparse as sp

from ..errors import BackendError, InputError, close_names
from ..registry import lookup, names
from .qp import require

KKT_TOL = 1e-4  # a raw solution's largest relative KKT error (kkt_error) for it to be kept: an inexact Newton step


@dataclass(frozen=True)
class SparseQP:
    """minimize ½vᵀPv + qᵀv subject to A v = b, G v ≤ h (P symmetric PSD, full, CSC)."""

    P: sp.csc_matrix
    q: np.ndarray
    A: sp.csc_matrix
    b: np.ndarray
    G: sp.csc_matrix
    h: np.ndarray

    @property
    def size(self) -> int:
        return self.q.size

    def kkt_error(self, v: np.ndarray, y: np.ndarray, z: np.ndarray) -> float:
        """The largest KKT residual at (v, y, z), each relative to its data: stationarity to
        1 + ‖q‖∞ + ‖Pv‖∞ + ‖Aᵀy‖∞ + ‖Gᵀz‖∞, feasibility to 1 + ‖b‖∞ (+ ‖h‖∞), complementarity
        to 1 + |objective|; z < 0 counts as a dual infeasibility. inf where anything is not finite."""
        if not (np.isfinite(v).all() and np.isfinite(y).all() and np.isfinite(z).all()):
            return np.inf
        Pv, Ay, Gz = self.P @ v, self.A.T @ y, self.G.T @ z
        scale = 1.0 + max(_norm(self.q), _norm(Pv), _norm(Ay), _norm(Gz))
        stationarity = _norm(Pv + self.q + Ay + Gz) / scale
        equalities = _norm(self.A @ v - self.b) / (1.0 + _norm(self.b))
        slack = self.h - self.G @ v
        inequalities = _norm(np.minimum(slack, 0.0)) / (1.0 + _norm(self.h))
        duals = _norm(np.minimum(z, 0.0)) / (1.0 + _norm(z))
        objective = 0.5 * float(v @ Pv) + float(self.q @ v)
        complementarity = abs(float(np.maximum(z, 0.0) @ np.maximum(slack, 0.0))) / (1.0 + abs(objective))
        return max(stationarity, equalities, inequalities, duals, complementarity)


def _norm(vector: np.ndarray) -> float:
    return float(np.max(np.abs(vector), initial=0.0))


@dataclass(frozen=True)
class StepSolution:
    """A backend's raw answer: v, the multipliers y (A v = b) and z ≥ 0 (G v ≤ h), its own
    status text, and `solved` when that status is its success."""

    v: np.ndarray
    y: np.ndarray
    z: np.ndarray
    status: str
    solved: bool


class StepQPSolver(ABC):
    """A backend of gauss-newton's step QP: one :meth:`solve` per step.

    `warm` is the previous step's solution when the QP has the same shapes (a backend
    that can warm-start uses it). A backend raises :class:`BackendError` only where it
    cannot answer at all (an exception of its package); anything else is a
    :class:`StepSolution` whose status says how it ended.
    """

    name: ClassVar[str] = ""
    structured: ClassVar[bool] = False  # True: gauss-newton's own active-set iteration (no general solve)

    def __init__(self, name: str | None = None) -> None:
        self.label = name or self.name

    @classmethod
    def from_name(cls, name: str) -> "StepQPSolver":
        return cls(name)

    @abstractmethod
    def solve(self, qp: SparseQP, warm: StepSolution | None = None) -> StepSolution:
        """The QP's (raw) solution."""


def make_step_qp(name: str) -> StepQPSolver:
    """The step-QP backend called `name` (the registry's ``step_qps``)."""
    entry = lookup("step_qps", str(name))
    return entry.obj.from_name(name)


def step_qp_names() -> list[str]:
    """The registered step-QP backends' names (``qpsolvers:`` spelled with its solvers)."""
    return [item for name in names("step_qps")
            for item in ([f"{name}{solver}" for solver in SPARSE_QPSOLVERS] if name.endswith(":") else [name])]


def step_qp_expected(name: str) -> str:
    """The expected form of gauss-newton's `qp` option, with why `name` was refused: the
    reason a qpsolvers solver is not offered, or the close names."""
    solver = name.partition(":")[2] if name.startswith("qpsolvers:") else ""
    known = step_qp_names()
    close = close_names(name, known)
    why = (f"; {name} is not offered: {NOT_OFFERED[solver]}" if solver in NOT_OFFERED else
           f"; did you mean {close[0]}?" if close else "")
    return "a step-QP backend (qdframe list: step_qps): " + ", ".join(known) + why


class ActiveSetStep(StepQPSolver):
    """gauss-newton's own active-set iteration (one KKT solve per guess); Clarabel where it does not settle."""

    name = "active-set"
    structured = True
    fallback = "clarabel"

    def solve(self, qp: SparseQP, warm: StepSolution | None = None) -> StepSolution:
        return make_step_qp(self.fallback).solve(qp, warm)


class ClarabelStep(StepQPSolver):
    """The step QP by Clarabel (interior point), gap and feasibility tolerances 1e-12, once more at 1e-10."""

    name = "clarabel"
    tolerances = (1e-12, 1e-10)  # the second try after InsufficientProgress: near a solution 1e-12
    # can be below Clarabel's reach, and whether it stalls depends on rounding-level details

    def solve(self, qp: SparseQP, warm: StepSolution | None = None) -> StepSolution:
        clarabel = require("clarabel", f"gauss-newton (qp={self.label})", "'qdframe[clarabel]'")
        matrix = sp.vstack([qp.A, qp.G], format="csc")
        rhs = np.concatenate([qp.b, qp.h])
        cones = [clarabel.ZeroConeT(qp.A.shape[0]), clarabel.NonnegativeConeT(qp.G.shape[0])]
        for tol in self.tolerances:
            settings = clarabel.DefaultSettings()
            settings.verbose = False
            settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = tol
            solution = clarabel.DefaultSolver(sp.triu(qp.P, format="csc"), qp.q, matrix, rhs, cones, settings).solve()
            if str(solution.status) != "InsufficientProgress":
                break
        status = str(solution.status)
        dual = np.asarray(solution.z, dtype=float)
        return StepSolution(np.asarray(solution.x, dtype=float), dual[: qp.A.shape[0]], dual[qp.A.shape[0]:],
                            status, status in ("Solved", "AlmostSolved"))


class OsqpStep(StepQPSolver):
    """The step QP by OSQP (ADMM, eps 1e-7, polished), warm-started from the previous step."""

    name = "osqp"
    settings: ClassVar[dict[str, Any]] = {"eps_abs": 1e-7, "eps_rel": 1e-7, "max_iter": 20_000, "polishing": True,
                                          "polish_refine_iter": 20}

    def solve(self, qp: SparseQP, warm: StepSolution | None = None) -> StepSolution:
        osqp = require("osqp", f"gauss-newton (qp={self.label})", "'qdframe[osqp]'")
        solver = osqp.OSQP()
        solver.setup(qp.P, qp.q, sp.vstack([qp.A, qp.G], format="csc"), np.concatenate([qp.b, np.full(qp.h.size, -np.inf)]),
                     np.concatenate([qp.b, qp.h]), verbose=False, warm_starting=True, **self.settings)
        if warm is not None:
            solver.warm_start(x=warm.v, y=np.concatenate([warm.y, warm.z]))
        result = solver.solve(raise_error=False)
        solved = result.info.status_val == osqp.SolverStatus.OSQP_SOLVED
        missing = np.full(qp.size, np.nan)
        dual = np.asarray(result.y if result.y is not None else np.full(qp.A.shape[0] + qp.h.size, np.nan), dtype=float)
        return StepSolution(np.asarray(result.x if result.x is not None else missing, dtype=float),
                            dual[: qp.A.shape[0]], dual[qp.A.shape[0]:], str(result.info.status), solved)


class CvxpyStep(StepQPSolver):
    """The step QP stated in CVXPY and solved by its default QP solver (each step compiled afresh)."""

    name = "cvxpy"

    def solve(self, qp: SparseQP, warm: StepSolution | None = None) -> StepSolution:
        cp = require("cvxpy", f"gauss-newton (qp={self.label})", "'qdframe[cvxpy]'")
        v = cp.Variable(qp.size)
        equalities, inequalities = qp.A @ v == qp.b, qp.G @ v <= qp.h
        objective = 0.5 * cp.quad_form(v, cp.psd_wrap(qp.P)) + qp.q @ v
        problem = cp.Problem(cp.Minimize(objective), [equalities, inequalities])
        try:
            problem.solve()
        except cp.error.SolverError as exc:
            raise BackendError(f"direction 'gauss-newton': the step QP (cvxpy) failed: {exc}") from exc
        if v.value is None:
            nan = np.full(qp.size, np.nan)
            return StepSolution(nan, np.full(qp.b.size, np.nan), np.full(qp.h.size, np.nan), str(problem.status), False)
        return StepSolution(np.asarray(v.value, dtype=float), np.asarray(equalities.dual_value, dtype=float).ravel(),
                            np.asarray(inequalities.dual_value, dtype=float).ravel(), str(problem.status),
                            problem.status == cp.OPTIMAL)


SPARSE_QPSOLVERS = ("clarabel", "osqp", "proxqp", "scs")
"""The qpsolvers solvers offered for the step: sparse ones, each measured on the paper's
examples and the stick/slide suite (tests/directions/test_step_qp.py); others are refused
with the reason in NOT_OFFERED."""

NOT_OFFERED: dict[str, str] = {
    "daqp": "a dense solver: the step QP has nodes × (3n + m) variables",
    "highs": "ends the step QPs of the friction models 'not found'",
}

QPSOLVERS_SETTINGS: dict[str, dict[str, Any]] = {
    "clarabel": {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12},
    "osqp": {"eps_abs": 1e-7, "eps_rel": 1e-7, "max_iter": 20_000, "polishing": True},
    "proxqp": {"eps_abs": 1e-10, "eps_rel": 0.0},
    "scs": {"eps_abs": 1e-10, "eps_rel": 1e-10, "max_iters": 20_000},
}


class QpsolversStep(StepQPSolver):
    """The step QP by a sparse qpsolvers solver: qpsolvers:NAME, NAME one of clarabel, osqp, proxqp, scs."""

    name = "qpsolvers:"

    def __init__(self, name: str | None = None) -> None:
        super().__init__(name)
        solver = (name or "").partition(":")[2]
        if solver not in SPARSE_QPSOLVERS:
            why = f" ({NOT_OFFERED[solver]})" if solver in NOT_OFFERED else ""
            raise InputError("qp", "qpsolvers:NAME with NAME one of " + ", ".join(SPARSE_QPSOLVERS), f"{name}{why}")
        self.solver = solver

    def solve(self, qp: SparseQP, warm: StepSolution | None = None) -> StepSolution:
        qpsolvers = require("qpsolvers", f"gauss-newton (qp={self.label})", "'qdframe[qpsolvers]'")
        problem = qpsolvers.Problem(qp.P, qp.q, qp.G, qp.h, qp.A, qp.b)
        try:
            with warnings.catch_warnings():  # its status warnings: the status is reported and judged here
                warnings.simplefilter("ignore", UserWarning)
                solution = qpsolvers.solve_problem(problem, solver=self.solver, initvals=None if warm is None else warm.v,
                                                   **QPSOLVERS_SETTINGS.get(self.solver, {}))
        except Exception as exc:  # noqa: BLE001 - the solver package's own failure
            raise BackendError(f"direction 'gauss-newton': the step QP ({self.label}) raised "
                               f"{type(exc).__name__}: {exc}") from exc
        nan = np.full(qp.size, np.nan)
        y = solution.y if solution.y is not None else np.full(qp.b.size, np.nan)
        z = solution.z if solution.z is not None else np.full(qp.h.size, np.nan)
        found = bool(solution.found)
        return StepSolution(np.asarray(solution.x if solution.x is not None else nan, dtype=float),
                            np.asarray(y, dtype=float), np.asarray(z, dtype=float),
                            "found" if found else "not found", found)
