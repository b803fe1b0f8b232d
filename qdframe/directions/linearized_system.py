"""The linearized problem of a `gauss-newton` step (:mod:`.gauss_newton`), assembled at ξ.

In the extended unknowns [x | z | u | Z] per node (u: the controls and the selections λ,
Z = ∫_0^t z), :class:`LinearizedSystem` holds what the step's model reads:

* r and J (one generalized-Jacobian element) of the least-squares residuals υ, χ, ω, the
  point sets' φ and σ;
* E, the equality constraints E d = 0 (the fixed start, Z_0 = 0, the resolved states and
  the scheme's rule for Z);
* the hinge rows of the sets' one-sided residuals h_b, √w_k·(ℓ_side + ∇ℓ_side·d);
* the cost's pieces (max- and min-groups) and their linearizations;
* the columns' map R of the constant states (one unknown x_i(t_0) for every node);

and the model's value at a step d: its predicted decrease and the objective's slope along d.
What does not depend on ξ (the columns, E, R and E on the reduced columns) is a
:class:`Skeleton`, built once per functional and shared by the steps of a solve.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from .kkt import Bordered
from .sparse_rows import RowBlocks

if TYPE_CHECKING:
    from ..functional import Functional


class Skeleton:
    """The ξ-independent part of the linearized system of one functional: each variable's
    columns at every node, E, and the constant states' columns map R with E on the reduced
    columns (:meth:`LinearizedSystem.reduced`). gauss-newton keeps it between the steps of a
    solve (on a fine grid, E and its reduction are a large part of a step to rebuild)."""

    def __init__(self, functional: "Functional") -> None:
        self.f = functional
        n, m = functional.n, functional.m + functional.p  # u and the selections λ: both enter y
        nodes = functional.grid.nodes
        self.n, self.m, self.nodes = n, m, nodes
        self.width = 3 * n + m  # per node: x, z, u, λ, Z
        self.size = nodes * self.width
        base = np.arange(nodes)[:, None] * self.width
        self.x_cols, self.z_cols, self.u_cols, self.Z_cols = (
            _frozen(base + start + np.arange(count)[None, :]) for start, count in
            ((0, n), (n, n), (2 * n, m), (2 * n + m, n)))  # (N, count) each
        self.y_cols = _frozen(np.concatenate([self.x_cols, self.u_cols], axis=1))
        self.constraints = _constraints(self)
        self.constant = 0  # how many constant states (:meth:`_constant_columns`) …
        self.constant_mask = np.zeros(n, dtype=bool)  # … and which
        self.columns = self._constant_columns()
        self.R = None if self.columns is None else self._reduction()
        cut = 0 if self.R is None else self.R.shape[1] - self.constant
        # per constant state, 1.0 on the columns R maps to its unknown (:meth:`split`)
        self.indicators = [(self.columns == cut + j).astype(float) for j in range(self.constant)]
        self.reduced_damping = None  # R·W: the L² weights (:meth:`LinearizedSystem.damping`) on the reduced columns
        if self.R is not None:
            weights = np.zeros((nodes, self.width))
            weights[:, : 2 * n + m] = functional.weights[:, None]
            self.reduced_damping = self.R.T @ weights.ravel()
        self.live_constraints: tuple[sp.csr_matrix, np.ndarray] | None = None  # E·R's rows that kept entries
        if self.columns is not None:
            reduced, emptied = self.reduced(self.constraints)
            self.live_constraints = reduced[~emptied], ~emptied

    def _constant_columns(self) -> np.ndarray | None:
        """Where each column of the extended unknowns goes in the KKT systems: a constant state
        (the model's `constant_states`, x_i' = 0: an unknown T or parameter) is one unknown
        x_i(t_0) for every node, its z_i and Z_i none (−1); None without constant states. The
        constant states' unknowns come last, after the other columns in their order: the KKT
        solver borders them (dense columns) and cuts them off its trailing rows and columns."""
        constant = [i for i in self.f.model.constant_states if i not in self.f.resolved]
        if not constant:
            return None
        target = np.arange(self.size)
        first = self.x_cols[0, constant]
        target[self.x_cols[:, constant]] = first
        target[self.z_cols[:, constant]] = -1
        target[self.Z_cols[:, constant]] = -1
        own = target == np.arange(self.size)  # the columns that stay, in order …
        own[first] = False
        self.constant = len(constant)
        self.constant_mask[constant] = True
        index = np.cumsum(own) - 1
        index[first] = np.count_nonzero(own) + np.arange(len(constant))  # … then the constant states'
        dtype = np.int32 if self.size < np.iinfo(np.int32).max else np.int64  # J's index type (:mod:`.sparse_rows`)
        return np.where(target >= 0, index[np.maximum(target, 0)], -1).astype(dtype)

    def _reduction(self) -> sp.csr_matrix:
        """R (size × reduced): d = R·d_r, a constant state's x_i(t_k) all the column of x_i(t_0)."""
        kept = self.columns >= 0
        return sp.csr_matrix((np.ones(int(kept.sum())), (np.flatnonzero(kept), self.columns[kept])),
                             shape=(self.size, int(self.columns.max()) + 1))

    def split(self, matrix: sp.csr_matrix) -> tuple[sp.csr_matrix, np.ndarray]:
        """matrix · R in two parts, by its column indices mapped (no product): the columns other
        than the constant states' (sparse: the rest keep their order, so stay sorted) and the
        constant states' (dense, rows × their count: each a sum over the nodes)."""
        cut = self.R.shape[1] - self.constant
        target = self.columns[matrix.indices]  # in the columns' own index type (:meth:`_constant_columns`)
        inner = target.view(np.uint64 if target.itemsize == 8 else np.uint32) < cut  # −1 (none) is large
        running = np.zeros(inner.size + 1, dtype=matrix.indptr.dtype)
        np.cumsum(inner, out=running[1:])
        rows = matrix.shape[0]
        sparse = sp.csr_matrix((matrix.data[inner], target[inner], running[matrix.indptr]), shape=(rows, cut))
        sparse.has_sorted_indices = True
        # the constant states' entries summed per row: matrix times each one's indicator of columns
        dense = np.stack([matrix @ indicator for indicator in self.indicators], axis=1)
        return sparse, dense

    def reduced(self, matrix: sp.spmatrix) -> tuple[sp.csr_matrix, np.ndarray]:
        """matrix · R (R: the columns' map of :meth:`_constant_columns`), explicit zeros kept, and
        which rows lost every entry they had (a constant state's own recursion rows)."""
        matrix = sp.csr_matrix(matrix)
        rows = matrix.shape[0]
        row_of = np.repeat(np.arange(rows), np.diff(matrix.indptr))
        target = self.columns[matrix.indices]
        keep = target >= 0
        reduced = sp.csr_matrix((matrix.data[keep], (row_of[keep], target[keep])),
                                shape=(rows, int(self.columns.max()) + 1))
        emptied = (np.diff(matrix.indptr) > 0) & (np.bincount(row_of[keep], minlength=rows) == 0)
        return reduced, emptied


