"""The sparse symmetric KKT systems of the `gauss-newton` step.

Every linear solve of a step is one system

    [ H  Cᵀ ] [ d ]   [ −g ]
    [ C  0  ] [ ν ] = [  c ]

with H = λJᵀJ + μW (+ the active hinges' λAᵀA) positive definite on the null space of
the constraint rows C (the scheme's recursion, the fixed start, and any ties the step
adds), ν their multipliers. This module is the one place that factors it.

H alone may be near singular (its diagonal goes down to μ·w_k ≈ 1e-13 on 7.3), so the
factorization pivots (SuperLU, partial pivoting): an LDLᵀ without pivoting loses up to
1e-5 of accuracy there. Two things make SuperLU cheaper than a fresh `spsolve`:

* **Row matching.** Each constraint row i trades places with the row of one column j(i)
  where C has a large entry (the recursion's dZ_p, the start's dx_0 and dZ_0): the
  matrix then has a nonzero diagonal (C_ij on both), and SuperLU runs in its symmetric
  mode, pivoting on the diagonal where it is within 1/10 of the column's largest entry
  (`PIVOT_THRESHOLD`): the column order then orders rows too, and the fill is lower.
* **Ordering once.** The fill-reducing column order (COLAMD) is computed at the first
  factorization of a :class:`KKTSolver` and reused for every later system of the same
  shape and constraint pattern (the active-set loop's refactors, the later iterations of
  one solve): each reuse is a numerical factorization only. A reused order whose factors
  grow past `REANALYSE_GROWTH` times the analysed ones (SuperLU's pivots left the diagonal
  it was analysed for) is not reused again in that solve: every later system is analysed
  afresh, which costs a COLAMD per system and not a fill-in 10× the fresh one. (gauss-newton
  keeps C's pattern through its guesses: a cost piece that leaves the tie keeps its row,
  with zero coefficients.)
* **One column per panel.** SuperLU's panels (`PANEL_SIZE` columns updated together, a
  dense work array of panel × rows) pay on wide dense fronts; these systems' columns are
  short, and on the paper's examples a panel of one column factors faster and needs less
  working memory than SuperLU's default (docs/benchmarks.md has the figures).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import maximum_bipartite_matching

from ..errors import BackendError

PIVOT_THRESHOLD = 0.1  # SuperLU's diag_pivot_thresh: a diagonal pivot within 1/10 of the column's largest
MATCH_FRACTION = 0.5  # a constraint row is matched to a column holding at least half its largest entry
REANALYSE_GROWTH = 1.5  # a reused order whose L + U outgrow the analysed ones by this is recomputed
PANEL_SIZE = 1  # SuperLU's panel width (its default 10 costs time and memory on these short columns)


class KKTSolver:
    """Factors the KKT systems of one solve, reusing the symbolic analysis between them.

    The analysis (the row matching and the column order) belongs to a shape and a
    constraint matrix; a system with another shape or another C pattern is analysed
    afresh. :func:`solve_kkt` with ``solver=None`` analyses every system.
    """

    def __init__(self) -> None:
        self._key: tuple | None = None
        self._rows: np.ndarray | None = None  # position of each row of K in the matched matrix
        self._order: np.ndarray | None = None  # the column (and row) order of the matched matrix
        self._factor_nnz = 0
        self._reuse = True  # False once a reused order filled in past REANALYSE_GROWTH
        self.analyses = 0  # how many fill-reducing orders were computed (for tests and benchmarks)
        self.factorizations = 0

    def solve(self, hessian: sp.spmatrix, constraints: sp.spmatrix, gradient: np.ndarray,
              rhs: np.ndarray | None = None, soft: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        size, count = hessian.shape[0], constraints.shape[0]
        constraints = sp.csr_matrix(constraints)
        if not self._same(size, constraints):
            self._key = (size, constraints.indptr.copy(), constraints.indices.copy())
            self._rows, self._order = _matching(constraints, size), None
        right = np.concatenate([-gradient, np.zeros(count) if rhs is None else rhs])
        rows = self._rows  # an involution: each matched pair trades places, so it is its own inverse
        order = self._order
        kkt = _assemble(hessian, constraints, rows, order, soft)
        if order is None:  # the analysis: SuperLU's COLAMD on the matched matrix, kept for later systems
            factor = _factor(kkt, "COLAMD")
            self._order = np.argsort(factor.perm_c) if self._reuse else None
            self._factor_nnz = factor.nnz  # L + U (not .L, .U: those build copies)
            self.analyses += 1
            solution = factor.solve(right[rows])
        else:
            factor = _factor(kkt, "NATURAL")
            if factor.nnz > REANALYSE_GROWTH * self._factor_nnz:
                # the pivots left the analysed order (the values, not the pattern, moved): reusing it
                # again would fill in as much, so every later system of this solve is analysed afresh
                self._order, self._reuse = None, False
            solution = np.empty(size + count)
            solution[order] = factor.solve(right[rows[order]])
        self.factorizations += 1
        del factor, kkt
        if not np.all(np.isfinite(solution)):
            raise BackendError("direction 'gauss-newton': the sparse KKT solve returned non-finite values")
        return solution[:size], solution[size:]

    def _same(self, size: int, constraints: sp.csr_matrix) -> bool:
        """Whether the analysis at hand is of this shape and constraint pattern."""
        if self._key is None or self._key[0] != size:
            return False
        _, indptr, indices = self._key
        return np.array_equal(indptr, constraints.indptr) and np.array_equal(indices, constraints.indices)


def solve_kkt(hessian: sp.spmatrix, constraints: sp.spmatrix, gradient: np.ndarray,
              rhs: np.ndarray | None = None, soft: np.ndarray | None = None,
              solver: KKTSolver | None = None) -> tuple[np.ndarray, np.ndarray]:
    """d and ν of the system above (rhs: c, zeros when None). solver: a :class:`KKTSolver`
    whose analysis from earlier systems of the same shape and constraints is reused.

    soft: ε ≥ 0 per constraint row, the block −diag(ε) in place of 0 (C d − εν = c): a row
    with ε > 0 holds to ε·ν, and rows that depend on others no longer make K singular."""
    return (solver or KKTSolver()).solve(hessian, constraints, gradient, rhs, soft)


def _matching(constraints: sp.csr_matrix, size: int) -> np.ndarray:
    """rows[r]: the position of row r of K in the matched matrix. Constraint row i (row
    size + i of K) takes the place of the row of a column j(i) with |C_ij| ≥ ½·max_j |C_ij|,
    distinct columns for distinct rows (a maximum bipartite matching); that row takes row
    size + i's place. Rows left unmatched keep theirs (SuperLU pivots off the diagonal there)."""
    count = constraints.shape[0]
    rows = np.arange(size + count)
    if count == 0:
        return rows
    magnitude = abs(constraints)
    largest = magnitude.max(axis=1).toarray().ravel()
    magnitude.data = (magnitude.data >= MATCH_FRACTION * np.repeat(largest, np.diff(magnitude.indptr))
                      ) & (magnitude.data > 0)
    magnitude.eliminate_zeros()
    match = maximum_bipartite_matching(sp.csr_matrix(magnitude, dtype=np.int8), perm_type="column")
    matched = np.flatnonzero(match >= 0)
    rows[size + matched] = match[matched]
    rows[match[matched]] = size + matched
    return rows


