"""Box-constrained linear complementarity: the Filippov selections of coupled sign terms.

At an event, k sign terms λ ∈ [−1, 1]^k at their surfaces (s = 0) move s by

    w = ds/dt = A·λ + b,     A = ∇s·B (k × k),  b = ∇s·(the rest of the velocity),

and a Filippov mode is a λ with w in the normal cone of the box at λ: λ_i = +1 ⇒ w_i ≥ 0
(the motion leaves to s_i > 0), λ_i = −1 ⇒ w_i ≤ 0, |λ_i| < 1 ⇒ w_i = 0 (it slides or
sticks on s_i = 0). This is the mixed (box) LCP that nosnoc, Stewart and Siconos solve at a
contact event instead of enumerating the 3^k labellings. Where the coupling is dissipative
(−A a P-matrix: dry friction through a mass matrix) its solution is unique (Cottle, Pang &
Stone, *The Linear Complementarity Problem*, 1992, §3.3).

:func:`box_lcp` writes it as a standard LCP in 2k unknowns and runs Lemke's method (ibid.,
§4.4): with λ = p − 1, p ∈ [0, 2], and w = u − v (u, v ≥ 0),

    v = −A·p + u + (A·1 − b) ≥ 0 ⟂ p ≥ 0,     2 − p ≥ 0 ⟂ u ≥ 0,

so p > 0 ⇒ v = 0 (w ≥ 0 at p = 2, w = 0 inside) and p < 2 ⇒ u = 0 (w ≤ 0 at p = 0).
"""

from __future__ import annotations

import numpy as np

PIVOT_TOL = 1e-12  # a tableau entry at most this (relative to its column's largest) is no pivot


def lemke(M: np.ndarray, q: np.ndarray, max_pivots: int | None = None) -> np.ndarray | None:
    """z ≥ 0 with w = M·z + q ≥ 0 and zᵀw = 0, by Lemke's complementary pivoting with the
    covering vector 1; None where it ends on a secondary ray (no solution it can reach) or
    exceeds `max_pivots` (default 50·n)."""
    q = np.asarray(q, dtype=float)
    n = q.size
    if n == 0 or np.all(q >= 0.0):
        return np.zeros(n)
    # the tableau of  w − M·z − 1·z0 = q: columns w (0..n−1), z (n..2n−1), z0 (2n), rhs
    tableau = np.hstack([np.eye(n), -np.asarray(M, dtype=float), -np.ones((n, 1)), q[:, None]])
    basis = list(range(n))
    artificial = 2 * n
    row = int(np.argmin(q))
    leaving = _pivot(tableau, basis, row, artificial)
    for _ in range(max_pivots or 50 * n):
        if leaving == artificial:
            break
        entering = leaving + n if leaving < n else leaving - n  # the complement of the variable that left
        column = tableau[:, entering]
        scale = max(float(np.max(np.abs(column))), 1e-300)
        rows = np.flatnonzero(column > PIVOT_TOL * scale)
        if rows.size == 0:
            return None  # a secondary ray
        ratios = tableau[rows, -1] / column[rows]
        best = ratios.min()
        ties = rows[ratios <= best + 1e-12 * max(1.0, abs(best))]
        # the artificial variable leaves first where it can (the end), else the smallest index
        row = next((int(r) for r in ties if basis[r] == artificial), int(min(ties, key=lambda r: basis[r])))
        leaving = _pivot(tableau, basis, row, entering)
    else:
        return None
    if artificial in basis:
        return None
    z = np.zeros(2 * n + 1)
    z[basis] = tableau[:, -1]
    return np.maximum(z[n : 2 * n], 0.0)


def _pivot(tableau: np.ndarray, basis: list[int], row: int, entering: int) -> int:
    """Pivot `entering` into the basis at `row`; the variable that left."""
    tableau[row] /= tableau[row, entering]
    others = np.arange(tableau.shape[0]) != row
    tableau[others] -= np.outer(tableau[others, entering], tableau[row])
    leaving, basis[row] = basis[row], entering
    return leaving


def box_lcp(A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """λ ∈ [−1, 1]^k with w = A·λ + b in the box's normal cone at λ (the module's problem),
    by :func:`lemke` on its 2k-variable form; None where Lemke's method finds none."""
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    k = b.size
    M = np.block([[-A, np.eye(k)], [-np.eye(k), np.zeros((k, k))]])
    q = np.concatenate([A @ np.ones(k) - b, 2.0 * np.ones(k)])
    z = lemke(M, q)
    if z is None:
        return None
    return np.clip(z[:k] - 1.0, -1.0, 1.0)


def labels(A: np.ndarray, b: np.ndarray, lam: np.ndarray, tol: float = 1e-9) -> tuple[int, ...]:
    """The mode of a box-LCP solution λ: +1 where λ_i = 1 and w_i > 0, −1 where λ_i = −1
    and w_i < 0, 0 (sliding, sticking) elsewhere."""
    w = np.asarray(A) @ lam + b
    scale = tol * max(1.0, float(np.max(np.abs(w), initial=0.0)))
    return tuple(1 if l >= 1.0 - tol and wi > scale else -1 if l <= -1.0 + tol and wi < -scale else 0
                 for l, wi in zip(lam, w))
