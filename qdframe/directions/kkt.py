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
  afresh, which costs a COLAMD per system and not a fill-in 10× the fresh one. A system
  with more than `REUSE_ENTRIES` times the analysed one's entries is analysed afresh before
  it is factored: that is another pattern of H (the exact selections' rows after a band
  start), whose fill under the old order REANALYSE_GROWTH would catch only after paying
  for it (docs/benchmarks.md, "The KKT solve"). (gauss-newton keeps C's pattern through its
  guesses: a cost piece that leaves the tie keeps its row, with zero coefficients.)
* **Dense columns bordered.** A free start value x_i(0), an unknown parameter or a free T
  (:mod:`qdframe.unknowns`) is a column of H with an entry in every node's υ row. Factored
  in place, SuperLU's fill depends on whether its diagonal pivot is accepted, and swings
  by more than 10× between two systems of the same pattern (docs/benchmarks.md). Such columns
  (`_dense_columns`) are bordered instead: the rest K_RR is factored as above (banded),
  and the |D| × |D| Schur complement K_DD − K_DR·K_RR⁻¹·K_RD is solved densely: one
  solve with |D| + 1 right-hand sides of one factorization. gauss-newton hands H over
  split (:class:`Bordered`, its constant states last); a whole H is split here
  (`Bordered.cut`); C is cut by a mask on its index array (`_without`: no COO round trip,
  no sort), and the right-hand sides are permuted a column at a time (`_permuted_solve`).
* **One column per panel.** SuperLU's panels (`PANEL_SIZE` columns updated together, a
  dense work array of panel × rows) pay on wide dense fronts; these systems' columns are
  short, and on the paper's examples a panel of one column factors faster and needs less
  working memory than SuperLU's default (docs/benchmarks.md has the figures).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import maximum_bipartite_matching

from ..errors import BackendError

PIVOT_THRESHOLD = 0.1  # SuperLU's diag_pivot_thresh: a diagonal pivot within 1/10 of the column's largest
MATCH_FRACTION = 0.5  # a constraint row is matched to a column holding at least half its largest entry
REANALYSE_GROWTH = 1.5  # a reused order whose L + U outgrow the analysed ones by this is recomputed
REUSE_ENTRIES = 1.2  # a system with more entries than this times the analysed one's is analysed afresh
PANEL_SIZE = 1  # SuperLU's panel width (its default 10 costs time and memory on these short columns)
DENSE_FACTOR = 10  # a Hessian column with more than this ·√size entries is bordered (_dense_columns) …
DENSE_MIN = 1000  # … and more than this many
MAX_BORDER = 16  # at most this many bordered columns (the densest)


