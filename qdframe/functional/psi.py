"""ψ*: the maximizer of ℓ(ψ) = <z, ψ> − c(F(x), ψ) over the unit sphere S_k.

For a block of k ≥ 2 coordinates (paper Remark 5.1, Example 7.2) ψ* has no closed
form. We sample S_k, keep the best sample per node, then refine by golden-section
search along great circles through the current point, cycling over an orthonormal
tangent basis — all vectorized over nodes. For k = 2 this is an exact 1-D search
in the angle.

The scan evaluates values only, a chunk of samples at a time (at most
``CHUNK`` node-sample pairs per call of ℓ), so its memory is bounded by a few arrays
of the nodes' size instead of growing with nodes × samples; it keeps the first best
sample, as one ``argmax`` over all samples would. Each golden search also returns ℓ at
its point: the warm start's test reads it, and the next search starts from there and
compares with that value at θ = 0 (the first with the scan's best value) instead of
evaluating ℓ again where ψ cos 0 + t sin 0 is ψ bit for bit (everywhere but at a zero of ψ
whose sign the rotation flips).

Warm start: given the previous iterate's ψ* (`start`), a coarse check scans every
CHECK_STRIDE-th sample of the grid (for k = 2; for k > 2 its first samples/CHECK_STRIDE,
at least 8). Where its best direction lies within one check spacing of the start, the
golden refinement runs from the start instead of from the full scan's best sample, and
the result stands unless a check sample has a larger ℓ, the refinement ran to the edge of
its window (ψ* moved further than the window) or ℓ is not finite. Every other node gets
the cold search as without a start, whose scan evaluates only the samples the check did
not and merges their best with the check's: the first best of all samples, as the full
scan finds it. A maximizer that moved to another local maximum narrower than the check's
spacing can be missed there, as one narrower than the full scan's spacing can be by the
cold search.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0
CHUNK = 1 << 16  # node-sample pairs per evaluation of ℓ in the scan
CHECK_STRIDE = 2  # the warm start's coarse check: every CHECK_STRIDE-th of the scan's directions (k = 2)
EDGE = 0.95  # a warm refinement that ends beyond this fraction of its window ran to the edge


def sphere_samples(k: int, count: int) -> np.ndarray:
    """Deterministic, roughly uniform unit vectors in R^k: (count, k)."""
    if k == 2:
        angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
        return np.stack([np.cos(angle), np.sin(angle)], axis=1)
    rng = np.random.default_rng(12345 + k)
    points = rng.standard_normal((count, k))
    return points / np.linalg.norm(points, axis=1, keepdims=True)


def maximize_on_sphere(
    objective: Callable[..., np.ndarray],
    nodes: int,
    k: int,
    samples: int = 128,
    sweeps: int | None = None,
    iterations: int = 40,
    start: np.ndarray | None = None,
) -> np.ndarray:
    """argmax over ψ ∈ S_k of objective, for every node at once.

    objective(psi, at=None) takes psi of shape (n, M, k) and returns values (n, M), for all
    nodes (at None, n = nodes) or the nodes of the index array `at`. start: a previous ψ*
    (nodes, k) to refine from (the module's warm start). Returns ψ* of shape (nodes, k).
    """
    grid = sphere_samples(k, samples)
    spacing = 2.0 * np.pi / samples if k == 2 else np.pi / samples ** (1.0 / (k - 1))
    sweeps = (1 if k == 2 else 4) if sweeps is None else sweeps

    def restricted(at: np.ndarray | None) -> Callable[[np.ndarray], np.ndarray]:
        """objective at the nodes `at` (None or all of them: no indexing)."""
        return objective if at is None or at.size == nodes else (lambda p: objective(p, at))

    def refine(psi: np.ndarray, at: np.ndarray | None, value: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The golden sweeps from ψ (ℓ there: `value`, if known): the refined ψ and ℓ there."""
        part = restricted(at)
        for sweep in range(sweeps):
            width = 2.0 * spacing / (4.0**sweep)
            for tangent in _tangent_basis(psi):
                psi, value = _golden_on_circle(part, psi, tangent, width, iterations, value)
        return psi, value

    if start is None or start.shape != (nodes, k):
        index, top = _best(objective, grid, nodes)
        return refine(grid[index], None, top)[0]
    # the coarse check first: the warm start stands where the check's best direction is next to it
    checked = np.arange(0, samples, CHECK_STRIDE) if k == 2 else np.arange(min(samples, max(8, samples // CHECK_STRIDE)))
    spread = CHECK_STRIDE * spacing  # the check's spacing
    index, top = _best(objective, grid[checked], nodes)
    index = checked[index]
    psi = np.array(start, dtype=float)
    warm = np.flatnonzero(_angle(grid[index], psi) <= spread)
    if warm.size:
        psi[warm], value = refine(psi[warm], warm)
        with np.errstate(invalid="ignore"):  # below the check, out of its window (ψ* moved further), or NaN
            lost = (value < top[warm]) | (_angle(psi[warm], start[warm]) > EDGE * 2.0 * spacing) | ~np.isfinite(value)
        warm = warm[~lost]
    stands = np.zeros(nodes, dtype=bool)
    stands[warm] = True
    cold = np.flatnonzero(~stands)
    if cold.size:  # the full scan there: the samples the check did not evaluate, merged with the check's best
        rest = np.setdiff1d(np.arange(samples), checked)
        more, more_top = _best(restricted(cold), grid[rest], cold.size)
        index, top = _first_best(index[cold], top[cold], rest[more], more_top)
        psi[cold] = refine(grid[index], cold, top)[0]
    return psi


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angle between unit vectors, row by row."""
    return np.arccos(np.clip(np.einsum("nk,nk->n", a, b), -1.0, 1.0))


def best_sample(objective: Callable[[np.ndarray], np.ndarray], grid: np.ndarray, nodes: int) -> np.ndarray:
    """Index (nodes,) of the first sample of `grid` (M, k) with the largest value at each
    node — ``argmax`` over all M samples, NaN counting as the largest — evaluated
    CHUNK node-sample pairs at a time."""
    return _best(objective, grid, nodes)[0]


def _best(objective, grid: np.ndarray, nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`best_sample`'s index and the value there."""
    count, k = grid.shape
    step = max(1, min(count, CHUNK // max(nodes, 1)))
    best = np.zeros(nodes, dtype=int)
    top = np.full(nodes, -np.inf)
    for start in range(0, count, step):
        chunk = grid[start : start + step]
        values = objective(np.broadcast_to(chunk, (nodes, chunk.shape[0], k)))
        for column in range(chunk.shape[0]):  # a later sample wins only if strictly larger, or the first NaN
            value = values[:, column]
            better = (value > top) | (np.isnan(value) & ~np.isnan(top))
            best[better] = start + column
            top[better] = value[better]
    return best, top


def _first_best(index: np.ndarray, top: np.ndarray, other: np.ndarray, other_top: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Two scans' best samples (grid index, value) merged into the best of both: the larger
    value, NaN counting as the largest, and of equal ones the lower index, as one scan of
    all their samples in index order (:func:`_best`) keeps."""
    nan, other_nan = np.isnan(top), np.isnan(other_top)
    tie = (other_top == top) | (nan & other_nan)
    other_wins = (other_top > top) | (other_nan & ~nan) | (tie & (other < index))
    return np.where(other_wins, other, index), np.where(other_wins, other_top, top)


def _tangent_basis(psi: np.ndarray) -> list[np.ndarray]:
    """k − 1 orthonormal tangent vectors at each ψ: list of (nodes, k)."""
    nodes, k = psi.shape
    if k == 2:
        return [np.stack([-psi[:, 1], psi[:, 0]], axis=1)]
    # Householder reflection mapping e_1 to ψ: its other columns span the tangent space.
    e1 = np.zeros(k)
    e1[0] = 1.0
    v = psi - e1
    norm2 = np.einsum("ij,ij->i", v, v)
    safe = norm2 > 1e-24
    basis = []
    for j in range(1, k):
        ej = np.zeros(k)
        ej[j] = 1.0
        coef = np.where(safe, 2.0 * v[:, j] / np.where(safe, norm2, 1.0), 0.0)
        basis.append(ej - coef[:, None] * v)
    return basis


def _golden_on_circle(objective, psi, tangent, width, iterations, known=None) -> tuple[np.ndarray, np.ndarray]:
    """Maximize along ψ cos θ + tangent sin θ, θ ∈ [−width, width], per node: the point and
    ℓ there. known: ℓ at ψ (θ = 0), if evaluated already."""

    def value(point: np.ndarray) -> np.ndarray:
        return objective(point[:, None, :])[:, 0]

    def along(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        point = _rotate(psi, tangent, np.cos(theta), np.sin(theta))
        return point, value(point)

    lo = np.full(psi.shape[0], -width)
    hi = np.full(psi.shape[0], width)
    a = hi - _GOLDEN * (hi - lo)
    b = lo + _GOLDEN * (hi - lo)
    fa, fb = along(a)[1], along(b)[1]
    for _ in range(iterations):
        left = fa >= fb  # maximum in [lo, b]: a new point left of a, else right of b
        hi = np.where(left, b, hi)
        lo = np.where(left, lo, a)
        step = _GOLDEN * (hi - lo)
        moved = np.where(left, hi - step, lo + step)
        f_moved = along(moved)[1]
        a, b = np.where(left, moved, b), np.where(left, a, moved)
        fa, fb = np.where(left, f_moved, fb), np.where(left, fa, f_moved)
    middle, f_middle = along(0.5 * (lo + hi))
    start = _rotate(psi, tangent, 1.0, 0.0)  # θ = 0: ψ itself, unless a zero of ψ changed its sign
    if known is None or not np.array_equal(start.view(np.int64), psi.view(np.int64)):
        known = value(start)
    better = f_middle >= known
    return np.where(better[:, None], middle, start), np.where(better, f_middle, known)


def _rotate(psi: np.ndarray, tangent: np.ndarray, cos, sin) -> np.ndarray:
    """ψ cos θ + tangent sin θ (nodes, k), a coordinate at a time (broadcasting (nodes, 1)
    against (nodes, k) costs several times more at a large k·nodes)."""
    point = np.empty_like(psi)
    for j in range(psi.shape[1]):
        np.multiply(psi[:, j], cos, out=point[:, j])
        point[:, j] += tangent[:, j] * sin
    return point
