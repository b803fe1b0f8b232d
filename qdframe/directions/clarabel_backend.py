"""The `clarabel` direction: all min-norm QPs of a direction in one sparse Clarabel problem.

The rows are stacked block-diagonally (:class:`~qdframe.directions.qp.BlockQP`; in
chunks of `chunk_rows` rows, 0 = all at once) as A x + s = b with s in
ZeroCone(equalities) × NonnegativeCone(λ). The solver is built once per shape and chunk
(presolve off, structural zeros kept, so that ``is_data_update_allowed()``); later
directions only replace the values of A and b with ``update(A=..., b=...)``. Clarabel is
an interior-point method and takes no warm start. Tolerances are tight; any status but
``Solved`` (e.g. ``AlmostSolved``, ``MaxIterations``) is a failure of every row of the
chunk: such a row counts as solved only if its polished weights pass the per-row check
(:mod:`qdframe.directions.qp`); rows that fail are retried in chunks of `retry_chunk_rows`
with `retry_tolerances` (gap abs, gap rel, feas, ktratio). The polish is what certifies
the degenerate rows: on collinear generators, or where the minimum-norm point is 0 (no
strict complementarity), the interior point stalls near the optimum and a whole stack can
end ``AlmostSolved``, which the retry alone does not cure (docs/directions.md gives the
bench's counts). Needs ``pip install 'qdframe[clarabel]'``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import number_rule
from .qp import BlockQP, QPDirection, chunks, require


@dataclass(frozen=True)
class ClarabelDirection(QPDirection):
    """Min-norm QPs by Clarabel (interior point), stacked into one sparse conic QP."""

    name = "clarabel"
    tol_gap_abs: float = 1e-14
    tol_gap_rel: float = 1e-14
    tol_feas: float = 1e-13
    tol_ktratio: float = 1e-12
    max_iter: int = 200
    chunk_rows: int = 0
    retry_chunk_rows: int = 10
    retry_tolerances: tuple[float, float, float, float] = (1e-13, 1e-13, 1e-12, 1e-10)
    option_rules = {  # Clarabel's limits: max_iter is a u32; its tolerances must be positive to mean anything
        **QPDirection.option_rules,
        **{name: number_rule(above=0.0, why="a Clarabel tolerance")
           for name in ("tol_gap_abs", "tol_gap_rel", "tol_feas", "tol_ktratio")},
        "max_iter": number_rule(1, 2**32 - 1, integer=True, why="Clarabel's limit"),
        "chunk_rows": number_rule(0, integer=True, why="0: all rows in one QP"),
        "retry_chunk_rows": number_rule(0, integer=True, why="0: all failed rows in one QP"),
    }

    def __post_init__(self) -> None:
        super().__post_init__()
        require("clarabel", self.label, "'qdframe[clarabel]'")

    def solve_scaled(self, c: np.ndarray, a: np.ndarray, retry: bool = False) -> tuple[np.ndarray, list[str | None]]:
        clarabel = require("clarabel", self.label, "'qdframe[clarabel]'")
        rows, groups, width, dim = a.shape
        lam = np.empty((rows, groups, width))
        status: list[str | None] = [None] * rows
        for index, part in enumerate(chunks(rows, self.retry_chunk_rows if retry else self.chunk_rows)):
            size = part.stop - part.start
            key = ("clarabel", index, size, groups, width, dim)
            (structure, solver), fresh = self.cached(key, lambda: self._setup(clarabel, c[part], a[part], retry), persistent=not retry)
            if not fresh:
                solver.update(A=structure.A_data(a[part]), b=_rhs(structure, c[part]))
            solution = solver.solve()
            if solution.status != clarabel.SolverStatus.Solved:
                status[part] = [str(solution.status)] * size
            lam[part] = structure.weights(np.asarray(solution.x, dtype=float))
        return lam, status

    def _setup(self, clarabel, c: np.ndarray, a: np.ndarray, retry: bool = False):
        structure = BlockQP.build(*a.shape, bound_sign=-1)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.presolve_enable = False
        settings.input_sparse_dropzeros = False
        tolerances = (self.tol_gap_abs, self.tol_gap_rel, self.tol_feas, self.tol_ktratio)
        tolerances = self.retry_tolerances if retry else tolerances
        settings.tol_gap_abs, settings.tol_gap_rel, settings.tol_feas, settings.tol_ktratio = tolerances
        settings.max_iter = self.max_iter
        cones = [
            clarabel.ZeroConeT(structure.n_equalities),
            clarabel.NonnegativeConeT(structure.n_constraints - structure.n_equalities),
        ]
        solver = clarabel.DefaultSolver(
            structure.P, np.zeros(structure.n_variables), structure.A(a), _rhs(structure, c), cones, settings
        )
        return structure, solver


def _rhs(structure: BlockQP, c: np.ndarray) -> np.ndarray:
    """b: the equality rows' right-hand side, then 0 for −λ + s = 0."""
    return np.concatenate([structure.equality_rhs(c), np.zeros(structure.n_constraints - structure.n_equalities)])
