"""The `osqp` direction: all min-norm QPs of a direction in one sparse OSQP problem.

The rows are stacked block-diagonally (:class:`~qdframe.directions.qp.BlockQP`; in
chunks of `chunk_rows` rows, 0 = all at once). The OSQP workspace is set up once per
shape and chunk; later directions only replace the values of A and the bounds
(``update(Ax=..., l=..., u=...)``) and start from the previous solution (OSQP's
``warm_starting``). Tolerances are tight and the solution is polished (an active-set
refinement); anything but the status ``solved`` is a failure of every row of the chunk,
and every row is then checked as :mod:`qdframe.directions.qp` describes. Needs
``pip install 'qdframe[osqp]'``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .qp import BlockQP, QPDirection, chunks, require


@dataclass(frozen=True)
class OsqpDirection(QPDirection):
    """Min-norm QPs by OSQP (ADMM + polishing), stacked into one sparse QP, warm-started."""

    name = "osqp"
    eps_abs: float = 1e-10
    eps_rel: float = 1e-10
    max_iter: int = 100_000
    polishing: bool = True
    chunk_rows: int = 0

    def __post_init__(self) -> None:
        super().__post_init__()
        require("osqp", self.label, "'qdframe[osqp]'")

    def solve_scaled(self, c: np.ndarray, a: np.ndarray, persistent: bool = True) -> tuple[np.ndarray, list[str | None]]:
        osqp = require("osqp", self.label, "'qdframe[osqp]'")
        rows, groups, width, dim = a.shape
        lam = np.empty((rows, groups, width))
        status: list[str | None] = [None] * rows
        for index, part in enumerate(chunks(rows, self.chunk_rows)):
            size = part.stop - part.start
            key = ("osqp", index, size, groups, width, dim)
            (structure, solver), fresh = self.cached(key, lambda: self._setup(osqp, c[part], a[part]), persistent)
            if not fresh:
                lower, upper = _bounds(structure, c[part])
                solver.update(Ax=structure.A_data(a[part]), l=lower, u=upper)
            result = solver.solve(raise_error=False)
            if result.info.status_val != osqp.SolverStatus.OSQP_SOLVED:
                status[part] = [str(result.info.status)] * size
            x = result.x if result.x is not None else np.full(structure.n_variables, np.nan)
            lam[part] = structure.weights(np.asarray(x, dtype=float))
        return lam, status

    def _setup(self, osqp, c: np.ndarray, a: np.ndarray):
        structure = BlockQP.build(*a.shape, bound_sign=+1)
        solver = osqp.OSQP()
        solver.setup(
            structure.P,
            np.zeros(structure.n_variables),
            structure.A(a),
            *_bounds(structure, c),
            verbose=False,
            eps_abs=self.eps_abs,
            eps_rel=self.eps_rel,
            max_iter=self.max_iter,
            polishing=self.polishing,
            warm_starting=True,
        )
        return structure, solver


def _bounds(structure: BlockQP, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """l and u: the equality rows' right-hand side, then 0 ≤ λ."""
    rhs = structure.equality_rhs(c)
    count = structure.rows * structure.groups * structure.width
    return np.concatenate([rhs, np.zeros(count)]), np.concatenate([rhs, np.full(count, np.inf)])
