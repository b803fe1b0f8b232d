"""RowBlocks (qdframe.directions.sparse_rows) against SciPy's COO → CSR conversion: the same
canonical matrix once SciPy's explicit zeros are eliminated, bit for bit where an entry
repeats at most twice (a sum of two is the same in either order; SciPy's sort is not
stable, so the order of three is not defined), and to rounding beyond."""

import numpy as np
import scipy.sparse as sp

from qdframe.directions import sparse_rows
from qdframe.directions.sparse_rows import RowBlocks


def _scipy(blocks, columns):
    """The reference: every block's entries as COO, converted by SciPy, zeros eliminated."""
    rows, cols, vals, count = [], [], [], 0
    for kind, block in blocks:
        if kind == "rows":
            c, v = block
            rows.append(np.repeat(count + np.arange(c.shape[0]), c.shape[1]))
            cols.append(c.ravel())
            vals.append(np.broadcast_to(v, c.shape).ravel())
            count += c.shape[0]
        else:
            r, c, v, n = block
            rows.append(count + r)
            cols.append(c)
            vals.append(v)
            count += n
    out = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(count, columns))
    out.eliminate_zeros()
    return out


def _assert_same(built, reference):
    assert built.shape == reference.shape
    assert np.array_equal(built.indptr, reference.indptr)
    assert np.array_equal(built.indices, reference.indices)
    assert np.array_equal(built.data, reference.data)  # exact: duplicates summed in the same order
    assert built.has_canonical_format


def test_blocks_with_unsorted_columns_duplicates_and_zeros(monkeypatch):
    monkeypatch.setattr(sparse_rows, "CHUNK", 7)  # several chunks per block
    rng = np.random.default_rng(3)
    columns = 40
    blocks = []
    for width in (1, 2, 3, 5):
        count = 23
        cols = np.argsort(rng.random((count, columns)), axis=1)[:, :width]  # distinct, unsorted
        cols[::4, -1] = cols[::4, 0]  # a column twice in a row
        vals = rng.standard_normal((count, width))
        vals[rng.random((count, width)) < 0.3] = 0.0  # exact zeros
        vals[1::5, 0] = -vals[1::5, -1] if width > 1 else 0.0  # duplicates that cancel where the columns repeat
        cols[1::5, -1] = cols[1::5, 0]
        blocks.append(("rows", (cols, vals)))
    same_order = np.arange(30)[:, None] + np.array([[4, 0, 2]])  # every row in the first row's order
    blocks.append(("rows", (same_order, rng.standard_normal((30, 3)))))
    place = rng.permutation(11 * columns)[:60]  # distinct (row, column) pairs, then some twice
    place[50:] = place[:10]
    entries = place // columns, place % columns, rng.standard_normal(60)
    entries[2][::6] = 0.0
    blocks.append(("entries", (*entries, 11)))
    built = RowBlocks(columns)
    for kind, block in blocks:
        built.add(*block) if kind == "rows" else built.add_entries(*block)
    _assert_same(built.matrix(), _scipy(blocks, columns))


def test_products_with_the_built_matrix_equal_scipys():
    rng = np.random.default_rng(5)
    cols = np.sort(rng.integers(0, 50, (200, 4)), axis=1)[:, ::-1]
    vals = rng.standard_normal((200, 4))
    vals[:, 1] = 0.0
    blocks = [("rows", (cols, vals))]
    built = RowBlocks(50)
    built.add(cols, vals)
    J = built.matrix()
    full = sp.csr_matrix((vals.ravel(), (np.repeat(np.arange(200), 4), cols.ravel())), shape=(200, 50))
    _assert_same(J, _scipy(blocks, 50))
    d, r = rng.standard_normal(50), rng.standard_normal(200)
    assert np.array_equal(J @ d, full @ d)
    assert np.array_equal(J.T @ r, full.T @ r)
    assert abs(J.T @ J - full.T @ full).max() == 0.0


def test_runs_of_three_or_more_sum_to_rounding():
    rng = np.random.default_rng(7)
    cols = rng.integers(0, 6, (500, 8))  # many columns several times in a row
    vals = rng.standard_normal((500, 8))
    built = RowBlocks(6)
    built.add(cols, vals)
    J, reference = built.matrix(), _scipy([("rows", (cols, vals))], 6)
    assert np.array_equal(J.indptr, reference.indptr) and np.array_equal(J.indices, reference.indices)
    np.testing.assert_allclose(J.data, reference.data, rtol=1e-13, atol=1e-14)
    dense = np.zeros((500, 6))
    np.add.at(dense, (np.repeat(np.arange(500), 8), cols.ravel()), vals.ravel())
    np.testing.assert_allclose(J.toarray(), dense, rtol=1e-13, atol=1e-14)