def _assemble(hessian: sp.spmatrix, constraints: sp.csr_matrix, rows: np.ndarray,
              order: np.ndarray | None, soft: np.ndarray | None = None) -> sp.csc_matrix:
    """The KKT matrix with row r at rows[r], and then, given an order, rows and columns
    permuted symmetrically by it (entry (a, b) of the result: entry (order[a], order[b])
    of the matched matrix), built once from triplets (no intermediate block copies)."""
    size = hessian.shape[0]
    h = sp.coo_matrix(hessian)
    c = constraints.tocoo()
    total = size + constraints.shape[0]
    index = np.int32 if total < 2**31 - 1 else np.int64
    position = np.arange(total, dtype=index)
    if order is not None:
        position[order] = np.arange(total, dtype=index)
    row_at, col_at = position[rows], position  # where row r and column c of K end up
    row = [row_at[h.row], row_at[size + c.row], row_at[c.col]]
    col = [col_at[h.col], col_at[c.col], col_at[size + c.row]]
    data = [h.data, c.data, c.data]
    if soft is not None and np.any(soft):  # −ε_i at (size + i, size + i)
        i = np.flatnonzero(soft)
        row.append(row_at[size + i])
        col.append(col_at[size + i])
        data.append(-soft[i])
    row, col, data = np.concatenate(row), np.concatenate(col), np.concatenate(data)
    del h, c
    return sp.csc_matrix((data, (row, col)), shape=(total, total))


def _factor(kkt: sp.csc_matrix, ordering: str):
    try:
        return spla.splu(kkt, permc_spec=ordering, diag_pivot_thresh=PIVOT_THRESHOLD, panel_size=PANEL_SIZE,
                         options={"SymmetricMode": True})
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise BackendError(f"direction 'gauss-newton': the sparse KKT factorization failed ({exc})") from exc