class Bordered(NamedTuple):
    """A symmetric H with the columns D (and their rows) apart: H_RR (`inner`, sparse), H_RD
    (`coupling`, dense, R's rows × |D|) and H_DD (`corner`). Given to :meth:`KKTSolver.solve`,
    D are its last |D| columns; gauss-newton's reduced H comes so (its constant states)."""

    inner: sp.csc_matrix
    coupling: np.ndarray
    corner: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        size = self.inner.shape[0] + self.corner.shape[0]
        return size, size

    @classmethod
    def cut(cls, hessian: sp.csc_matrix, dense: np.ndarray) -> "Bordered":
        """H (CSC) split at its columns `dense`."""
        keep = np.ones(hessian.shape[0], dtype=bool)
        keep[dense] = False
        cut = hessian.shape[0] - dense.size
        position = None
        if dense[0] != cut:  # not the last columns: R's renumbered
            position = np.full(keep.size, -1, dtype=hessian.indices.dtype)
            position[keep] = np.arange(cut, dtype=position.dtype)
        columns = hessian[:, dense].toarray()
        return cls(_without(hessian, keep, position, square=True), columns[keep], columns[dense])

    def plus(self, rows: sp.csr_matrix, weight: float) -> "Bordered":
        """H + weight·AᵀA, A (`rows`) on the same columns, D last."""
        cut = self.inner.shape[0]
        inner = _without(sp.csr_matrix(rows), np.arange(self.shape[0]) < cut, None)
        outer = rows[:, cut:].toarray()
        return Bordered((self.inner + weight * (inner.T @ inner)).tocsc(), self.coupling + weight * (inner.T @ outer),
                        self.corner + weight * (outer.T @ outer))


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
        self._gather: np.ndarray | None = None  # rows[order]: the row of K at each place of the ordered matrix
        self._factor_nnz = 0
        self._entries = 0  # K's entries at the analysis (H's and C's twice, as assembled)
        self._reuse = True  # False once a reused order filled in past REANALYSE_GROWTH
        self.analyses = 0  # how many fill-reducing orders were computed (for tests and benchmarks)
        self._triplets: dict[str, np.ndarray] = {}  # _assemble's (row, col, data) arrays, kept between systems
        self.factorizations = 0

    def solve(self, hessian: sp.spmatrix, constraints: sp.spmatrix, gradient: np.ndarray,
              rhs: np.ndarray | None = None, soft: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        size, count = hessian.shape[0], constraints.shape[0]
        constraints = sp.csr_matrix(constraints)
        right = np.concatenate([-gradient, np.zeros(count) if rhs is None else rhs])
        if isinstance(hessian, Bordered):  # bordered by the caller: its last columns
            dense = np.arange(hessian.inner.shape[0], size)
        else:
            hessian = sp.csc_matrix(hessian)
            dense = _dense_columns(hessian)
        if not dense.size:
            solution = self._factored(hessian, constraints, soft)(right)
        else:
            bordered = hessian if isinstance(hessian, Bordered) else Bordered.cut(hessian, dense)
            solution = self._bordered(bordered, constraints, soft, right, dense)
        if not np.all(np.isfinite(solution)):
            raise BackendError("direction 'gauss-newton': the sparse KKT solve returned non-finite values")
        return solution[:size], solution[size:]

    def _bordered(self, hessian: "Bordered", constraints: sp.csr_matrix, soft: np.ndarray | None,
                  right: np.ndarray, dense: np.ndarray) -> np.ndarray:
        """The system with the dense columns D (and their rows) bordered: K_RR factored as any
        system, then the Schur complement S = K_DD − K_DRK_RR⁻¹K_RD (|D| × |D|) solved densely.
        H comes split (:class:`Bordered`), C is cut by a mask on its index array (`_without`),
        and K_RR⁻¹[right | K_RD] is one solve with |D| + 1 right-hand sides. Where D are the
        last columns (gauss-newton puts the constant states there) R's keep their numbers."""
        size, count = right.size - constraints.shape[0], constraints.shape[0]
        keep = np.ones(size, dtype=bool)
        keep[dense] = False
        cut = size - dense.size
        if dense[0] == cut:  # D trailing: R's rows of K are K's without rows cut … size − 1
            position, inner = None, None
        else:
            position = np.full(size, -1, dtype=constraints.indices.dtype)  # each column's place among R's
            position[keep] = np.arange(cut, dtype=position.dtype)
            inner = np.concatenate([np.flatnonzero(keep), size + np.arange(count)])
        c_rr = _without(constraints, keep, position)
        stacked = np.empty((cut + count, 1 + dense.size), order="F")  # [right_R | K_RD]: H's rows of R, then C's
        if inner is None:
            stacked[:cut, 0], stacked[cut:, 0] = right[:cut], right[size:]
        else:
            stacked[:, 0] = right[inner]
        stacked[:cut, 1:] = hessian.coupling
        stacked[cut:, 1:] = constraints[:, dense].toarray() if c_rr.nnz < constraints.nnz else 0.0  # C's entries in D
        coupling = stacked[:, 1:]
        solve = self._factored(hessian.inner, c_rr, soft)
        both = solve(stacked)
        first, through = both[:, 0], both[:, 1:]
        schur = hessian.corner - coupling.T @ through
        try:
            border = np.linalg.solve(schur, right[dense] - coupling.T @ first)
        except np.linalg.LinAlgError as exc:
            raise BackendError(f"direction 'gauss-newton': the bordered KKT solve failed ({exc})") from exc
        inside = first
        for j in range(border.size):  # first − through·border in place (no array of K's size)
            inside -= through[:, j] * border[j]
        solution = np.empty(right.size)
        if inner is None:
            solution[:cut], solution[size:] = inside[:cut], inside[cut:]
        else:
            solution[inner] = inside
        solution[dense] = border
        return solution

    def _factored(self, hessian: sp.csc_matrix, constraints: sp.csr_matrix, soft: np.ndarray | None):
        """K factored (the analysis reused where it applies): a function of right-hand sides
        (one, or one per column) returning K⁻¹·right."""
        size = hessian.shape[0]
        if not self._same(size, constraints):
            self._key = (size, constraints.indptr.copy(), constraints.indices.copy())
            self._rows, self._order = _matching(constraints, size), None
        rows = self._rows  # an involution: each matched pair trades places, so it is its own inverse
        entries = hessian.nnz + 2 * constraints.nnz
        if self._order is not None and entries > REUSE_ENTRIES * self._entries:  # another H pattern: not its order
            self._order = None
        order, gather = self._order, self._gather
        kkt = _assemble(hessian, constraints, rows, order, soft, self._triplets)
        self.factorizations += 1
        if order is None:  # the analysis: SuperLU's COLAMD on the matched matrix, kept for later systems
            factor = _factor(kkt, "COLAMD")
            self._order = np.argsort(factor.perm_c) if self._reuse else None
            self._gather = None if self._order is None else rows[self._order]  # K's row at each place
            self._factor_nnz = factor.nnz  # L + U (not .L, .U: those build copies)
            self._entries = entries
            self.analyses += 1
            return lambda right: _permuted_solve(factor, right, rows, None)
        factor = _factor(kkt, "NATURAL")
        if factor.nnz > REANALYSE_GROWTH * self._factor_nnz:
            # the pivots left the analysed order (the values, not the pattern, moved): reusing it
            # again would fill in as much, so every later system of this solve is analysed afresh
            self._order, self._reuse = None, False
        return lambda right: _permuted_solve(factor, right, gather, order)

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


def _dense_columns(hessian: sp.csc_matrix) -> np.ndarray:
    """The columns of H with more than DENSE_FACTOR·√size entries (at most MAX_BORDER, the
    densest): a free start value x_i(0), a parameter or a free T, which every node's υ row
    holds. Factored in place they make SuperLU's fill depend on its pivots (the diagonal
    rejected once, the fill can grow 30×); bordered, the rest factors as a banded system."""
    counts = np.diff(hessian.indptr)
    limit = max(DENSE_MIN, DENSE_FACTOR * np.sqrt(hessian.shape[0]))
    dense = np.flatnonzero(counts > limit)
    return np.sort(dense[np.argsort(counts[dense])[::-1][:MAX_BORDER]])


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


def _permuted_solve(factor, right: np.ndarray, gather: np.ndarray, order: np.ndarray | None) -> np.ndarray:
    """K⁻¹·right from the factors of K with its rows at `gather` and then, given an order, rows
    and columns in that order (:func:`_assemble`): right's rows gathered, the solution's
    scattered back to `order`, one column at a time (a 2-D fancy index is several times slower)."""
    columns = right.reshape(right.shape[0], -1)
    permuted = np.empty(columns.shape, order="F")
    for j in range(columns.shape[1]):
        np.take(columns[:, j], gather, out=permuted[:, j])
    solved = factor.solve(permuted if right.ndim == 2 else permuted[:, 0]).reshape(columns.shape, order="F")
    if order is not None:  # scattered into `permuted`, which SuperLU copied (no new array of K's size)
        for j in range(columns.shape[1]):
            permuted[order, j] = solved[:, j]
        solved = permuted
    return solved if right.ndim == 2 else solved[:, 0]


def _without(matrix: sp.spmatrix, keep: np.ndarray, position: np.ndarray | None, square: bool = False) -> sp.spmatrix:
    """A CSR matrix's columns `keep`, or (`square`) a symmetric CSC matrix's rows and columns
    `keep`, renumbered by `position` (None: the dropped ones are the last, the rest keep their
    numbers): the index array masked, the pointers read off the mask's running count (indices
    stay sorted). A CSR matrix with no entry to drop comes back with its own arrays."""
    cut = int(np.count_nonzero(keep))
    inside = matrix.indices < cut if position is None else keep[matrix.indices]
    for column in np.flatnonzero(~keep) if square else ():  # the few D columns: all their entries out
        inside[matrix.indptr[column]: matrix.indptr[column + 1]] = False
    if not square and position is None and inside.all():
        return sp.csr_matrix((matrix.data, matrix.indices, matrix.indptr), shape=(matrix.shape[0], cut))
    running = np.zeros(inside.size + 1, dtype=matrix.indptr.dtype)
    np.cumsum(inside, out=running[1:])
    indices = matrix.indices[inside]
    if position is not None:
        indices = position[indices]
    if not square:  # CSR: every row, some columns
        return sp.csr_matrix((matrix.data[inside], indices, running[matrix.indptr]), shape=(matrix.shape[0], cut))
    kept = np.flatnonzero(keep)
    indptr = running[matrix.indptr[np.concatenate([[0], kept + 1])]]
    return sp.csc_matrix((matrix.data[inside], indices, indptr), shape=(cut, cut))


def _assemble(hessian: sp.spmatrix, constraints: sp.csr_matrix, rows: np.ndarray,
              order: np.ndarray | None, soft: np.ndarray | None = None,
              kept: dict[str, np.ndarray] | None = None) -> sp.csc_matrix:
    """The KKT matrix with row r at rows[r], and then, given an order, rows and columns
    permuted symmetrically by it (entry (a, b) of the result: entry (order[a], order[b])
    of the matched matrix), built once from triplets (no intermediate block copies). `kept`:
    the triplet arrays of the last system, reused where they are large enough (the systems of
    a solve have about the same size: no memory paged in afresh for each)."""
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
    row, col, data = (_joined(parts, name, kept) for parts, name in ((row, "row"), (col, "col"), (data, "data")))
    del h, c
    return sp.csc_matrix((data, (row, col)), shape=(total, total))


def _joined(parts: list[np.ndarray], name: str, kept: dict[str, np.ndarray] | None) -> np.ndarray:
    """np.concatenate(parts), into kept[name] where that is large enough (grown otherwise)."""
    size = sum(part.size for part in parts)
    if kept is None:
        return np.concatenate(parts)
    store = kept.get(name)
    if store is None or store.size < size or store.dtype != parts[0].dtype:
        store = kept[name] = np.empty(size + size // 8, dtype=parts[0].dtype)
    return np.concatenate(parts, out=store[:size])


def _factor(kkt: sp.csc_matrix, ordering: str):
    try:
        return spla.splu(kkt, permc_spec=ordering, diag_pivot_thresh=PIVOT_THRESHOLD, panel_size=PANEL_SIZE,
                         options={"SymmetricMode": True})
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise BackendError(f"direction 'gauss-newton': the sparse KKT factorization failed ({exc})") from exc
