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
entry) ≤ 1e-6 × the row's largest entry.

Exact polish (``exact_polish``, on by default). Interior-point and ADMM solvers end near
the optimum but not on it, and on degenerate rows (collinear or duplicate generators,
minimum-norm point 0: no strict complementarity) "near" may miss the gap by a hair or
come with a status like AlmostSolved. So every row's raw weights, whatever the status,
are polished (:func:`polish`): the support they identify (by weight, else by the KKT
gradient) is solved exactly on its affine hull as the native solver solves a support
pattern, and the polished weights replace the raw ones when they pass the same check.
A row whose status or check failed counts as solved only through polished weights that
pass the check (counted in :attr:`QPDirection.stats` as ``polished``); a row whose raw
weights pass but whose polish does not keeps its raw weights.

A row that still fails is solved once more by the same backend, in smaller QPs of only the
failed rows (``retry``; a stacked QP's tolerances are global, so a few rows of a large
stack can miss the per-row check that they meet alone, and an interior-point method
may stall on a large stack that it solves in small pieces), and polished again. A row that
still fails raises :class:`~qdframe.errors.BackendError` naming the backend, the row (and
node), the status and why the polish did not help, or, with ``fallback=True``, is solved
by ``native`` after a :class:`BackendFallbackWarning`. A bad direction is never returned
silently.
"""

from __future__ import annotations

import importlib
import warnings
from abc import abstractmethod
from contextvars import ContextVar
from dataclasses import astuple, dataclass, field
from types import ModuleType
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import scipy.sparse as sp

from ..errors import BackendError, InputError
from .base import Direction, MinNormDirection, Rule, number_rule
from .minnorm import min_norm_point, solve_on_support, validate_batch

if TYPE_CHECKING:
    from ..functional.quasidifferential import Quasidifferential

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
        center, generators, mask = validate_batch(center, generators, mask)
        rows = center.shape[0]
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


# --------------------------------------------------------------------------- polish

POLISH_THRESHOLDS = (1e-6, 1e-3, 1e-9)
"""Support rule 1 of :func:`polish`: entry p of group g is in the support when
λ_gp > τ × max_q λ_gq, for each τ here in turn. One τ is not enough: an interior point
leaves residue of a size that varies from row to row on inactive entries, and a genuine
weight may be small, so 1e-6 alone misses supports that 1e-3 (larger residue) or 1e-9
(small genuine weights) recover."""

POLISH_NEGATIVE = 1e-9
"""Polished weights must be ≥ −this (and sum to 1 within it) to be checked at all."""

_PINV_RTOL = 1e-12  # singular values below this × the largest count as 0 (the projection)


def polish(c: np.ndarray, a: np.ndarray, raw: np.ndarray, gap_tol: float) -> tuple[np.ndarray, np.ndarray, list[str | None]]:
    """Exact weights on the support that a backend's raw weights identify, and their check.

    c (B, d), a (B, G, m, d) scaled rows, raw (B, G, m) the backend's weights (whatever its
    status). Candidate supports S, in order:

      1. S_τ = {p : λ_gp > τ · max_q λ_gq}, the support of the weights, for τ = 1e-6, 1e-3,
         1e-9 (POLISH_THRESHOLDS: an interior point leaves ~1e-9…1e-5 on inactive entries,
         a genuine weight may be small);
      2. S₂ = {p : ⟨a_gp, y⟩ ≤ min_q ⟨a_gq, y⟩ + r}, the KKT-gradient rule at the backend's
         point y (r = 2 max ‖a‖ √gap(y) + 1e-12 bounds the error of these gradients);
      3. S_1e-6 ∪ S₂;

    each followed, on the rows it leaves open, by S minus the entries that came out
    negative on S (a near-active entry the backend gave a small weight). On S the problem
    restricted to the affine hull of S — stationarity with one multiplier per group, every
    group summing to 1 — is solved exactly by the native solver's batched QR
    (:func:`~qdframe.directions.minnorm.solve_on_support`). Its point is unique, its
    weights need not be: with duplicate or collinear generators, or the origin as the
    point (more than d + 1 affinely dependent generators), the QR's weights may be
    negative where nonnegative ones reach the same point; then the weights closest to the
    backend's (restricted to S) among all that reach it are tried, a rank-revealing (SVD)
    projection. A candidate must be feasible (≥ −POLISH_NEGATIVE, group sums within it)
    and pass :func:`certify` with the same gap_tol: the check alone decides, so a polished
    row is as certain as any other. Rows with non-finite raw weights cannot be polished.

    Returns clean weights, points and per-row problems (None: polished and certified;
    otherwise why the first support failed) for the rows of c.
    """
    rows, groups, width, _ = a.shape
    finite = np.isfinite(raw).all(axis=(1, 2))
    start = np.where(finite[:, None, None], np.maximum(raw, 0.0), 0.0)
    total = start.sum(axis=2, keepdims=True)
    start = np.where(total > 0.0, start / np.where(total > 0.0, total, 1.0), 1.0 / max(width, 1))
    y = c + np.einsum("bgp,bgpd->bd", start, a)
    values = np.einsum("bgpd,bd->bgp", a, y)
    slack = values - values.min(axis=2, keepdims=True, initial=np.inf)
    gap = np.einsum("bgp,bgp->b", start, slack)
    reach = 2.0 * np.sqrt(np.einsum("bgpd,bgpd->bgp", a, a).max(axis=(1, 2), initial=0.0) * gap) + 1e-12
    largest = start.max(axis=2, keepdims=True, initial=0.0)
    by_weight = [start > threshold * largest for threshold in POLISH_THRESHOLDS]
    by_gradient = slack <= reach[:, None, None]

    lam, points = start.copy(), y.copy()
    problems: list[str | None] = [None if ok else "weights not finite, nothing to polish" for ok in finite]
    open_rows = finite.copy()

    def accept(at: np.ndarray, candidate: np.ndarray, note: bool) -> np.ndarray:
        """Certify candidate weights of rows `at`; keep those that pass. Returns which passed."""
        clean, point, found = certify(c[at], a[at], candidate, POLISH_NEGATIVE, gap_tol)
        passed = np.array([problem is None for problem in found], dtype=bool)
        lam[at[passed]], points[at[passed]] = clean[passed], point[passed]
        open_rows[at[passed]] = False
        if note:
            for i in np.flatnonzero(~passed):
                problems[at[i]] = found[i]
        return passed

    for number, candidates in enumerate((*by_weight, by_gradient, by_weight[0] | by_gradient)):
        support = candidates
        for reduced in (False, True):
            at = np.flatnonzero(open_rows)
            if reduced:  # S minus its negative entries, where that changes S and leaves every group nonempty
                at = at[(support[at] != candidates[at]).any(axis=(1, 2)) & support[at].any(axis=2).all(axis=1)]
            if not at.size:
                continue
            own = solve_on_support(c[at], a[at], support[at])
            rest = ~accept(at, own, note=False)
            projected = closest_weights(c[at[rest]], a[at[rest]], support[at[rest]], start[at[rest]])
            accept(at[rest], projected, note=number == 0 and not reduced)
            if not reduced:
                support = candidates.copy()
                support[at[rest]] &= ~(projected < -POLISH_NEGATIVE)
    for b in np.flatnonzero(~open_rows & finite):
        problems[b] = None
    return lam, points, problems


def closest_weights(c: np.ndarray, a: np.ndarray, support: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Weights on `support` minimizing ‖c + Σ λ a‖ with group sums 1, the closest such to `start`.

    c (B, d), a (B, G, m, d); support, start (B, G, m). With x0 = start on S (0 elsewhere)
    and P the orthogonal projector onto {δ on S : Σ_p δ_gp = 0 for every g}, the weights
    are x0 + δ₀ − (A P)⁺ (c + A (x0 + δ₀)), δ₀ spreading each group's sum defect evenly
    over S_g: the least-squares step of minimum norm, by an SVD of A P in which singular
    values below _PINV_RTOL × the largest count as 0 (rank revealing, so dependent
    generators — duplicates, collinear points, more than d + 1 points — need no care).
    """
    rows, groups, width, dim = a.shape
    count = groups * width
    inside = support.astype(float)
    sizes = np.maximum(inside.sum(axis=2, keepdims=True), 1.0)
    x0 = np.where(support, start, 0.0)
    x0 = x0 + inside * (1.0 - x0.sum(axis=2, keepdims=True)) / sizes
    # P = diag(S) − Σ_g s_g s_gᵀ / |S_g|, applied to the rows of A (d × K)
    generators = a * inside[..., None]  # (B, G, m, d)
    projected = generators - inside[..., None] * generators.sum(axis=2, keepdims=True) / sizes[..., None]
    matrix = projected.reshape(rows, count, dim).transpose(0, 2, 1)  # A P: (B, d, K)
    residual = c + np.einsum("bgp,bgpd->bd", x0, a)
    u, s, vt = np.linalg.svd(matrix, full_matrices=False)
    keep = s > _PINV_RTOL * s[:, :1]
    inverse = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    step = np.einsum("bjk,bj,bij,bi->bk", vt, inverse, u, residual)
    return x0 - step.reshape(rows, groups, width)


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
    docstring), in units of the row's largest entry (squared for gap_tol). exact_polish:
    polish every row's weights exactly on their support (:func:`polish`); False returns
    the backend's weights as they are (and a failure status is then final).
    `stats` / `last_stats` count rows, polished rows, retried and failed rows.
    """

    fallback: bool = False
    retry: bool = True
    feas_tol: float = 1e-6
    gap_tol: float = 2.5e-13
    exact_polish: bool = True
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    _stats: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    name: ClassVar[str] = ""

    option_rules: ClassVar[dict[str, Rule]] = {
        "feas_tol": number_rule(above=0.0), "gap_tol": number_rule(above=0.0),
    }

    def __post_init__(self) -> None:
        self.check_options()

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

    @property
    def stats(self) -> "SolveStats":
        """Row counts of every min_norm call since the direction was made (or reset_stats)."""
        return self._stats.get("total", SolveStats())

    @property
    def last_stats(self) -> "SolveStats":
        """Row counts of the latest min_norm call."""
        return self._stats.get("last", SolveStats())

    def reset_stats(self) -> None:
        self._stats.clear()

    def _count(self, counts: "SolveStats") -> None:
        self._stats["last"] = counts
        self._stats["total"] = self.stats + counts

    def min_norm(self, center: np.ndarray, generators: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        batch = ScaledBatch.prepare(center, generators, mask)
        rows, groups = batch.generators.shape[:2]
        if rows == 0 or groups == 0:
            self._count(SolveStats(calls=1, rows=rows))
            return np.array(center, dtype=float), np.zeros(batch.mask.shape)
        c, a = batch.center, batch.generators
        lam, points, reasons, polished = self._attempt(c, a, retry=False)
        failed = [b for b in range(rows) if reasons[b] is not None]
        counts = SolveStats(calls=1, rows=rows, polished=int(polished.sum()))
        if self.retry and failed:  # once more, as QPs of only those rows
            index = np.array(failed)
            counts.retried = index.size
            lam[index], points[index], reasons_again, polished_again = self._attempt(c[index], a[index], retry=True)
            counts.polished += int(polished_again.sum())
            for i, b in enumerate(failed):
                reasons[b] = reasons_again[i]
            failed = [b for b in failed if reasons[b] is not None]
        counts.failed = len(failed)
        self._count(counts)
        points = points * batch.scale[:, None]
        weights = batch.weights_of(lam)
        if failed:
            first = failed[0]
            message = (
                f"direction {self.label!r} failed on {len(failed)} of {rows} min-norm QPs; first at "
                f"{_where(first, rows)}: status {reasons[first]!r}"
            )
            if not self.fallback:
                raise BackendError(message)
            warnings.warn(f"{message}; solved those by 'native' instead", BackendFallbackWarning, stacklevel=3)
            index = np.array(failed)
            points[index], weights[index] = min_norm_point(
                np.asarray(center, dtype=float)[index], np.asarray(generators, dtype=float)[index], batch.mask[index]
            )
        return points, weights

    def _attempt(
        self, c: np.ndarray, a: np.ndarray, retry: bool
    ) -> tuple[np.ndarray, np.ndarray, list[str | None], np.ndarray]:
        """One solve by the backend, the per-row check and the exact polish.

        Every row is polished (:func:`polish`); a row returns its polished weights when they
        pass the check, else the backend's own when those do (and the status is success).
        Returns clean weights, points, per-row reasons (None: the row is certified) and which
        rows were certified only thanks to the polish."""
        raw, status = self.solve_scaled(c, a, retry=retry)
        lam, points, problems = certify(c, a, raw, self.feas_tol, self.gap_tol)
        reasons = [
            status[b] if status[b] is not None else None if problems[b] is None else f"solved, but {problems[b]}"
            for b in range(len(c))
        ]
        polished = np.zeros(len(c), dtype=bool)
        if self.exact_polish:
            lam_p, points_p, problems_p = polish(c, a, raw, self.gap_tol)
            exact = np.array([problem is None for problem in problems_p], dtype=bool)
            lam[exact], points[exact] = lam_p[exact], points_p[exact]
            for b in range(len(c)):
                if exact[b] and reasons[b] is not None:
                    reasons[b], polished[b] = None, True
                elif reasons[b] is not None:
                    reasons[b] = f"{reasons[b]}; polished: {problems_p[b]}"
        return lam, points, reasons, polished


@dataclass
class SolveStats:
    """Row counts of QP-backend min_norm calls.

    rows: rows solved; polished: rows certified only after the exact polish (their
    backend's status was not success or its weights failed the check; see :func:`polish`);
    retried: rows given to the second attempt; failed: rows that raised or fell back.
    """

    calls: int = 0
    rows: int = 0
    polished: int = 0
    retried: int = 0
    failed: int = 0

    def __add__(self, other: "SolveStats") -> "SolveStats":
        return SolveStats(*(x + y for x, y in zip(astuple(self), astuple(other))))


def _where(row: int, rows: int) -> str:
    """'row r (node k, vertex v of −B_k)' when the node count of the batch is known."""
    nodes = _NODES.get()
    if not nodes or rows % nodes:
        return f"row {row}"
    per_node = rows // nodes
    if per_node == 1:
        return f"row {row} (node {row})"
    return f"row {row} (node {row // per_node}, vertex {row % per_node} of −B_k)"
