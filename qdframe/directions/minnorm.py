"""Exact, batched minimum-norm points of sums of simplices (Wolfe's problem).

For every batch row b the function :func:`min_norm_point` solves

    minimize   ‖ c_b + Σ_g Σ_p λ_bgp · a_bgp ‖²
    subject to λ_bg in the unit simplex over the active entries (mask_bgp True),

i.e. it finds the Euclidean distance from the origin to the convex polyhedron
c_b + Σ_g co{a_bgp} ("finding the Euclidean distance from a point to a convex
polyhedron", Wolfe 1976). The minimum-norm *point* y_b is unique; the weights λ
need not be.

Method (active-set enumeration, vectorized over the batch)
-----------------------------------------------------------
1. Every row is divided by the power of two just above its largest absolute
   entry, so all tolerances below are relative and the result is scale
   invariant; the point is computed at the end from the returned weights (the
   power-of-two rescaling is exact). Internally the batch axis is last, so that
   every NumPy operation runs over long contiguous vectors.
2. A group with exactly one active entry in every row is folded into the center
   (its weight is 1 there).
3. For the remaining groups a *support pattern* picks one nonempty subset S_g of
   the (anywhere) active entries per group. On a pattern the problem restricted to
   the affine hull is an unconstrained least-squares problem: with a base entry
   s_g ∈ S_g,

       y = y0 + D μ,   y0 = c + Σ_g a_{g,s_g},   D = [a_gp − a_{g,s_g}]_{p ∈ S_g∖s_g},

   and λ_gp = μ_gp, λ_{g,s_g} = 1 − Σ_p μ_gp. All rows are solved at once by a
   batched Gram–Schmidt QR of D (classical Gram–Schmidt with one
   re-orthogonalization, "twice is enough"). Patterns whose D is (numerically)
   rank deficient are rejected: by Carathéodory's argument some optimal λ has a
   support with affinely independent directions, and every sub-pattern is
   enumerated as well. Hence duplicate or collinear generators and the origin as
   a generator need no special treatment. Patterns with more free directions than
   the dimension d are skipped for the same reason.
4. A candidate is feasible when its λ ≥ −tiny. Among feasible candidates a row
   prefers one that passes the optimality (KKT) check, and among those the
   smallest ‖y‖. The check is normalized: for every group, supported p and active
   q, the slope <a_gp − a_gq, y> / ‖a_gp − a_gq‖ must be ≤ ~1e-12 (scaled units).
   Unlike the plain gap <a_gp − a_gq, y>, or a comparison of norms, this does not
   lose a nearby better point on a tiny edge (nearly equal generators), where the
   norms differ only below rounding. Single-vertex patterns are always feasible, so
   every row gets an answer; the exact optimum is feasible and passes the check,
   so it wins.

The loop runs over patterns, never over rows. The number of patterns is
Π_g (2^{m_g} − 1) before the dimension cut, and the cost grows with it; beyond
`_DIRECT_PATTERNS` (64, where the two methods cost about the same) the solver
switches to an iterative method, still batched over rows: a few accelerated
projected gradient iterations (FISTA with adaptive restart and a vectorized
simplex projection) give feasible weights close to optimal, and an exact *polish*
finishes from there: Wolfe's primal active-set method, each step being the
least-squares solve of step 3 on a per-row support. A row is done when it passes
the optimality check of step 4, so this path is exact as well. Only round-off
cycling on nearly degenerate data can make a row hit the step cap; such rows are
solved again by enumeration if there are at most :data:`PATTERN_CAP` (4096)
patterns, and otherwise keep feasible, nearly optimal weights.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

PATTERN_CAP = 4096
"""Largest number of support patterns ever enumerated (see the module docstring)."""

_DIRECT_PATTERNS = 64  # up to this many patterns enumeration is faster than active-set steps

_RANK_RTOL = 1e-10  # a direction counts as dependent below this relative residual
_RANK_ATOL = 1e-14  # ... or below this absolute one (scaled rows have |entries| ≤ 1)
_FEASIBILITY_TOL = 1e-12  # λ ≥ −this counts as feasible
_KKT_TOL = 1e-12  # tolerance of the normalized optimality check (a length, scaled rows)
_WARM_START_ITERATIONS = 30  # gradient iterations before the active-set steps
_POLISH_STEPS = 500  # cap on active-set steps (each one decreases ‖y‖ or the support)

Pattern = tuple[tuple[int, ...], ...]  # one nonempty tuple of entry indices per group


def min_norm_point(center: np.ndarray, generators: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-norm points of a batch of sums of simplices.

    center: (B, d); generators: (B, G, m, d); mask: (B, G, m) bool with at least one
    True per group and row. Masked-out generators are ignored (they may hold any
    value). Returns ``(points, weights)`` of shapes (B, d) and (B, G, m), where
    ``points = center + Σ_g Σ_p weights · generators`` and every ``weights[b, g]`` lies
    in the unit simplex over the active entries. G = 0 returns the center itself.

    Raises :class:`~qdframe.errors.InputError` (a ValueError) naming the argument for
    wrong shapes, a non-boolean mask, non-finite values or an empty group.
    """
    center, generators, mask = validate_batch(center, generators, mask)
    rows, groups, width, _ = generators.shape
    if groups == 0 or rows == 0:
        return center.copy(), np.zeros((rows, groups, width))

    # Internally the batch axis is last, so that every operation runs over long
    # contiguous vectors: c (d, B), a (G, m, d, B), active and λ (G, m, B).
    c, a, active, scale = _scaled_batch_last(center, generators, mask)
    lam = np.zeros((groups, width, rows))
    fixed = (active.sum(axis=1) == 1).all(axis=1)  # groups that are a single point in every row
    lam[fixed] = active[fixed]
    live = np.flatnonzero(~fixed)
    if live.size:
        folded = c + np.einsum("gpb,gpdb->db", lam[fixed], a[fixed])
        lam[live] = _solve_scaled(folded, a[live], active[live])

    points = (c + np.einsum("gpb,gpdb->db", lam, a)) * scale  # exact: scale is a power of 2
    return np.ascontiguousarray(points.T), np.ascontiguousarray(lam.transpose(2, 0, 1))