def _live(col: np.ndarray, val: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """col/val (R, E) without the columns of entries all zero (a piece constant in a variable),
    left out before sorting."""
    live = np.any(val != 0.0, axis=0)
    return (col, val) if live.all() else (col[:, live], val[:, live])


def _psd_factor(hessian: np.ndarray) -> np.ndarray:
    """L (N, w, w) with LᵀL = [H]₊, the positive semidefinite part of each symmetric H (N, w, w)."""
    values, vectors = np.linalg.eigh(0.5 * (hessian + np.swapaxes(hessian, 1, 2)))
    return np.sqrt(np.maximum(values, 0.0))[:, :, None] * np.swapaxes(vectors, 1, 2)


def _frozen(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False  # shared by the steps of a solve
    return array


def _constraints(skeleton: Skeleton) -> sp.csr_matrix:
    """E d = 0: dx_0 = 0 where x(t_0) is given, dZ_0 = 0, dz_i = dx_j for resolved states,
    dZ_p − dZ_{base(p)} − Σ_j A_pj dz_j = 0 (the scheme's rule)."""
    f, n, nodes = skeleton.f, skeleton.n, skeleton.nodes
    x_cols, z_cols, Z_cols = skeleton.x_cols, skeleton.z_cols, skeleton.Z_cols
    rows = RowBlocks(skeleton.size)
    fixed = np.concatenate([x_cols[0, f.start_given], Z_cols[0]])
    rows.add(fixed[:, None], np.ones((fixed.size, 1)))
    for i, j in f.resolved.items():  # dz_i = dx_j at every node
        rows.add(np.stack([z_cols[:, i], x_cols[:, j]], axis=1), np.broadcast_to([1.0, -1.0], (nodes, 2)))
    points, base, increments = f.grid.recursion()
    # one row per point p ≥ 1 and state: dZ_p − dZ_{base(p)} − Σ_j A_pj dz_j, the row p − 1 of the
    # restricted A padded with zeros to its longest row (a zero entry is left out)
    increments = sp.csr_matrix(increments)
    counts = np.diff(increments.indptr)
    width = int(counts.max(initial=0))
    place = np.arange(increments.nnz) - np.repeat(increments.indptr[:-1], counts)
    terms = np.zeros((points.size, width), dtype=increments.indices.dtype)
    weights = np.zeros((points.size, width))
    row_of = np.repeat(np.arange(points.size), counts)
    terms[row_of, place] = increments.indices
    weights[row_of, place] = -increments.data
    cols = np.concatenate([Z_cols[points][:, :, None], Z_cols[base][:, :, None],
                           np.moveaxis(z_cols[terms], 1, 2)], axis=2)  # (points, n, 2 + width)
    vals = np.concatenate([np.ones((points.size, 1)), -np.ones((points.size, 1)), weights], axis=1)
    rows.add(cols.reshape(points.size * n, 2 + width), np.repeat(vals, n, axis=0))
    return rows.matrix()


def _held_rows(f: "Functional", xi: np.ndarray, y_cols: np.ndarray, z_cols: np.ndarray,
               root_w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """η's rows: per pair (p, q) of one interval's stages and held choice j, √w_p·(c_pj − c_qj)
    on the columns of y = (x, u, λ) and z at p and at q."""
    held = f.held
    choice, grads = held.choices(xi, gradients=True)
    coords = held.coords(f.arguments(xi))
    first, last = held.pairs[:, 0], held.pairs[:, 1]
    count, H = first.size, choice.shape[1]
    unit = np.zeros((H, f.n))  # ∂c/∂z: the identity on the held blocks' z
    unit[np.arange(len(coords)), coords] = 1.0
    scale = root_w[first][:, None, None]
    cols = np.concatenate([np.repeat(y_cols[first][:, None, :], H, axis=1), np.repeat(z_cols[first][:, None, :], H, axis=1),
                           np.repeat(y_cols[last][:, None, :], H, axis=1), np.repeat(z_cols[last][:, None, :], H, axis=1)],
                          axis=2)
    vals = np.concatenate([scale * grads[first], scale * np.broadcast_to(unit, (count, H, f.n)),
                           -scale * grads[last], -scale * np.broadcast_to(unit, (count, H, f.n))], axis=2)
    residual = root_w[first][:, None] * (choice[first] - choice[last])
    return residual.ravel(), cols.reshape(count * H, -1), vals.reshape(count * H, -1)


class LinearizedSystem:
    """The linearized problem at ξ in the extended unknowns [x | z | u | Z] per node.

    value: the objective at ξ where the caller has it; skeleton: the functional's
    :class:`Skeleton` where the caller keeps one (both computed here if None)."""

    def __init__(self, functional: "Functional", xi: np.ndarray, delta: float, value: float | None = None,
                 skeleton: Skeleton | None = None) -> None:
        self.f = functional
        self._xi = xi
        skeleton = skeleton if skeleton is not None else Skeleton(functional)
        self.skeleton = skeleton
        self.n, self.m, self.nodes, self.width, self.size = (skeleton.n, skeleton.m, skeleton.nodes, skeleton.width,
                                                             skeleton.size)
        self.delta = delta
        self.penalty = functional.penalty
        self.value = functional.objective(xi) if value is None else value
        blocks = functional.distance_sides(xi)
        self.shifts = functional.shifts  # the augmented Lagrangian's (qdframe.functional.shifts), or None
        self.block_index = [b for b, block in enumerate(blocks) if not block.equation]  # each side's block
        self.sides = [block for block in blocks if not block.equation]  # sets: one-sided hinges
        # z_b = f_b(y): least squares, their sides not kept past J (at N = 1e5 on 7.3, 46 MB)
        # the constant states whose own rows vanish on the reduced columns (with x_i(t_0) given they do not)
        self._own_states = skeleton.constant_mask & ~functional.start_given
        self._still_entries: list[Callable[[], tuple[np.ndarray, np.ndarray]]] = []  # their rows' (:meth:`still`)
        self._still: sp.csr_matrix | None = None
        self.residual, self.jacobian, self.still_residual = self._least_squares(
            xi, [(b, block) for b, block in enumerate(blocks) if block.equation])
        del blocks
        self.terminal_value = 0.0  # M(x(T)) of a terminal cost and its gradient (:meth:`_curvature`)
        self.terminal_gradient: np.ndarray | None = None
        curvature = _curvature(self, xi)  # the cost's second-order model, as rows of zero residual
        if curvature is not None:
            self.jacobian = sp.vstack([self.jacobian, curvature], format="csr")
            self.residual = np.concatenate([self.residual, np.zeros(curvature.shape[0])])
        self.constraints = skeleton.constraints
        # the cost's max- and min-groups: (values (N, q), gradients (N, q, n + m)) each, a 0
        # column for each selection λ (the cost is a function of (x, u) alone)
        self.max_groups, self.min_groups = ([[(v, self._widened(g)) for v, g in groups]
                                             for groups in functional.cost_pieces(xi)]
                                            if functional.cost is not None else ([], []))
        self.columns, self.R = skeleton.columns, skeleton.R
        self._hinge_rows: tuple[sp.csr_matrix, np.ndarray] | None = None  # :meth:`hinges`
        self._min_linear: np.ndarray | None = None  # :meth:`min_linear`

    def _widened(self, gradients: np.ndarray) -> np.ndarray:
        """Gradients in (x, u) padded with zeros to y = (x, u, λ)."""
        missing = self.n + self.m - gradients.shape[-1]
        return np.concatenate([gradients, np.zeros(gradients.shape[:-1] + (missing,))], axis=-1) if missing else gradients

    # column indices of each variable at every node: (N, count), shared (read-only)
    def x_cols(self) -> np.ndarray:
        return self.skeleton.x_cols

    def z_cols(self) -> np.ndarray:
        return self.skeleton.z_cols

    def u_cols(self) -> np.ndarray:
        return self.skeleton.u_cols

    def Z_cols(self) -> np.ndarray:
        return self.skeleton.Z_cols

    def y_cols(self) -> np.ndarray:
        return self.skeleton.y_cols

    def unknowns_step(self, step: np.ndarray) -> np.ndarray:
        """The step on ξ = [x | z | u] per node (dropping Z)."""
        return step.reshape(self.nodes, self.width)[:, : 2 * self.n + self.m].copy()

    def reduced(self, ties: sp.spmatrix | None = None) -> tuple[sp.csr_matrix, np.ndarray]:
        """C = [E; ties] · R without the rows that lost every entry (:meth:`Skeleton.reduced`), and
        which rows of C those are not (E's part kept in the skeleton)."""
        reduced, live = self.skeleton.live_constraints
        if ties is None or not ties.shape[0]:
            return reduced, live
        more, emptied = self.skeleton.reduced(ties)
        return sp.vstack([reduced, more[~emptied]], format="csr"), np.concatenate([live, ~emptied])

    def _least_squares(self, xi: np.ndarray, equations: list) -> tuple[np.ndarray, sp.csr_matrix, np.ndarray]:
        """The residuals r and J (one generalized-Jacobian element) of υ, χ, ω, the point
        sets' φ (`equations`) and σ, row blocks in that order, but for the constant states' own
        rows (their υ and x_i' = 0), whose residuals come third and whose J waits (:meth:`still`)."""
        f, nodes = self.f, self.nodes
        root_w = np.sqrt(f.weights)
        rows = RowBlocks(self.size)  # exactly-zero entries left out (:mod:`.sparse_rows`)
        residuals: list[np.ndarray] = []
        still_residuals: list[np.ndarray] = []
        constant = self._own_states

        def add(res: np.ndarray, col: np.ndarray, val: np.ndarray) -> None:
            """res: (R,), col/val: (R, E) entries of R new rows."""
            rows.add(*_live(col, val))
            residuals.append(res)

        def add_still(res: np.ndarray, entries: Callable[[], tuple[np.ndarray, np.ndarray]]) -> None:
            """A constant state's own rows: res now, their entries (col, val) when :meth:`still` asks."""
            self._still_entries.append(entries)
            still_residuals.append(res)

        shifts = self.shifts
        consistency = f.consistency(xi)  # υ, one row per node and state: x_k − x_0 − Z_k
        if shifts is not None:
            consistency = consistency + shifts.consistency
        x_cols, Z_cols = self.x_cols(), self.Z_cols()

        def upsilon(states: np.ndarray | slice) -> tuple[np.ndarray, np.ndarray]:
            """υ's entries for `states`: columns x_i(t_0) ≤ x_i(t_k) < Z_i(t_k), every row in order,
            −√w_k on a free x_i(0) (0 where it is given)."""
            count = x_cols[0, states].size
            start_free = np.tile(~f.start_given[states], nodes)
            return (np.stack([np.tile(x_cols[0, states], nodes), x_cols[:, states].ravel(), Z_cols[:, states].ravel()],
                             axis=1),
                    np.stack([-np.repeat(root_w, count) * start_free, np.repeat(root_w, count),
                              -np.repeat(root_w, count)], axis=1))

        moving = ~constant if constant.any() else slice(None)
        add((root_w[:, None] * consistency[:, moving]).ravel(), *upsilon(moving))
        if constant.any():
            add_still((root_w[:, None] * consistency[:, constant]).ravel(), lambda: upsilon(constant))
        end = f.end_residual(xi)  # χ: x_j(0) + Z_{N−1,j} − xT_j (j ∈ J), then Z_{N−1,i} (i ∈ P)
        if shifts is not None:
            end = end + shifts.end
        if end.size:
            coords = np.concatenate([f.end, f.periodic])
            starts = np.concatenate([~f.start_given[f.end], np.zeros(f.periodic.size, dtype=bool)])
            add(end, np.stack([Z_cols[-1, coords], x_cols[0, coords]], axis=1),
                np.stack([np.ones(end.size), starts.astype(float)], axis=1))
        if f.surface is not None:  # ω
            e, de = f.surface_values(xi)
            if shifts is not None:
                e = e + shifts.surface
            o = e.shape[1]
            add((root_w[:, None] * e).ravel(),
                np.repeat(x_cols[:, None, :], o, axis=1).reshape(nodes * o, self.n),
                (root_w[:, None, None] * de).reshape(nodes * o, self.n))
        y_cols, z_cols = self.y_cols(), self.z_cols()
        for b, block in equations:  # φ of a point set: √w·(z_b − f_b(y)), a plain residual
            (ell, dell_dy, psi), = block.sides
            if shifts is not None:
                ell = ell + shifts.blocks[:, b, 0]

            def phi(block=block, dell_dy=dell_dy, psi=psi) -> tuple[np.ndarray, np.ndarray]:
                return (np.concatenate([y_cols, z_cols[:, list(block.coords)]], axis=1),
                        root_w[:, None] * np.concatenate([dell_dy, psi], axis=1))

            if constant[list(block.coords)].all() and not np.any(dell_dy):  # x_i' = 0 of a constant state
                add_still(root_w * ell, phi)
            else:
                add(root_w * ell, *phi())
        if f.p:  # σ: the selections' natural map
            _selection_rows(self, xi, root_w, add)
        if f.held is not None:  # η: √w_{k,i}·(c_{k,i} − c_{k,s}), the held choices (functional.held)
            add(*_held_rows(f, xi, y_cols, z_cols, root_w))
        return np.concatenate(residuals), rows.matrix(), np.concatenate(still_residuals or [np.zeros(0)])

    def still(self) -> sp.csr_matrix:
        """J's rows of the constant states' own residuals (`still_residual`): υ, √w_k·(x_i(t_k) −
        x_i(t_0) − Z_i(t_k)), and x_i' = 0, √w_k·z_i. On the reduced columns (R) they vanish
        (x_i(t_k) and x_i(t_0) are one unknown, z_i and Z_i none), so a step on them never builds
        them: at N = 1e5 a third of J's rows for one parameter, ~20 ms a step."""
        if self._still is None:
            rows = RowBlocks(self.size)
            for entries in self._still_entries:
                rows.add(*_live(*entries()))
            self._still = rows.matrix()
        return self._still

    def _still_moves(self, d: np.ndarray) -> bool:
        """Whether the constant states' own rows count: their residuals are not all 0, or `d`
        is not on the reduced columns (a constant state's step unlike at some node, or its z or Z moved)."""
        if not self._still_entries:
            return False
        if np.any(self.still_residual):
            return True
        for i in np.flatnonzero(self._own_states):
            if np.any(d[self.x_cols()[:, i]] != d[self.x_cols()[0, i]]) or np.any(d[self.z_cols()[:, i]]) \
                    or np.any(d[self.Z_cols()[:, i]]):
                return True
        return False

    def gradient(self) -> np.ndarray:
        """λJᵀr on every column (the constant states' own rows: where their residuals are not all 0)."""
        gradient = self.jacobian.T @ self.residual
        if np.any(self.still_residual):
            gradient += self.still().T @ self.still_residual
        return self.penalty * gradient

    def damping(self) -> np.ndarray:
        """L² weights w_k on x, z, u (none on Z, which the constraints determine)."""
        weights = np.zeros((self.nodes, self.width))
        weights[:, : 2 * self.n + self.m] = self.f.weights[:, None]
        return weights.ravel()

    def hessian(self, mu: float, reduced: bool) -> sp.csc_matrix | Bordered:
        """λJᵀJ + μW; if `reduced` (and there are constant states) on their reduced columns (R),
        bordered: the constant states' columns (the last, each dense) apart (:class:`.kkt.Bordered`)."""
        J, lam = self.jacobian, self.penalty
        if not reduced or self.R is None:
            normal = J.T @ J + self.still().T @ self.still() if self._still_entries else J.T @ J
            return (lam * normal + mu * sp.diags(self.damping())).tocsc()
        inner, outer = self.skeleton.split(J)
        damping = self.skeleton.reduced_damping
        cut = inner.shape[1]
        return Bordered((lam * (inner.T @ inner) + mu * sp.diags(damping[:cut])).tocsc(), lam * (inner.T @ outer),
                        lam * (outer.T @ outer) + mu * np.diag(damping[cut:]))

    def hinges(self) -> tuple[sp.csr_matrix, np.ndarray]:
        """The one-sided residuals of φ: rows √w_k·(ℓ_side + ∇ℓ_side·d) for every block,
        side and node (h_b = max(0, max_side ℓ)), as a matrix and the values √w_k·ℓ (built
        once per step: the active-set iteration, the QP and its polish all read them)."""
        if self._hinge_rows is None:
            self._hinge_rows = self._assemble_hinges()
        return self._hinge_rows

    def _assemble_hinges(self) -> tuple[sp.csr_matrix, np.ndarray]:
        root_w = np.sqrt(self.f.weights)
        y_cols, z_cols = self.y_cols(), self.z_cols()
        rows = RowBlocks(self.size)  # exactly-zero coefficients left out (:mod:`.sparse_rows`)
        values = []
        shifts = self.shifts
        for b, block in zip(self.block_index, self.sides):
            block_cols = np.concatenate([y_cols, z_cols[:, list(block.coords)]], axis=1)
            for side, (ell, dell_dy, psi) in enumerate(block.sides):
                rows.add(block_cols, root_w[:, None] * np.concatenate([dell_dy, psi], axis=1))
                values.append(root_w * (ell if shifts is None else ell + shifts.blocks[:, b, side]))
        bounds = self.f.bounds
        if bounds is not None:  # β: √w_k·sense·(y_j − limit), one row per node and finite side
            sides = self.f.values.bound_sides(self.f.arguments(self._xi))
            if shifts is not None:
                sides = sides + shifts.bounds
            q = bounds.columns.size
            rows.add(y_cols[:, bounds.columns].reshape(-1, 1), np.repeat(root_w, q)[:, None] * np.tile(bounds.sense, self.nodes)[:, None])
            values.append((root_w[:, None] * sides).ravel())
        if not rows.rows:
            return sp.csr_matrix((0, self.size)), np.zeros(0)
        return rows.matrix(), np.concatenate(values)

    def min_linear(self) -> np.ndarray:
        """Σ_k w_k ∇b_p*·d_k: each cost min-group (concave) linearized at its active piece."""
        if self._min_linear is None:
            min_linear = np.zeros(self.size)
            y_cols = self.y_cols()
            for values, grads in self.min_groups:
                pick = grads[np.arange(self.nodes), np.argmin(values, axis=1)]
                np.add.at(min_linear, y_cols.ravel(), (self.f.weights[:, None] * pick).ravel())
            if self.terminal_gradient is not None:  # ∇M(x(T))·dx_{N−1}
                min_linear[self.x_cols()[-1]] += self.terminal_gradient
            self._min_linear = min_linear
        return self._min_linear

    def max_pieces(self, d: np.ndarray) -> list[np.ndarray]:
        """Each cost max-group's pieces linearized at d: a_q + ∇a_q·d_k, (N, m) per group."""
        dy = d[self.y_cols()]
        return [piece_values + np.einsum("kqp,kp->kq", grads, dy) for piece_values, grads in self.max_groups]

    def decrease(self, d: np.ndarray, predicted_sides: np.ndarray) -> float:
        """I(ξ) minus the step model at d: (λ/2)(‖r + Jd‖² + Σ max(0, v + Ad)²) plus the cost's
        max-groups at their linearized maximum and min-groups at their linearized active piece
        (predicted_sides: v + Ad, the hinge rows at d)."""
        w = self.f.weights
        if self.shifts is not None:  # the objective is the shifted one less its constant: the change itself
            return _shifted_decrease(self, d, predicted_sides)
        squares = np.sum((self.residual + self.jacobian @ d) ** 2)
        if self._still_moves(d):
            squares += np.sum((self.still_residual + self.still() @ d) ** 2)
        model = 0.5 * self.penalty * (squares + np.sum(np.maximum(predicted_sides, 0.0) ** 2))
        model += sum(float(w @ predicted.max(axis=1)) for predicted in self.max_pieces(d))
        model += float(self.min_linear() @ d) + sum(float(w @ values.min(axis=1)) for values, _ in self.min_groups)
        model += self.terminal_value
        return float(self.value - model)

    def slope(self, d: np.ndarray, gradient: np.ndarray) -> float:
        """The objective's one-sided derivative along d: the smooth part (gradient: λJᵀr and the
        min-groups' :meth:`min_linear`), the cost's δ-active max-pieces and the violated sides."""
        w, dy = self.f.weights, d[self.y_cols()]
        matrix, values = self.hinges()
        slope = float(gradient @ d) + self.penalty * float(np.maximum(values, 0.0) @ (matrix @ d))
        for piece_values, grads in self.max_groups:
            active = piece_values >= piece_values.max(axis=1, keepdims=True) - self.delta
            slope += float(w @ np.max(np.where(active, np.einsum("kqp,kp->kq", grads, dy), -np.inf), axis=1))
        return slope


def _curvature(self: "LinearizedSystem", xi: np.ndarray) -> sp.csr_matrix | None:
    """The cost's second-order part as rows C with λ·CᵀC = Σ_k w_k [∇²c(y_k)]₊ (+ [∇²M(x(T))]₊),
    [·]₊ the positive semidefinite part (eigenvalues below 0 cut to 0): appended to J with
    residual 0, they add the cost's curvature to the step's Hessian λJᵀJ + μW (a smooth
    integrand's `hessian`, a terminal cost's). None where the cost has neither. Also sets
    the terminal cost's value and gradient (:meth:`min_linear`)."""
    cost = self.f.cost
    if cost is None or (cost.hessian is None and cost.terminal is None):
        return None
    rows = RowBlocks(self.size)
    scale = 1.0 / np.sqrt(self.penalty)
    if cost.hessian is not None:
        y = self.f.arguments(xi)
        hessian = np.asarray(cost.hessian(y), float)
        self.f.pieces.check("cost Hessian", hessian, (self.nodes, y.shape[1], y.shape[1]))
        factor = _psd_factor(hessian) * (scale * np.sqrt(self.f.weights))[:, None, None]  # (N, w, w)
        width = y.shape[1]
        cols = np.repeat(self.y_cols()[:, None, : width], width, axis=1)
        rows.add(*_live(cols.reshape(-1, width), factor.reshape(-1, width)))
    if cost.terminal is not None:
        x_T = self.f.split(xi)[0][-1]
        value, gradient, hessian = cost.terminal(x_T)
        self.terminal_value, self.terminal_gradient = float(value), np.asarray(gradient, float)
        factor = scale * _psd_factor(np.asarray(hessian, float)[None])[0]
        n = x_T.size
        rows.add(*_live(np.repeat(self.x_cols()[-1][None, :], n, axis=0), factor))
    return rows.matrix() if rows.rows else None


def _shifted_decrease(self: "LinearizedSystem", d: np.ndarray, predicted_sides: np.ndarray) -> float:
    """:meth:`decrease` as the model's change from d = 0, term by term (with the augmented
    Lagrangian's shifts the model's value is ½λ·Σs² above the objective's, a constant that
    can be 1e8 times the change near the optimum: the difference of the two would be rounding)."""
    w = self.f.weights
    Jd = self.jacobian @ d
    change = float(self.residual @ Jd) + 0.5 * float(Jd @ Jd)
    if self._still_moves(d):
        still = self.still() @ d
        change += float(self.still_residual @ still) + 0.5 * float(still @ still)
    values = self.hinges()[1]
    change += 0.5 * float(np.sum(np.maximum(predicted_sides, 0.0) ** 2 - np.maximum(values, 0.0) ** 2))
    model = self.penalty * change
    model += sum(float(w @ (predicted.max(axis=1) - values.max(axis=1)))
                 for predicted, (values, _) in zip(self.max_pieces(d), self.max_groups))
    model += float(self.min_linear() @ d)
    return -model


def _selection_rows(self: "LinearizedSystem", xi: np.ndarray, root_w: np.ndarray,
                    add: Callable[[np.ndarray, np.ndarray, np.ndarray], None]) -> None:
    """σ's rows, √w_k·(r + s) of every selection with one generalized-Jacobian element (a held
    left limit's r_k = λ_k − λ_{k−1}: a −1 on λ_{k−1}); with shifts, a selection within reach of
    its natural map's kink has both branches' rows, each with half the weight."""
    f, nodes, shifts = self.f, self.nodes, self.shifts
    y_cols = self.y_cols()
    r, dr = f.selection_residual(xi)
    if shifts is not None:
        r = r + shifts.selections
    cols = np.repeat(y_cols[:, None, :], f.p, axis=1)  # (N, p, width)
    vals = root_w[:, None, None] * dr
    left, held = f.left_limits(f.selections(xi))  # r_k = λ_k − λ_{k−1}: a −1 on λ_{k−1}
    if left.size:
        lam_cols = self.u_cols()[:, f.m :]  # (N, p)
        extra_cols = lam_cols.copy()[:, :, None]  # elsewhere a zero on the row's own λ (left out)
        extra_vals = np.zeros((nodes, f.p, 1))
        extra_cols[left, :, 0] = lam_cols[left - 1]
        extra_vals[left, :, 0] = np.where(held, -root_w[left, None], 0.0)
        cols = np.concatenate([cols, extra_cols], axis=2)
        vals = np.concatenate([vals, extra_vals], axis=2)
    kinks = None
    if shifts is not None:  # a shift makes a kink first-order: its two branches both modelled
        kinks = f.values.selection_kinks(xi, 2.0 * np.abs(shifts.selections))
        kinks = kinks if kinks.any() else None
    if kinks is not None:
        half = np.where(kinks, np.sqrt(0.5), 1.0)
        vals = vals * half[:, :, None]
    add((root_w[:, None] * r * (1.0 if kinks is None else half)).ravel(), cols.reshape(nodes * f.p, -1),
        vals.reshape(nodes * f.p, -1))
    if kinks is not None:  # ½(r + s)² as ¼ on each branch's linearization
        other = f.values.selection_residual(xi, flip=kinks)[1]
        node, column = np.nonzero(kinks)
        add(np.sqrt(0.5) * root_w[node] * r[node, column], y_cols[node],
            np.sqrt(0.5) * root_w[node, None] * other[node, column])
