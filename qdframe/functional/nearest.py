"""The point of F(y) nearest to a velocity: P_{F(y_k)}(z_k) at every node.

From the functional's sides (:meth:`~qdframe.functional.Functional.distance_sides`): per
block ℓ(ψ) = ⟨z_b, ψ⟩ − c(F_b, ψ), dist(z, F_b) = max_ψ ℓ(ψ), so the nearest point is
z_b − dist·ψ*, i.e. z_b − Σ_sides max(0, ℓ)·ψ, and z_b − ℓ for an equation block.

The caveat of intersections. For a block of k ≥ 2 coordinates whose set is an
intersection (a min-group, c̃ = min of support functions, Remark 5.1), max_ψ ℓ̃ is
max(dist(z, A), dist(z, B)), not dist(z, A ∩ B): where z lies in the normal cone of a
corner of A ∩ B the one-pass point z − h·ψ* is the projection onto the farther set only
and lies outside the other. The moved points (h > CHECK_ABOVE) are therefore checked and
the step repeated from there (alternating projections onto the farther set) until the
point is in F to FEASIBLE: a point of F within a constant times dist(z, F) (the constant
depends on the corner's angle), but not always the nearest one.

Used by the replay of a trajectory (:mod:`qdframe.certificates.filippov`, the benchmark's projection
replay) to continue a solver's choice of velocity as the true motion's.
"""

from __future__ import annotations

import numpy as np

CHECK_ABOVE = 1e-10  # a moved point whose distance exceeded this is checked for the corner case
FEASIBLE = 1e-13  # ... and moved again until h ≤ this (relative to 1 + |z|)
CORNER_STEPS = 100


def nearest_velocity(functional, xi: np.ndarray) -> np.ndarray:
    """P_{F(y_k)}(z_k) for every row of ξ (N, 2n + m (+ p)), shape (N, n); resolved states
    (z_i ≡ x_j) get x_j. See the module's docstring for the formula and the corner case."""
    return nearest(functional, np.asarray(xi, dtype=float))[0]


def nearest(functional, xi: np.ndarray, jacobian: bool = False):
    """(P (N, n), ∂P/∂x (N, n, n) or None, corner count)."""
    n = functional.n
    _, z = functional.split(xi)
    v = z.copy()
    jac = np.zeros((xi.shape[0], n, n)) if jacobian else None
    for i, j in functional.resolved.items():
        if jac is not None:
            jac[:, i, j] = 1.0
    corners = 0
    for block, sides in zip(functional.blocks, functional.distance_sides(xi)):
        coords = list(sides.coords)
        if sides.equation:  # F_b a single point: z_b − ℓ (ℓ signed, ψ = +1)
            ell, grad, _ = sides.sides[0]
            v[:, coords[0]] = z[:, coords[0]] - ell
            if jac is not None:
                jac[:, coords[0], :] = -grad[:, :n]
            continue
        step = np.zeros((xi.shape[0], len(coords)))
        if len(sides.sides) == 2:  # an interval: ℓ+ = z − hi, ℓ− = lo − z
            (lp, gp, pp), (lm, gm, pm) = sides.sides
            empty = lp + lm > 0  # ℓ+ + ℓ− = lo − hi > 0: F_b is empty; take the middle (lo + hi)/2
            wp = np.where(empty, 0.5, (lp > 0).astype(float))
            wm = np.where(empty, 0.5, (lm > 0).astype(float))
            step = np.where(empty[:, None], 0.5 * (lp[:, None] * pp + lm[:, None] * pm),
                            np.maximum(lp, 0)[:, None] * pp + np.maximum(lm, 0)[:, None] * pm)
            if jac is not None:
                jac[:, coords, :] -= (wp[:, None, None] * pp[:, :, None] * gp[:, None, :n]
                                      + wm[:, None, None] * pm[:, :, None] * gm[:, None, :n])
        else:
            for ell, grad, psi in sides.sides:
                step += np.maximum(ell, 0.0)[:, None] * psi
                if jac is not None:
                    jac[:, coords, :] -= (ell > 0)[:, None, None] * psi[:, :, None] * grad[:, None, :n]
        v[:, coords] = z[:, coords] - step
        if block.size >= 2 and block.min_groups:
            corners += _corner_repair(functional, xi, v, coords, sides)
    return v, jac, corners


def _corner_repair(functional, xi: np.ndarray, v: np.ndarray, coords: list[int], sides) -> int:
    """Where the one-pass point of an intersection block left F, step again (in place)."""
    h = sides.h
    moved = np.flatnonzero(h > CHECK_ABOVE)
    if moved.size == 0:
        return 0
    b = [k for k, blk in enumerate(functional.blocks) if list(blk.coords) == coords][0]
    n = functional.n
    sub = xi[moved].copy()
    sub[:, n: 2 * n] = v[moved]  # z := the one-pass point (only this block's coordinates matter)
    count = 0
    for _ in range(CORNER_STEPS):
        state = functional.distance_sides(sub)[b]
        hh = state.h
        bad = hh > FEASIBLE * (1.0 + np.abs(sub[:, [n + c for c in coords]]).max(axis=1))
        if not bad.any():
            break
        count = max(count, int(bad.sum()))
        ell, _, psi = state.sides[0]
        shift = np.maximum(ell, 0.0)[:, None] * psi * bad[:, None]
        for c_index, c in enumerate(coords):
            sub[:, n + c] -= shift[:, c_index]
    v[np.ix_(moved, coords)] = sub[:, [n + c for c in coords]]
    return count
