"""What the QP backends of the direction subproblem share.

Every backend (``osqp``, ``clarabel``, ``qpsolvers:NAME``, ``cvxpy``) solves the same
batch of minimum-norm-point problems as the ``native`` solver, in the form

    minimize ½‖p‖²   subject to   p − Σ_gp λ_gp a_gp = c,   Σ_p λ_gp = 1 (every g),   λ ≥ 0,

over (p, λ). The Hessian diag(I, 0) is positive semidefinite and the problem is exact
(no regularization): the point p is unique even where λ is not. Two preparations make
the problem well posed for every solver and keep its sparsity pattern fixed per shape:

* a masked-out generator is replaced by a copy of its group's first active one (a
  duplicate point does not change a convex hull), so there are no masks in the QP and
  its structure depends only on (rows, G, m, d); the weights of the copies are added
  back to the original entry afterwards;
* every row is divided by the power of two just above its largest absolute entry (as
  the native solver does), so absolute solver tolerances are relative to the row's data
  and the rescaling of the result is exact.

Status discipline. A backend returns raw weights and a per-row status ('' for success).
Then every row is checked: the weights must be finite, ≥ −``feas_tol`` and sum to 1
within ``feas_tol``; they are projected onto the simplices and the point y = c + Σ λ a
(now exactly in the polytope P) must satisfy the Frank–Wolfe (complementarity) gap

    gap(y) = Σ_g Σ_p λ_gp ⟨y, a_gp − a_g,q*⟩ ≤ ``gap_tol``,   q* = argmin_q ⟨y, a_gq⟩.

Since y* is in the ball with diameter [0, y] and on the far side of the supporting
hyperplane {s : ⟨y, s⟩ = min_P ⟨y, ·⟩}, ‖y − y*‖² ≤ gap(y): the default
``gap_tol`` = 2.5e-13 certifies ‖y − y*‖ ≤ 5e-7 × (power of two ≥ the row's largest
entry) ≤ 1e-6 × the row's largest entry. A row that fails is solved once more by the same backend, in smaller QPs of only the
failed rows (``retry``; a stacked QP's tolerances are global, so a few rows of a large
stack can miss the per-row check that they meet alone, and an interior-point method
may stall on a large stack that it solves in small pieces). A row that still fails raises
:class:`~qdframe.errors.BackendError` naming the backend, the row (and node) and the
status, or, with ``fallback=True``, is solved by ``native`` after a
:class:`BackendFallbackWarning`. A bad direction is never returned silently.
"""

from __future__ import annotations

import importlib
import warnings
from abc import abstractmethod
from contextvars import ContextVar
from dataclasses import dataclass, field
from types import ModuleType
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import scipy.sparse as sp

from ..errors import BackendError, InputError
from .base import Direction, MinNormDirection
from .minnorm import min_norm_point

if TYPE_CHECKING:
    from ..quasidifferential import Quasidifferential

_NODES: ContextVar[int | None] = ContextVar("qdframe_direction_nodes", default=None)
"""Number of nodes of the batch being solved (rows = nodes × vertices), for messages."""

_CACHE_LIMIT = 64  # solver objects kept per backend instance (one per chunk and shape)


class BackendFallbackWarning(UserWarning):
    """A QP backend failed on some rows, which were solved by `native` instead."""


