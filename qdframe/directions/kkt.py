"""The sparse symmetric KKT systems of the `gauss-newton` step.

Every linear solve of a step is one system

    [ H  Cᵀ ] [ d ]   [ −g ]
    [ C  0  ] [ ν ] = [  c ]

with H = λJᵀJ + μW (+ the active hinges' λAᵀA) positive definite on the null space of
the constraint rows C (the scheme's recursion, the fixed start, and any ties the step
adds), ν their multipliers. This module is the one place that factors it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import BackendError


def solve_kkt(hessian: sp.spmatrix, constraints: sp.spmatrix, gradient: np.ndarray,
              rhs: np.ndarray | None = None, soft: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """d and ν of the system above (rhs: c, zeros when None), by SuperLU (COLAMD ordering).

    soft: ε ≥ 0 per constraint row, the block −diag(ε) in place of 0 (C d − εν = c): a row
    with ε > 0 holds to ε·ν, and rows that depend on others no longer make K singular."""
    size, rows = hessian.shape[0], constraints.shape[0]
    corner = None if soft is None or not np.any(soft) else -sp.diags(soft)
    kkt = sp.bmat([[hessian, constraints.T], [constraints, corner]], format="csc")
    right = np.concatenate([-gradient, np.zeros(rows) if rhs is None else rhs])
    solution = spla.spsolve(kkt, right)
    if not np.all(np.isfinite(solution)):
        raise BackendError("direction 'gauss-newton': the sparse KKT solve returned non-finite values")
    return solution[:size], solution[size:]
