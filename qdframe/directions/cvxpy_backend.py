"""The `cvxpy` direction: the min-norm QPs as one DPP-parameterized CVXPY problem.

For `chunk_rows` rows (fewer if the batch is smaller; the last chunk is padded with rows
c = 0, a = 0) the problem

    minimize ½‖P‖²  subject to  P[:, j] = C[:, j] + Σ_k W_j[:, k] ∘ Λ[:, k] (every j),
                                Σ_{k ∈ g} Λ[:, k] = 1 (every group g),  Λ ≥ 0,

with parameters C (rows × d) and W_j (rows × K) is built once per shape; CVXPY compiles
it once (it is DPP) and every later chunk and direction only sets the parameter values
and re-solves. The solver is CVXPY's `solver` (default CLARABEL) with the tight
`solver_options` of ``DEFAULT_OPTIONS``. Any status but ``optimal`` (e.g.
``optimal_inaccurate``, which CVXPY only warns about) or a SolverError is a failure of
every row of the chunk, and every row is then checked and polished as
:mod:`qdframe.directions.qp` describes; failed rows are retried in chunks of `retry_chunk_rows`. Needs ``pip install 'qdframe[cvxpy]'``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from .base import OptionError, number_rule
from .qp import QPDirection, require

DEFAULT_OPTIONS: dict[str, dict[str, Any]] = {
    "CLARABEL": {"tol_gap_abs": 1e-13, "tol_gap_rel": 1e-13, "tol_feas": 1e-12, "tol_ktratio": 1e-10},
    "OSQP": {"eps_abs": 1e-10, "eps_rel": 1e-10, "polish": True, "max_iter": 100_000},
    "SCS": {"eps_abs": 1e-12, "eps_rel": 1e-12, "max_iters": 100_000},
    "PROXQP": {"eps_abs": 1e-13, "eps_rel": 0.0},
}
"""Tight options per CVXPY solver name (others get the solver's defaults). For CLARABEL
gap 1e-14 (as the `clarabel` direction uses) ended `optimal_inaccurate` on 8 of 10000 rows
through CVXPY; 1e-13 did not."""


@dataclass(frozen=True)
class CvxpyDirection(QPDirection):
    """Min-norm QPs as a DPP-parameterized CVXPY problem, compiled once per shape."""

    name = "cvxpy"
    solver: str = "CLARABEL"
    chunk_rows: int = 1000
    retry_chunk_rows: int = 10
    solver_options: tuple[tuple[str, Any], ...] = ()
    option_rules = {
        **QPDirection.option_rules,
        "chunk_rows": number_rule(0, integer=True, why="0: all rows in one problem"),
        "retry_chunk_rows": number_rule(0, integer=True, why="0: all failed rows in one problem"),
    }

    def __post_init__(self) -> None:
        super().__post_init__()
        cp = require("cvxpy", self.label, "'qdframe[cvxpy]'")
        installed = sorted(cp.installed_solvers())
        if self.solver.upper() not in installed:
            raise OptionError(type(self).__name__, "solver", f"a CVXPY solver installed here: {', '.join(installed)}",
                              self.solver)

    def solve_scaled(self, c: np.ndarray, a: np.ndarray, retry: bool = False) -> tuple[np.ndarray, list[str | None]]:
        cp = require("cvxpy", self.label, "'qdframe[cvxpy]'")
        rows, groups, width, dim = a.shape
        chunk = self.retry_chunk_rows if retry else self.chunk_rows
        size = rows if chunk <= 0 else min(chunk, rows)
        count = -(-rows // size)
        c_all = np.zeros((count * size, dim))
        c_all[:rows] = c
        v_all = np.zeros((count * size, groups * width, dim))
        v_all[:rows] = a.reshape(rows, -1, dim)
        (problem, center, columns, weights), _ = self.cached(
            ("cvxpy", size, groups, width, dim), lambda: _parameterized(cp, size, groups, width, dim), not retry
        )
        options = {**DEFAULT_OPTIONS.get(self.solver.upper(), {}), **dict(self.solver_options)}
        lam = np.empty((count * size, groups, width))
        status: list[str | None] = [None] * (count * size)
        for i in range(count):
            part = slice(i * size, (i + 1) * size)
            center.value = c_all[part]
            for j, parameter in enumerate(columns):
                parameter.value = v_all[part, :, j]
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    problem.solve(solver=self.solver, **options)
            except cp.error.SolverError as exc:
                status[part] = [f"SolverError: {exc}"] * size
                lam[part] = np.nan
                continue
            if problem.status != cp.OPTIMAL:
                status[part] = [str(problem.status)] * size
            value = weights.value
            lam[part] = np.nan if value is None else np.asarray(value).reshape(size, groups, width)
        return lam[:rows], status[:rows]


def _parameterized(cp, rows: int, groups: int, width: int, dim: int) -> tuple[Any, Any, list[Any], Any]:
    """The DPP problem of `rows` rows and its parameters C, [W_j], variable Λ."""
    count = groups * width
    center = cp.Parameter((rows, dim))
    columns = [cp.Parameter((rows, count)) for _ in range(dim)]
    weights = cp.Variable((rows, count), nonneg=True)
    point = cp.Variable((rows, dim))
    constraints = [point[:, j] == center[:, j] + cp.sum(cp.multiply(columns[j], weights), axis=1) for j in range(dim)]
    constraints += [cp.sum(weights[:, g * width : (g + 1) * width], axis=1) == 1 for g in range(groups)]
    problem = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(point)), constraints)
    return problem, center, columns, weights