def require(module: str, direction: str, install: str) -> ModuleType:
    """Import an optional solver package, or raise a BackendError with the pip command."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise BackendError(
            f"direction {direction!r} needs the package {module.split('.')[0]}: pip install {install}"
            f" ({type(exc).__name__}: {exc})"
        ) from exc


# ------------------------------------------------------------------------- the batch


@dataclass(frozen=True)
class ScaledBatch:
    """The batch as the QP backends see it.

    center (B, d) and generators (B, G, m, d) divided row-wise by `scale` (B,), a power
    of two; masked slots hold a copy of their group's first active generator (`first`,
    (B, G)). `mask` is the caller's mask.
    """

    center: np.ndarray
    generators: np.ndarray
    mask: np.ndarray
    first: np.ndarray
    scale: np.ndarray

    @classmethod
    def prepare(cls, center: object, generators: object, mask: object) -> "ScaledBatch":
        center = np.asarray(center, dtype=float)
        generators = np.asarray(generators, dtype=float)
        mask = np.asarray(mask)
        if center.ndim != 2:
            raise InputError("center", "a 2-D array of shape (B, d)", center.shape)
        rows, dim = center.shape
        if generators.ndim != 4 or generators.shape[0] != rows or generators.shape[3] != dim:
            raise InputError("generators", f"an array of shape ({rows}, G, m, {dim})", generators.shape)
        if mask.shape != generators.shape[:3] or mask.dtype != bool:
            raise InputError("mask", f"a boolean array of shape {generators.shape[:3]}", (mask.shape, str(mask.dtype)))
        if generators.shape[1] and not mask.any(axis=2).all():
            row, group = np.argwhere(~mask.any(axis=2))[0]
            raise InputError("mask", "at least one True entry in every group of every row", f"row {row}, group {group} empty")
        width = generators.shape[2]
        first = mask.argmax(axis=2) if width else np.zeros(generators.shape[:2], dtype=int)
        source = np.where(mask, np.arange(width), first[..., None])
        filled = np.take_along_axis(generators, source[..., None], axis=2)
        if not (np.isfinite(center).all() and np.isfinite(filled).all()):
            raise InputError("center, generators", "finite values (at the active entries)")
        largest = np.maximum(
            np.abs(center).max(axis=1, initial=0.0), np.abs(filled).reshape(rows, -1).max(axis=1, initial=0.0)
        )
        _, exponent = np.frexp(np.where(largest > 0.0, largest, 1.0))
        scale = np.ldexp(1.0, exponent)
        return cls(center / scale[:, None], filled / scale[:, None, None, None], mask, first, scale)

    def weights_of(self, lam: np.ndarray) -> np.ndarray:
        """Weights (B, G, m) on the caller's entries from weights on the filled slots."""
        weights = np.where(self.mask, lam, 0.0)
        extra = np.where(self.mask, 0.0, lam).sum(axis=2, keepdims=True)
        np.put_along_axis(
            weights, self.first[..., None], np.take_along_axis(weights, self.first[..., None], axis=2) + extra, axis=2
        )
        return weights


def certify(
    c: np.ndarray, a: np.ndarray, lam: np.ndarray, feas_tol: float, gap_tol: float
) -> tuple[np.ndarray, np.ndarray, list[str | None]]:
    """Check raw weights of scaled rows; returns clean weights, points and per-row problems.

    c (B, d), a (B, G, m, d), lam (B, G, m). A row's problem is None when its weights are
    feasible within feas_tol and the Frank–Wolfe gap of the projected weights is ≤ gap_tol.
    """
    rows = len(c)
    finite = np.isfinite(lam).all(axis=(1, 2))
    lam = np.where(finite[:, None, None], lam, 0.0)
    lowest = lam.min(axis=(1, 2), initial=np.inf)
    sum_error = np.abs(lam.sum(axis=2) - 1.0).max(axis=1, initial=0.0)
    clean = np.maximum(lam, 0.0)
    total = clean.sum(axis=2, keepdims=True)
    clean = np.where(total > 0.0, clean / np.where(total > 0.0, total, 1.0), 1.0 / lam.shape[2])
    y = c + np.einsum("bgp,bgpd->bd", clean, a)
    values = np.einsum("bgpd,bd->bgp", a, y)
    gap = np.einsum("bgp,bgp->b", clean, values - values.min(axis=2, keepdims=True))
    problems: list[str | None] = [None] * rows
    for b in np.flatnonzero(~finite | (lowest < -feas_tol) | (sum_error > feas_tol) | ~(gap <= gap_tol)):
        if not finite[b]:
            problems[b] = "weights not finite"
        elif lowest[b] < -feas_tol or sum_error[b] > feas_tol:
            problems[b] = f"weights off the simplex (min {lowest[b]:.1e}, |sum − 1| {sum_error[b]:.1e})"
        else:
            problems[b] = f"KKT check failed: complementarity gap {gap[b]:.1e} > {gap_tol:.1e}"
    return clean, y, problems


# ------------------------------------------------------------------ sparse structure


