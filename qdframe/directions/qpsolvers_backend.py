"""The `qpsolvers:NAME` direction: the min-norm QPs by any solver qpsolvers knows.

``qpsolvers:daqp``, ``qpsolvers:proxqp``, ``qpsolvers:scs``, … (``SUPPORTED``). The
QPs are passed to ``qpsolvers.solve_problem`` `rows_per_qp` rows at a time (0: all),
stacked block-diagonally (:class:`~qdframe.directions.qp.BlockQP`, with λ ≥ 0 as
variable bounds): dense matrices for a dense-only solver or one-row QPs, CSC otherwise
(`dense` forces either). By default the stack size is the one chosen per solver
(``ROWS_PER_QP``; docs/directions.md): one QP per row for daqp, 32 rows per sparse QP
for proxqp. Each solver gets tight tolerances (``DEFAULT_SETTINGS``, which
`settings` overrides); a solution that is not ``found`` or a solver exception is a
failure of the rows of that QP, and every row is checked and polished as
:mod:`qdframe.directions.qp` describes; failed rows are retried one QP per row (with ``RETRY_SETTINGS``). Only the solvers in
``SUPPORTED`` are offered: quadprog and ecos require a positive definite Hessian (this
exact formulation's is singular in λ), and highs fails rows of the paper's QPs. Needs ``pip install 'qdframe[qpsolvers]'`` and the solver's own package.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import BackendError, InputError
from .base import OptionError
from .qp import BlockQP, QPDirection, require

DEFAULT_SETTINGS: dict[str, dict[str, Any]] = {
    "daqp": {"primal_tol": 1e-12, "eps_prox": 3e-2, "eta_prox": 1e-15},
    "proxqp": {"eps_abs": 1e-13, "eps_rel": 0.0, "check_duality_gap": True, "eps_duality_gap_abs": 1e-14},
    "piqp": {"eps_abs": 1e-12, "eps_rel": 0.0, "eps_duality_gap_abs": 1e-13, "eps_duality_gap_rel": 0.0},
    "clarabel": {"tol_gap_abs": 1e-14, "tol_gap_rel": 1e-14, "tol_feas": 1e-13, "tol_ktratio": 1e-12},
    "osqp": {"eps_abs": 1e-6, "eps_rel": 1e-6, "polishing": True, "polish_refine_iter": 20, "max_iter": 100_000},
    "scs": {"eps_abs": 1e-12, "eps_rel": 1e-12, "max_iters": 100_000},
    "cvxopt": {"abstol": 1e-14, "reltol": 1e-14, "feastol": 1e-12},
}
"""High-accuracy settings per qpsolvers solver name (others get the solver's defaults)."""

RETRY_SETTINGS: dict[str, dict[str, Any]] = {
    "daqp": {"eps_prox": 1e-3, "iter_limit": 100_000},
    "osqp": {"eps_abs": 1e-12, "eps_rel": 1e-12},
}
"""Changes for the second attempt on failed rows. daqp: at eps_prox = 3e-2 some rows of the
degenerate batches (collinear, badly scaled) hit its iteration limit ("not found", no
weights to polish); eps_prox = 1e-3 with a higher iteration limit solves them, where 1e-2
did not (docs/directions.md). 1e-3 is not the first choice: on other rows it is less
accurate, which the polish then has to repair. osqp: as the `osqp` direction, eps 1e-6 +
polish first, eps 1e-12 for the rows that fail."""

ROWS_PER_QP: dict[str, int] = {"daqp": 1, "proxqp": 32, "scs": 256}
"""Default stack sizes, chosen per solver (docs/directions.md): daqp one row per QP
(stacking rows only slows it); proxqp 32 rows per sparse QP (one row per QP is slower,
large stacks hit its iteration limit at these tolerances); scs 256 (small stacks leave
rows that miss the KKT check). Other dense-only solvers: 1; other sparse solvers:
DEFAULT_STACK."""

DEFAULT_STACK = 1000

SUPPORTED = ("daqp", "osqp", "proxqp", "scs")
"""The qpsolvers solvers offered: each solves the paper's examples' min-norm QPs and the
degenerate batches of ``qdframe bench directions``. Another solver is offered once it
does (measure it, then add it here and to the backend tests)."""

NOT_OFFERED: dict[str, str] = {
    "highs": "fails rows of paper-7.1's QPs on 11 nodes ('not found', also one QP per row)",
    "clarabel": "fails rows of the degenerate batches ('not found'); use the direction 'clarabel'",
    "quadprog": "needs a positive definite Hessian; the min-norm QP's is singular in λ",
    "ecos": "needs a positive definite Hessian; the min-norm QP's is singular in λ",
}
"""Why a solver qpsolvers knows is not offered, where it was tried."""


def offered_solvers(qpsolvers: Any) -> list[str]:
    """The supported solvers that are installed, sorted."""
    return sorted(set(SUPPORTED) & set(qpsolvers.available_solvers))


@dataclass(frozen=True)
class QpsolversDirection(QPDirection):
    """Min-norm QPs by a qpsolvers solver: the name `qpsolvers:NAME` (e.g. qpsolvers:daqp)."""

    name = "qpsolvers:"
    solver: str = "daqp"
    rows_per_qp: int | None = None
    dense: bool | None = None
    settings: tuple[tuple[str, Any], ...] = ()

    @classmethod
    def from_name(cls, name: str) -> "QpsolversDirection":
        """`qpsolvers:NAME` → the direction with solver NAME."""
        _, _, solver = name.partition(":")
        return cls(solver=solver)

    def __post_init__(self) -> None:
        super().__post_init__()
        qpsolvers = require("qpsolvers", self.label, "'qdframe[qpsolvers]'")
        offered = offered_solvers(qpsolvers)
        if self.solver not in offered:
            if self.solver in SUPPORTED:
                raise BackendError(
                    f"direction {self.label!r} needs the solver {self.solver}: pip install 'qpsolvers[{self.solver}]'"
                    f" (installed and supported: {', '.join(offered) or 'none'})"
                )
            known = self.solver in qpsolvers.available_solvers or self.solver in NOT_OFFERED
            reason = NOT_OFFERED.get(self.solver, "not verified on the min-norm QPs") if known else None
            raise InputError("direction", f"qpsolvers:NAME with NAME one of: {', '.join(offered)}"
                             + (f" ({self.solver} is not offered: {reason})" if reason else ""), self.label)
        per_qp = self.rows_per_qp
        if per_qp is not None and (isinstance(per_qp, bool) or not isinstance(per_qp, int) or per_qp < 0):
            raise OptionError(type(self).__name__, "rows_per_qp", "none (the measured default) or an integer ≥ 0 "
                              "(0: all rows)", per_qp)

    @property
    def label(self) -> str:
        return f"qpsolvers:{self.solver}"

    def _rows_per_qp(self, qpsolvers) -> int:
        if self.rows_per_qp is not None:
            return self.rows_per_qp
        if self.solver in ROWS_PER_QP:
            return ROWS_PER_QP[self.solver]
        return 1 if self.solver not in qpsolvers.sparse_solvers else DEFAULT_STACK

    def _dense(self, qpsolvers, per_qp: int) -> bool:
        """Dense matrices for a dense-only solver or one-row QPs, unless `dense` says otherwise."""
        if self.dense is not None:
            return self.dense or self.solver not in qpsolvers.sparse_solvers
        return self.solver not in qpsolvers.sparse_solvers or (per_qp == 1 and self.solver in qpsolvers.dense_solvers)

    def solve_scaled(self, c: np.ndarray, a: np.ndarray, retry: bool = False) -> tuple[np.ndarray, list[str | None]]:
        qpsolvers = require("qpsolvers", self.label, "'qdframe[qpsolvers]'")
        rows, groups, width, dim = a.shape
        per_qp = 1 if retry else self._rows_per_qp(qpsolvers)
        per_qp = rows if per_qp == 0 else min(per_qp, rows)
        count = -(-rows // per_qp)
        padded = count * per_qp  # the last QP is padded with rows c = 0, a = 0 (solution p = 0)
        c_all = np.zeros((padded, dim))
        c_all[:rows] = c
        a_all = np.zeros((padded, groups, width, dim))
        a_all[:rows] = a
        (structure, rows_idx, cols_idx), _ = self.cached(
            ("qpsolvers", per_qp, groups, width, dim), lambda: _structure(per_qp, groups, width, dim), persistent=not retry
        )
        shape = (structure.n_equalities, structure.n_variables)
        data = np.broadcast_to(structure.template, (count, structure.template.size)).copy()
        data[:, structure.generator_slots] = (
            -a_all.reshape(count, per_qp, -1, dim).transpose(0, 1, 3, 2).reshape(count, -1)
        )
        rhs = np.concatenate([c_all, np.ones((padded, groups))], axis=1).reshape(count, -1)
        dense = self._dense(qpsolvers, per_qp)
        if dense:
            matrices = np.zeros((count,) + shape)
            matrices[:, rows_idx, cols_idx] = data
            P = structure.P.toarray()
        else:
            P = structure.P
        q = np.zeros(structure.n_variables)
        lower = structure.lower_bounds()
        settings = {**DEFAULT_SETTINGS.get(self.solver, {}), **(RETRY_SETTINGS.get(self.solver, {}) if retry else {})}
        settings.update(self.settings)
        lam = np.empty((padded, groups, width))
        status: list[str | None] = [None] * padded
        for i in range(count):
            part = slice(i * per_qp, (i + 1) * per_qp)
            A = matrices[i] if dense else _csc(structure, data[i], shape)
            problem = qpsolvers.Problem(P, q, None, None, A, rhs[i], lower, None)
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    solution = qpsolvers.solve_problem(problem, solver=self.solver, **settings)
            except Exception as exc:  # a solver that refuses the problem: a failure of these rows
                status[part] = [f"error {type(exc).__name__}: {exc}"] * per_qp
                lam[part] = np.nan
                continue
            if not solution.found or solution.x is None:
                status[part] = [_not_found(solution)] * per_qp
                lam[part] = np.nan
                continue
            lam[part] = structure.weights(np.asarray(solution.x, dtype=float))
        return lam[:rows], status[:rows]


def _structure(rows: int, groups: int, width: int, dim: int) -> tuple[BlockQP, np.ndarray, np.ndarray]:
    """The equality-only block QP and the (row, column) of each of its A entries (CSC order)."""
    structure = BlockQP.build(rows, groups, width, dim, bound_sign=0)
    columns = np.repeat(np.arange(structure.n_variables), np.diff(structure.indptr))
    return structure, structure.indices, columns


def _csc(structure: BlockQP, data: np.ndarray, shape: tuple[int, int]):
    import scipy.sparse as sp

    return sp.csc_matrix((data, structure.indices, structure.indptr), shape=shape)


def _not_found(solution: Any) -> str:
    """A qpsolvers Solution that was not found, as a status text with the solver's own status if any."""
    info = (getattr(solution, "extras", None) or {}).get("info")
    detail = getattr(info, "status", None)
    return "not found" + (f" ({detail})" if detail is not None else "")
