"""Sparse matrices of the `gauss-newton` step, assembled row block by row block.

The Jacobian J, the hinge rows and the constraints E of :mod:`.gauss_newton` come in
blocks of consecutive rows (one residual per node, say) with a few entries each. Built
through SciPy's COO format, every entry first costs two int64 indices and a copy per
concatenation and conversion, and the many entries that are exactly zero (a piece's
gradient is zero in most of the columns of y = (x, u, λ); −√w·0 on a given x(t_0)) are
kept as explicit zeros: at N = 1e5 on paper-7.3, two thirds of J's 12 million entries.

:class:`RowBlocks` turns each block into compressed rows as it arrives, in the canonical
form SciPy's conversion gives (column indices sorted within a row, duplicates summed
from left to right: the same sum as SciPy's for an entry given twice, the most these
matrices have, x_0's column in υ's first rows), keeps only the nonzero entries, with
32-bit indices where they fit.
Products with the matrix are then bit for bit those with SciPy's matrix: an entry that
is exactly zero only ever adds an exact zero to a sum of finite numbers (and SciPy's
sparse products drop zero results anyway).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


CHUNK = 1 << 15  # rows sorted at a time by RowBlocks.add


class RowBlocks:
    """A CSR matrix with `columns` columns, one block of rows at a time (see the module)."""

    def __init__(self, columns: int) -> None:
        self.columns = columns
        self.rows = 0
        self._counts: list[np.ndarray] = []
        self._indices: list[np.ndarray] = []
        self._data: list[np.ndarray] = []

    def add(self, cols: np.ndarray, vals: np.ndarray) -> np.ndarray:
        """Append R rows with the entries `vals` (R, E) in the columns `cols` (R, E);
        returns the new rows' indices (R,). Taken CHUNK rows at a time, so the sorting
        copies stay bounded whatever R."""
        cols = np.asarray(cols)
        vals = np.broadcast_to(np.asarray(vals, dtype=float), cols.shape)
        count = cols.shape[0]
        for start in range(0, count, CHUNK):
            self._add_rows(cols[start : start + CHUNK], vals[start : start + CHUNK])
        first = self.rows
        self.rows += count
        return first + np.arange(count)

    def _add_rows(self, cols: np.ndarray, vals: np.ndarray) -> None:
        width = cols.shape[1]
        if width > 1:  # sort each row's columns (stably), then sum runs of equal columns left to right
            order = np.argsort(cols[0], kind="stable")  # the first row's order, usually every row's
            sorted_cols = cols[:, order]
            if np.all(sorted_cols[:, 1:] >= sorted_cols[:, :-1]):
                cols, vals = sorted_cols, vals[:, order]
            else:  # not every row's: sort each row
                del sorted_cols
                order = np.argsort(cols, axis=1, kind="stable")
                cols = np.take_along_axis(cols, order, axis=1)
                vals = np.take_along_axis(vals, order, axis=1)
            repeated = cols[:, 1:] == cols[:, :-1]  # entry j + 1 repeats entry j's column
            if repeated.any():
                head = np.broadcast_to(np.arange(width), cols.shape).copy()  # each entry's run start
                for j in range(1, width):
                    head[:, j] = np.where(repeated[:, j - 1], head[:, j - 1], j)
                    rows = np.flatnonzero(repeated[:, j - 1])
                    vals[rows, head[rows, j]] += vals[rows, j]
                keep = np.ones(cols.shape, dtype=bool)
                keep[:, 1:] = ~repeated
                keep &= vals != 0.0
            else:
                keep = vals != 0.0
        else:
            keep = vals != 0.0
        self._counts.append(np.count_nonzero(keep, axis=1))
        self._indices.append(cols[keep].astype(self._index_dtype(), copy=False))
        self._data.append(vals[keep])

    def add_entries(self, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, count: int) -> None:
        """Append `count` rows given as entries (row within the block, column, value), any order."""
        rows, cols, vals = np.ravel(rows), np.ravel(cols), np.ravel(np.asarray(vals, dtype=float))
        order = np.lexsort((cols, rows))  # stable: equal (row, column) keep their given order
        rows, cols, vals = rows[order], cols[order], vals[order]
        new = np.ones(rows.size, dtype=bool)
        new[1:] = (rows[1:] != rows[:-1]) | (cols[1:] != cols[:-1])
        starts = np.flatnonzero(new)
        if starts.size < rows.size:
            vals = np.add.reduceat(vals, starts)
            rows, cols = rows[starts], cols[starts]
        keep = vals != 0.0
        rows, cols, vals = rows[keep], cols[keep], vals[keep]
        self._counts.append(np.bincount(rows, minlength=count))
        self._indices.append(cols.astype(self._index_dtype(), copy=False))
        self._data.append(vals)
        self.rows += count

    def matrix(self) -> sp.csr_matrix:
        """The rows added so far, as a canonical CSR matrix (sorted indices, no duplicates)."""
        indptr = np.zeros(self.rows + 1, dtype=np.int64)
        if self._counts:
            np.cumsum(np.concatenate(self._counts), out=indptr[1:])
        dtype = self._index_dtype(int(indptr[-1]))
        data = np.concatenate(self._data) if self._data else np.zeros(0)
        indices = np.concatenate(self._indices).astype(dtype, copy=False) if self._indices else np.zeros(0, dtype)
        out = sp.csr_matrix((data, indices, indptr.astype(dtype, copy=False)), shape=(self.rows, self.columns))
        out.has_sorted_indices = True
        out.has_canonical_format = True
        return out

    def _index_dtype(self, nnz: int = 0) -> type:
        limit = np.iinfo(np.int32).max
        return np.int32 if max(self.columns, self.rows, nnz) < limit else np.int64