@dataclass(frozen=True)
class BlockQP:
    """Sparsity of the block-diagonal QP of `rows` min-norm problems (fixed per shape).

    Variables, per row b: [p_b (d), λ_b (K = G·m)]. Constraint rows: first all equality
    rows, per row [p − Σ λ a = c (d), Σ_p λ_gp = 1 (G)], then, if `bound_sign` ≠ 0, the
    rows bound_sign · λ (K per row) for a solver that takes λ ≥ 0 as constraint rows
    (OSQP: +1 with 0 ≤ λ; Clarabel: −1 with −λ + s = 0, s ≥ 0). The objective ½‖p‖²
    is the upper-triangular P with ones on the p coordinates. Matrix values are only
    replaced (`A_data`), never restructured, so solvers can update them in place.
    """

    rows: int
    groups: int
    width: int
    dim: int
    bound_sign: int
    P: sp.csc_matrix
    indptr: np.ndarray
    indices: np.ndarray
    template: np.ndarray  # the values of A in CSC order, with the generator block 0
    generator_slots: np.ndarray  # CSC positions of the −a entries, in (b, j, k) order

    @classmethod
    def build(cls, rows: int, groups: int, width: int, dim: int, bound_sign: int) -> "BlockQP":
        k_count = groups * width
        per_var, per_eq = dim + k_count, dim + groups
        b = np.arange(rows)[:, None]
        j, k = np.arange(dim), np.arange(k_count)
        parts_r = [b * per_eq + j, (b * per_eq + j)[:, :, None] + 0 * k, b * per_eq + dim + k // width]
        parts_c = [b * per_var + j, (b * per_var + dim + k)[:, None, :] + 0 * j[:, None], b * per_var + dim + k]
        parts_v = [np.ones((rows, dim)), np.zeros((rows, dim, k_count)), np.ones((rows, k_count))]
        if bound_sign:
            parts_r.append(rows * per_eq + b * k_count + k)
            parts_c.append(b * per_var + dim + k)
            parts_v.append(np.full((rows, k_count), float(bound_sign)))
        r = np.concatenate([x.ravel() for x in parts_r])
        col = np.concatenate([x.ravel() for x in parts_c])
        order = np.lexsort((r, col))
        slot = np.empty_like(order)
        slot[order] = np.arange(order.size)
        start = rows * dim
        generator_slots = slot[start : start + rows * dim * k_count]
        indptr = np.concatenate([[0], np.cumsum(np.bincount(col, minlength=rows * per_var))])
        template = np.concatenate([x.ravel() for x in parts_v])[order]
        diag = (b * per_var + j).ravel()
        n = rows * per_var
        P = sp.csc_matrix(
            (np.ones(diag.size), diag, np.concatenate([[0], np.cumsum(np.bincount(diag, minlength=n))])), shape=(n, n)
        )
        return cls(rows, groups, width, dim, bound_sign, P, indptr, r[order], template, generator_slots)

    @property
    def n_variables(self) -> int:
        return self.rows * (self.dim + self.groups * self.width)

    @property
    def n_equalities(self) -> int:
        return self.rows * (self.dim + self.groups)

    @property
    def n_constraints(self) -> int:
        return self.n_equalities + (self.rows * self.groups * self.width if self.bound_sign else 0)

    def A_data(self, a: np.ndarray) -> np.ndarray:
        """The values of A (CSC order) for scaled generators a (rows, G, m, d)."""
        data = self.template.copy()
        data[self.generator_slots] = -a.reshape(self.rows, -1, self.dim).transpose(0, 2, 1).ravel()
        return data

    def A(self, a: np.ndarray) -> sp.csc_matrix:
        return sp.csc_matrix((self.A_data(a), self.indices, self.indptr), shape=(self.n_constraints, self.n_variables))

    def equality_rhs(self, c: np.ndarray) -> np.ndarray:
        """Right-hand side of the equality rows: [c_b, 1 (G)] per row."""
        return np.concatenate([c, np.ones((self.rows, self.groups))], axis=1).ravel()

    def lower_bounds(self) -> np.ndarray:
        """−∞ on p, 0 on λ, for solvers that take bounds on the variables."""
        per_row = np.concatenate([np.full(self.dim, -np.inf), np.zeros(self.groups * self.width)])
        return np.tile(per_row, self.rows)

    def weights(self, x: np.ndarray) -> np.ndarray:
        """λ (rows, G, m) from a solution vector."""
        return x.reshape(self.rows, -1)[:, self.dim :].reshape(self.rows, self.groups, self.width)


def chunks(rows: int, chunk_rows: int) -> list[slice]:
    """Consecutive row ranges of at most chunk_rows rows (all rows for chunk_rows ≤ 0)."""
    size = rows if chunk_rows <= 0 else min(chunk_rows, rows)
    return [slice(start, min(start + size, rows)) for start in range(0, rows, max(size, 1))]


# --------------------------------------------------------------------- the base class


@dataclass(frozen=True)
class QPDirection(MinNormDirection):
    """The paper's direction with the min-norm QPs solved by a QP library.

    fallback: solve the rows a backend fails on by `native` (with a warning) instead of
    raising BackendError. retry: first solve the failed rows once more by the same
    backend, as separate, smaller QPs of only those rows (a backend may use other
    settings for them). feas_tol, gap_tol: the per-row acceptance check (module
    docstring), in units of the row's largest entry (squared for gap_tol).
    """

    fallback: bool = False
    retry: bool = True
    feas_tol: float = 1e-6
    gap_tol: float = 2.5e-13
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    name: ClassVar[str] = ""

    def __post_init__(self) -> None:
        for name in ("feas_tol", "gap_tol"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
                raise InputError(name, "a positive finite number", value)

    @property
    def label(self) -> str:
        """The name this direction is registered and reported under."""
        return self.name

    @abstractmethod
    def solve_scaled(self, c: np.ndarray, a: np.ndarray, retry: bool = False) -> tuple[np.ndarray, list[str | None]]:
        """Raw weights (B, G, m) and per-row solver status (None = success) of the scaled
        problems min ‖c_b + Σ λ a_b‖ with λ_bg in the unit simplex; c (B, d), a (B, G, m, d).
        retry: this is the second attempt, on the rows that failed the first (solver objects
        are then not kept for later calls, and a backend may use other settings)."""

    def cached(self, key: Any, build: Callable[[], Any], persistent: bool = True) -> tuple[Any, bool]:
        """(solver object for `key`, whether it was built just now). Built once per key
        (shape and chunk) by build() and kept when persistent."""
        if not persistent:
            return build(), True
        if key in self._cache:
            return self._cache[key], False
        if len(self._cache) >= _CACHE_LIMIT:
            self._cache.clear()
        self._cache[key] = build()
        return self._cache[key], True

    def from_quasidifferential(self, qd: "Quasidifferential", weights: np.ndarray) -> Direction:
        token = _NODES.set(qd.sub.nodes)
        try:
            return super().from_quasidifferential(qd, weights)
        finally:
            _NODES.reset(token)

    def min_norm(self, center: np.ndarray, generators: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        batch = ScaledBatch.prepare(center, generators, mask)
        rows, groups = batch.generators.shape[:2]
        if rows == 0 or groups == 0:
            return np.array(center, dtype=float), np.zeros(batch.mask.shape)
        c, a = batch.center, batch.generators
        raw, status = self.solve_scaled(c, a)
        lam, points, problems = certify(c, a, raw, self.feas_tol, self.gap_tol)
        failed = [b for b in range(rows) if status[b] is not None or problems[b] is not None]
        if self.retry and failed:  # once more, as QPs of only those rows
            index = np.array(failed)
            raw_again, status_again = self.solve_scaled(c[index], a[index], retry=True)
            lam_again, points_again, problems_again = certify(c[index], a[index], raw_again, self.feas_tol, self.gap_tol)
            lam[index], points[index] = lam_again, points_again
            for i, b in enumerate(failed):
                status[b], problems[b] = status_again[i], problems_again[i]
            failed = [b for b in failed if status[b] is not None or problems[b] is not None]
        points = points * batch.scale[:, None]
        weights = batch.weights_of(lam)
        if failed:
            first = failed[0]
            reason = status[first] if status[first] is not None else f"solved, but {problems[first]}"
            message = (
                f"direction {self.label!r} failed on {len(failed)} of {rows} min-norm QPs; first at "
                f"{_where(first, rows)}: status {reason!r}"
            )
            if not self.fallback:
                raise BackendError(message)
            warnings.warn(f"{message}; solved those by 'native' instead", BackendFallbackWarning, stacklevel=3)
            index = np.array(failed)
            points[index], weights[index] = min_norm_point(
                np.asarray(center, dtype=float)[index], np.asarray(generators, dtype=float)[index], batch.mask[index]
            )
        return points, weights


def _where(row: int, rows: int) -> str:
    """'row r (node k, vertex v of −B_k)' when the node count of the batch is known."""
    nodes = _NODES.get()
    if not nodes or rows % nodes:
        return f"row {row}"
    per_node = rows // nodes
    if per_node == 1:
        return f"row {row} (node {row})"
    return f"row {row} (node {row // per_node}, vertex {row % per_node} of −B_k)"