# ----------------------------------------------------------------------------- input


def validate_batch(center: object, generators: object, mask: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A min-norm batch as float arrays center (B, d), generators (B, G, m, d) and a bool
    mask (B, G, m); a wrong shape or type is an InputError naming the argument."""
    center = _real_array("center", center)
    generators = _real_array("generators", generators)
    mask = np.asarray(mask)
    if center.ndim != 2:
        raise InputError("center", "a 2-D array of shape (B, d)", center.shape)
    rows, dim = center.shape
    if generators.ndim != 4 or generators.shape[0] != rows or generators.shape[3] != dim:
        raise InputError("generators", f"an array of shape ({rows}, G, m, {dim})", generators.shape)
    if mask.shape != generators.shape[:3]:
        raise InputError("mask", f"an array of shape {generators.shape[:3]}", mask.shape)
    if mask.dtype != bool:
        raise InputError("mask", "a boolean array", str(mask.dtype))
    return center, generators, mask


def _scaled_batch_last(
    center: np.ndarray, generators: np.ndarray, mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Batch-last copies divided row-wise by a power of two ≥ the largest |entry|.

    Returns c (d, B), a (G, m, d, B) with inactive generators set to 0, active (G, m, B)
    and the scale (B,). Checks finiteness and that no group is empty.
    """
    active = np.ascontiguousarray(mask.transpose(1, 2, 0))
    empty = ~active.any(axis=1)
    if empty.any():
        group, row = np.argwhere(empty)[0]
        expected = "at least one True entry in every group of every row"
        raise InputError("mask", expected, f"row {row}, group {group} empty")
    c = np.array(center.T, order="C")  # always a copy: it is scaled in place below
    if not np.isfinite(c).all():
        raise InputError("center", "finite values")
    a = np.zeros(generators.shape[1:] + generators.shape[:1])
    np.copyto(a, generators.transpose(1, 2, 3, 0), where=active[:, :, None])
    if not np.isfinite(a).all():
        raise InputError("generators", "finite values at the active (mask True) entries")
    largest = np.maximum(np.abs(c).max(axis=0, initial=0.0), np.abs(a).max(axis=(0, 1, 2), initial=0.0))
    _, exponent = np.frexp(np.where(largest > 0.0, largest, 1.0))
    scale = np.ldexp(1.0, np.minimum(exponent, 1023))  # 2^1024 would overflow
    c /= scale
    a /= scale
    return c, a, active, scale


def _real_array(name: str, value: object) -> np.ndarray:
    array = np.asarray(value)
    if array.dtype.kind not in "biuf":
        raise InputError(name, "a real numeric array", str(array.dtype))
    return array.astype(float, copy=False)


# ------------------------------------------------------------------ the scaled problem
# From here on: c (d, B), a (G, m, d, B) with inactive generators 0, active and
# weights λ (G, m, B), points y (d, B).


def _solve_scaled(c: np.ndarray, a: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Optimal weights (G, m, B) of the row-normalized problem."""
    patterns = _support_patterns(active.any(axis=2), budget=c.shape[0], cap=PATTERN_CAP)
    if patterns is not None and len(patterns) <= _DIRECT_PATTERNS:
        return _enumerated(c, a, active, patterns)
    lam, certified = _active_set(c, a, active)
    if patterns is not None and not certified.all():  # rescue rows that hit the step cap
        rows = (Ellipsis, ~certified)
        lam[rows] = _enumerated(c[rows], a[rows], active[rows], patterns)
    return lam


def _enumerated(c: np.ndarray, a: np.ndarray, active: np.ndarray, patterns: list[Pattern]) -> np.ndarray:
    """Best candidate of every row over all support patterns."""
    best = _Incumbent.empty(active.shape)
    for pattern in patterns:
        lam, y, support, valid = _pattern_candidate(c, a, active, pattern)
        best.offer(a, active, lam, y, support, valid)
    return _cleaned(best.weights, active)


def _support_patterns(active: np.ndarray, budget: int, cap: int) -> list[Pattern] | None:
    """Every choice of one nonempty subset of active entries per group with at most
    `budget` free directions in total (Σ_g |S_g| − 1 ≤ d); None if there are more than `cap`."""
    choices = []
    for entries in active:
        index = np.flatnonzero(entries).tolist()
        choices.append([s for r in range(1, len(index) + 1) for s in itertools.combinations(index, r)])
    patterns: list[Pattern] = []

    def extend(group: int, chosen: Pattern, used: int) -> bool:
        if group == len(choices):
            patterns.append(chosen)
            return len(patterns) <= cap
        for subset in choices[group]:  # ordered by size, so `break` is safe
            if used + len(subset) - 1 > budget:
                break
            if not extend(group + 1, chosen + (subset,), used + len(subset) - 1):
                return False
        return True

    return patterns if extend(0, (), 0) else None


def _pattern_candidate(
    c: np.ndarray, a: np.ndarray, active: np.ndarray, pattern: Pattern
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Minimizer on the affine hull of one support pattern, for all rows at once.

    Returns the weights (G, m, B), the point (d, B), the pattern's support (G, m) and
    the rows (B,) where the candidate is valid: the pattern uses only active entries,
    its directions are independent and the weights are nonnegative.
    """
    groups, width, _, rows = a.shape
    group_index = np.arange(groups)
    base = np.array([subset[0] for subset in pattern])
    support = np.zeros((groups, width), dtype=bool)
    for g, subset in enumerate(pattern):
        support[g, list(subset)] = True
    valid = active[support].all(axis=0)

    lam = np.zeros((groups, width, rows))
    lam[group_index, base] = 1.0
    y = c + a[group_index, base].sum(axis=0)
    free_g = np.array([g for g, subset in enumerate(pattern) for _ in subset[1:]], dtype=int)
    free_p = np.array([p for subset in pattern for p in subset[1:]], dtype=int)
    if free_g.size:
        directions = a[free_g, free_p] - a[free_g, base[free_g]]  # (k, d, B)
        mu, dependent = _affine_least_squares(y, directions)
        y = y + np.einsum("kb,kdb->db", mu, directions)
        lam[free_g, free_p] = mu
        for g in np.unique(free_g):
            lam[g, base[g]] -= mu[free_g == g].sum(axis=0)
        valid &= ~dependent & (lam[support] >= -_FEASIBILITY_TOL).all(axis=0)
    return lam, y, support, valid


def _affine_least_squares(
    y0: np.ndarray, directions: np.ndarray, present: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """μ minimizing ‖y0 + Σ_j μ_j directions_j‖ for every row, by a batched QR.

    y0: (d, B); directions: (k, d, B); present: optional (k, B) bool — absent columns
    get μ = 0. Numerically dependent columns are dropped as well (μ = 0) and
    reported: returns μ (k, B) and a (B,) flag "some present column was dependent".
    """
    count, _, rows = directions.shape
    q = np.zeros_like(directions)  # orthonormal columns (0 for dropped ones)
    r = np.zeros((count, count, rows))  # upper triangular factor
    dependent = np.zeros(rows, dtype=bool)
    for j in range(count):
        v = directions[j] if present is None else directions[j] * present[j]
        for _ in range(2):  # classical Gram–Schmidt, twice
            coefficients = np.einsum("idb,db->ib", q[:j], v)
            v = v - np.einsum("ib,idb->db", coefficients, q[:j])
            r[:j, j] += coefficients
        residual = np.sqrt(np.einsum("db,db->b", v, v))
        length = np.sqrt(np.einsum("db,db->b", directions[j], directions[j]))
        keep = residual > _RANK_RTOL * length + _RANK_ATOL
        dependent |= ~keep if present is None else ~keep & present[j]
        q[j] = v * np.where(keep, 1.0 / np.where(keep, residual, 1.0), 0.0)
        r[j, j] = np.where(keep, residual, 1.0)
    rhs = -np.einsum("kdb,db->kb", q, y0)
    mu = np.zeros((count, rows))
    for j in reversed(range(count)):  # back substitution R μ = −Qᵀ y0
        mu[j] = (rhs[j] - np.einsum("ib,ib->b", r[j, j + 1 :], mu[j + 1 :])) / r[j, j]
    return mu, dependent


@dataclass
class _Incumbent:
    """Per-row best candidate: KKT-satisfying first, then least ‖y‖²."""

    weights: np.ndarray
    objective: np.ndarray
    optimal: np.ndarray

    @classmethod
    def empty(cls, shape: tuple[int, ...]) -> "_Incumbent":
        rows = shape[-1]
        return cls(np.zeros(shape), np.full(rows, np.inf), np.zeros(rows, dtype=bool))

    def offer(
        self, a: np.ndarray, active: np.ndarray, lam: np.ndarray, y: np.ndarray, support: np.ndarray, valid: np.ndarray
    ) -> None:
        """Candidate weights λ with point y = c + Σ λ a and support (G, m)."""
        objective = np.einsum("db,db->b", y, y)
        optimal = _kkt_violation(a, active, y, support) <= _KKT_TOL
        better = valid & ((optimal & ~self.optimal) | ((optimal == self.optimal) & (objective < self.objective)))
        np.copyto(self.weights, lam, where=better)
        np.copyto(self.objective, objective, where=better)
        np.copyto(self.optimal, optimal, where=better)


def _kkt_violation(a: np.ndarray, active: np.ndarray, y: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Largest normalized KKT violation of every row: (B,), see :func:`_slopes`."""
    return _slopes(a, active, y, support).max(axis=(0, 1))


def _slopes(a: np.ndarray, active: np.ndarray, y: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Normalized KKT violations (G, m, B), ≥ 0, of moving weight onto every unsupported q.

    Entry (g, q) is the maximum over supported p of the slope
    <a_gp − a_gq, y> / ‖a_gp − a_gq‖ with which ‖y‖²/2 decreases when weight moves
    from p to q (0 where q is supported or inactive). At the optimum all are 0; the
    supported entries need no check, as every candidate is the minimizer on the
    affine hull of its support. Unlike the plain gap <a_gp − a_gq, y> this does not
    vanish for a short edge, so a vertex next to a nearby better point on a tiny
    edge is not mistaken for optimal. The differences are taken before the inner
    product, which keeps them accurate for nearly equal generators.
    support: (G, m) for one pattern or (G, m, B) per row.
    """
    groups, width = active.shape[:2]
    worst = np.zeros(active.shape)
    for g, p, q in itertools.product(range(groups), range(width), range(width)):
        if support.ndim == 2:  # one pattern: decided without touching the rows
            if not support[g, p] or support[g, q]:
                continue
            applies = active[g, q]
        else:
            applies = support[g, p] & active[g, q] & ~support[g, q]
            if not applies.any():
                continue
        edge = a[g, p] - a[g, q]
        length = np.sqrt(np.einsum("db,db->b", edge, edge))
        slope = np.einsum("db,db->b", edge, y)
        ratio = np.divide(slope, length, out=np.zeros_like(slope), where=length > 0.0)
        worst[g, q] = np.maximum(worst[g, q], np.where(applies, ratio, 0.0))
    return worst


def _cleaned(lam: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Clip round-off negatives, zero inactive entries and renormalize every group to sum 1."""
    lam = np.where(active, np.maximum(lam, 0.0), 0.0)
    return lam / lam.sum(axis=1, keepdims=True)


# ------------------------------------------------------------ active-set method (many patterns)


def _active_set(c: np.ndarray, a: np.ndarray, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A few accelerated projected gradient iterations, then exact active-set steps
    from the (feasible) iterate. Returns the weights and which rows are certified."""
    lam = _Fista.start(c, a, active).run(_WARM_START_ITERATIONS)
    lam, certified = _active_set_polish(c, a, active, lam)
    return _cleaned(lam, active), certified


def _active_set_polish(
    c: np.ndarray, a: np.ndarray, active: np.ndarray, lam: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Wolfe's primal active-set method, batched over rows, from feasible weights λ.

    Each step solves the least-squares problem on the current support S (dependent
    directions dropped). If that target has negative weights the row moves from λ
    towards it as far as feasibility allows and drops the blocking entries (a minor
    cycle); otherwise λ becomes the target and, unless it passes the optimality check,
    the unsupported entry with the steepest descent slope joins S (a major cycle). A
    row is final when it passes the check; ‖y‖ decreases strictly, so this ends after
    finitely many steps. `_POLISH_STEPS` guards against round-off cycling; a row still
    pending then keeps its current feasible λ and is reported as not certified.
    """
    groups, width, rows = lam.shape
    lam = lam.copy()
    support = lam > 0.0
    pending = np.arange(rows)
    for _ in range(_POLISH_STEPS):
        at = (Ellipsis, pending)
        current, supported = lam[at], support[at]
        target = _solve_on_support(c[at], a[at], supported)

        blocking = supported & (target < 0.0)
        ratio = np.divide(current, current - target, out=np.full(current.shape, np.inf), where=blocking)
        step = np.minimum(ratio.min(axis=(0, 1)), 1.0)
        raw = current + step * (target - current)
        moved = np.where(supported & (ratio > step) & (raw > 0.0), raw, 0.0)
        emptied = moved.sum(axis=1) <= 0.0  # (groups, rows): all entries blocked at once (ties)
        if emptied.any():  # keep the largest supported entry of such a group, with weight 1
            best = np.where(supported, raw, -np.inf).argmax(axis=1)
            g, r = np.nonzero(emptied)
            moved[g, best[g, r], r] = 1.0
        moved /= moved.sum(axis=1, keepdims=True)
        supported = moved > 0.0

        slopes = _slopes(a[at], active[at], _point(c[at], a[at], moved), supported)
        steepest = slopes.reshape(groups * width, -1).argmax(axis=0)
        major = ~blocking.any(axis=(0, 1))
        final = major & (slopes.max(axis=(0, 1)) <= _KKT_TOL)
        joins = np.flatnonzero(major & ~final)
        supported[steepest[joins] // width, steepest[joins] % width, joins] = True

        lam[at], support[at] = moved, supported
        pending = pending[~final]
        if not pending.size:
            break
    certified = np.ones(rows, dtype=bool)
    certified[pending] = False
    return lam, certified


def _point(c: np.ndarray, a: np.ndarray, lam: np.ndarray) -> np.ndarray:
    return c + np.einsum("gpb,gpdb->db", lam, a)


def _solve_on_support(c: np.ndarray, a: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Least-squares weights (G, m, B) on a per-row support; dependent directions are dropped."""
    groups, width, dim, rows = a.shape
    base = np.argmax(support, axis=1)  # (G, B): a supported entry of every group
    base_vectors = np.take_along_axis(a, base[:, None, None, :], axis=1)  # (G, 1, d, B)
    y0 = c + base_vectors.sum(axis=(0, 1))
    directions = (a - base_vectors).reshape(groups * width, dim, rows)
    is_base = np.arange(width)[:, None] == base[:, None, :]  # (G, m, B)
    mu, _ = _affine_least_squares(y0, directions, (support & ~is_base).reshape(groups * width, rows))
    lam = mu.reshape(groups, width, rows)
    return np.where(is_base, 1.0 - lam.sum(axis=1, keepdims=True), lam)


def solve_on_support(center: np.ndarray, generators: np.ndarray, support: np.ndarray) -> np.ndarray:
    """The exact step of the active-set method, batch first: least-squares weights on a support.

    center (B, d), generators (B, G, m, d) (row-scaled), support (B, G, m) bool with at least
    one True per group. Returns λ (B, G, m): 0 off the support, every group summing to 1,
    c + Σ λ a the minimum-norm point of the affine hull of the support (dependent directions
    are dropped, so λ may be negative even where a nonnegative λ reaches the same point).
    Used by the QP backends' polish (:mod:`qdframe.directions.qp`).
    """
    lam = _solve_on_support(
        np.ascontiguousarray(center.T),
        np.ascontiguousarray(generators.transpose(1, 2, 3, 0)),
        np.ascontiguousarray(support.transpose(1, 2, 0)),
    )
    return np.ascontiguousarray(lam.transpose(2, 0, 1))


@dataclass
class _Fista:
    """FISTA with adaptive restart on λ.

    It works on centered copies of the data (a_gp − mean_p a_gp, the mean moved into
    the center), which change nothing in the problem but shrink the step constant.
    """

    c: np.ndarray
    a: np.ndarray
    active: np.ndarray
    lipschitz: np.ndarray
    lam: np.ndarray
    extrapolated: np.ndarray
    momentum: np.ndarray

    @classmethod
    def start(cls, c: np.ndarray, a: np.ndarray, active: np.ndarray) -> "_Fista":
        count = active.sum(axis=1, keepdims=True)
        mean = a.sum(axis=1) / count  # (G, d, B)
        centered = (a - mean[:, None]) * active[:, :, None]
        lipschitz = np.maximum(np.einsum("gpdb,gpdb->b", centered, centered), 1e-300)
        lam = active / count
        return cls(c + mean.sum(axis=0), centered, active, lipschitz, lam, lam, np.ones(c.shape[-1]))

    def run(self, iterations: int) -> np.ndarray:
        """Iterate and return the (feasible) weights."""
        for _ in range(iterations):
            gradient = np.einsum("gpdb,db->gpb", self.a, _point(self.c, self.a, self.extrapolated))
            new = _project_to_simplices(self.extrapolated - gradient / self.lipschitz, self.active)
            restart = np.einsum("gpb,gpb->b", gradient, new - self.lam) > 0.0
            following = (1.0 + np.sqrt(1.0 + 4.0 * self.momentum**2)) / 2.0
            beta = np.where(restart, 0.0, (self.momentum - 1.0) / following)
            self.momentum = np.where(restart, 1.0, following)
            self.extrapolated = new + beta * (new - self.lam)
            self.lam = new
        return self.lam


def _project_to_simplices(v: np.ndarray, active: np.ndarray) -> np.ndarray:
    """Euclidean projection of every v[g, :, b] onto the unit simplex over its active entries."""
    width = v.shape[1]
    values = np.where(active, v, -np.inf)
    ordered = -np.sort(-values, axis=1)
    finite = np.isfinite(ordered)
    sums = np.cumsum(np.where(finite, ordered, 0.0), axis=1)
    positions = np.arange(1, width + 1)[:, None]
    positive = finite & (ordered - (sums - 1.0) / positions > 0.0)
    last = width - 1 - np.argmax(positive[:, ::-1], axis=1)  # (G, B)
    threshold = (np.take_along_axis(sums, last[:, None], axis=1) - 1.0) / (last[:, None] + 1.0)
    return np.where(active, np.maximum(values - threshold, 0.0), 0.0)
