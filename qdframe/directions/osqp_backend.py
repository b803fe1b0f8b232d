"""The `osqp` direction: all min-norm QPs of a direction in one sparse OSQP problem.

The rows are stacked block-diagonally (:class:`~qdframe.directions.qp.BlockQP`; in
chunks of `chunk_rows` rows, 0 = all at once). The OSQP workspace is set up once per
shape and chunk; later directions only replace the values of A and the bounds
(``update(Ax=..., l=..., u=...)``) and start from the previous solution (OSQP's
``warm_starting``). ADMM runs to eps 1e-6 and the solution is then polished (OSQP's
active-set refinement, with 20 refinement steps), which makes it exact once the active
set is right; anything but the status ``solved`` is a failure of every row of the chunk,
and every row is then checked and polished as :mod:`qdframe.directions.qp` describes (OSQP's
refinement ends a few rows of the degenerate batches with the active set off by a
near-active entry; the exact polish repairs them). Rows that still fail are solved again
with eps `retry_eps` = 1e-12. ADMM is not simply run to a tight eps because it converges
slowly where the minimum-norm point is 0 (zero multipliers, no strict complementarity):
there a tight eps takes many times the iterations of a loose eps with polish, or ends
``solved inaccurate``, while eps 1e-6 + polish is exact. Needs
``pip install 'qdframe[osqp]'``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .base import OptionError, number_rule
from .qp import BlockQP, QPDirection, chunks, require


@dataclass(frozen=True)
class OsqpDirection(QPDirection):
    """Min-norm QPs by OSQP (ADMM + polishing), stacked into one sparse QP, warm-started."""

    name = "osqp"
    eps_abs: float = 1e-6
    eps_rel: float = 1e-6
    retry_eps: float = 1e-12
    max_iter: int = 100_000
    polishing: bool = True
    polish_refine_iter: int = 20
    chunk_rows: int = 0
    settings: tuple[tuple[str, Any], ...] = ()
    option_rules = {  # OSQP's own limits (its settings check; max_iter is a C int)
        **QPDirection.option_rules,
        "eps_abs": number_rule(0.0, why="OSQP's limit"),
        "eps_rel": number_rule(0.0, why="OSQP's limit"),
        "retry_eps": number_rule(above=0.0, why="OSQP's eps_abs and eps_rel of the retry"),
        "max_iter": number_rule(1, 2**31 - 1, integer=True, why="OSQP's limit"),
        "polish_refine_iter": number_rule(0, 2**31 - 1, integer=True, why="OSQP's limit"),
        "chunk_rows": number_rule(0, integer=True, why="0: all rows in one QP"),
    }

    def __post_init__(self) -> None:
        super().__post_init__()
        require("osqp", self.label, "'qdframe[osqp]'")

    def check_options(self) -> None:
        super().check_options()
        if self.eps_abs == 0 and self.eps_rel == 0:
            raise OptionError(type(self).__name__, "eps_abs", "a number > 0 when eps_rel = 0 (OSQP's limit)", 0.0)

    def solve_scaled(self, c: np.ndarray, a: np.ndarray, retry: bool = False) -> tuple[np.ndarray, list[str | None]]:
        osqp = require("osqp", self.label, "'qdframe[osqp]'")
        rows, groups, width, dim = a.shape
        lam = np.empty((rows, groups, width))
        status: list[str | None] = [None] * rows
        for index, part in enumerate(chunks(rows, self.chunk_rows)):
            size = part.stop - part.start
            key = ("osqp", index, size, groups, width, dim)
            (structure, solver), fresh = self.cached(key, lambda: self._setup(osqp, c[part], a[part], retry), persistent=not retry)
            if not fresh:
                lower, upper = _bounds(structure, c[part])
                solver.update(Ax=structure.A_data(a[part]), l=lower, u=upper)
            result = solver.solve(raise_error=False)
            if result.info.status_val != osqp.SolverStatus.OSQP_SOLVED:
                status[part] = [str(result.info.status)] * size
            x = result.x if result.x is not None else np.full(structure.n_variables, np.nan)
            lam[part] = structure.weights(np.asarray(x, dtype=float))
        return lam, status

    def _setup(self, osqp, c: np.ndarray, a: np.ndarray, retry: bool):
        structure = BlockQP.build(*a.shape, bound_sign=+1)
        solver = osqp.OSQP()
        solver.setup(
            structure.P,
            np.zeros(structure.n_variables),
            structure.A(a),
            *_bounds(structure, c),
            verbose=False,
            eps_abs=self.retry_eps if retry else self.eps_abs,
            eps_rel=self.retry_eps if retry else self.eps_rel,
            max_iter=self.max_iter,
            polishing=self.polishing,
            polish_refine_iter=self.polish_refine_iter,
            warm_starting=True,
            **dict(self.settings),
        )
        return structure, solver


def _bounds(structure: BlockQP, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """l and u: the equality rows' right-hand side, then 0 ≤ λ."""
    rhs = structure.equality_rhs(c)
    count = structure.rows * structure.groups * structure.width
    return np.concatenate([rhs, np.zeros(count)]), np.concatenate([rhs, np.full(count, np.inf)])
