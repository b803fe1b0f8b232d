"""Switch times of a trajectory: where a Filippov selection changes regime.

A sign term a·Sgn(s) has two regimes along a solution: *off* the surface (s ≠ 0, λ =
sign s) and *on* it (s = 0 with λ ∈ [−1, 1]: sticking, sliding). A point with s = 0 and λ = ±1
is the switch itself between two off stretches, unless s stays 0 for HELD points in a row: a
block stuck exactly on the friction threshold (|force| = μ, λ = ±1 while it sticks) is on. On a mesh the change
falls inside an interval and the scheme drops to first order there; a mesh point on the
switch time restores its order (nosnoc's FESD gets the same by making the steps unknown).
Each switch is located from the smooth side, by the polynomial (degree ≤ 2) through the
last points of one regime, extrapolated to the event:

- off → on (a block stops, a state reaches a sliding surface): s = 0, from the off side;
- on → off (breakaway, leaving the surface): |λ| = 1, from the on side (s = 0 from the
  off side when the on phase has a single point);
- off → off with a sign change (crossing the surface): s = 0 between the two points.

A vector sign Sgn(s), s ∈ R^k (isotropic friction), is located the same way on |s| and |λ|
(:func:`_ball_regimes`): a stop where |s| reaches 0, a break-away where |λ| reaches 1.

Where the scheme is exact on the pieces (Radau IIA on quadratic motion, implicit Euler
on the velocity of a block) one location is exact; otherwise the switch is re-located on
the mesh that has a point there, and converges (see :mod:`qdframe.solve.adaptive`).

The times returned lie in [0, T] (an extrapolation past an end, such as a block at rest
at t = 0 that starts to move, is the end itself). One switching function's times closer
than the mesh step there are one switch (located twice): their mean; two functions' times
are one only within SAME_TIME·T (two blocks that stop 0.08 s apart on a mesh of 0.1 s
stopped twice).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from ..functional import Functional

SAME_TIME = 1e-9  # relative to T: two switching functions' switches this close are one time (they switch together)
ON_SURFACE = 1e-6  # |s| ≤ this·max(1, max|s|): the point is on the surface (s = 0 up to the solve's residuals)
SATURATED = 1e-6  # |λ| ≥ 1 − this: λ is at an end of [−1, 1] (to the solve's residuals), the off side's regime …
HELD = 3  # … unless s = 0 at this many points in a row: stuck on the threshold (|λ| = 1 all along)


def switch_times(functional: Functional, xi: np.ndarray, crossings: bool = True, merge: bool = True,
                 bounds: bool = True) -> np.ndarray:
    """The located switch times of the iterate ξ, increasing (empty without sign terms);
    with `bounds`, also where a state or control bound starts or stops binding (:func:`bound_times`);
    `crossings=False` leaves out the transversal crossings of a surface (s changes sign,
    λ jumps from one end of [−1, 1] to the other), keeping the stops, sticks, break-aways
    and the entries into and exits from sliding; `merge=False` keeps times closer than the
    mesh step apart (the refinement pins a mesh point on each)."""
    grid = functional.grid
    y, lam = functional.arguments(xi), functional.selections(xi)
    found: list[np.ndarray] = [bound_times(functional, xi, merge) if bounds else np.zeros(0)]
    if not functional.p:
        return found[0]
    s = functional.switch_values(y, gradients=False)[0]
    for group in functional.selection_groups:
        if group.width == 1:
            pair = s[:, group.first], lam[:, group.first]
        else:
            pair = _ball_regimes(s[:, group.columns], lam[:, group.columns])
        located = [time for time, crossing in _locate(grid.t, grid.mesh, *pair) if crossings or not crossing]
        times = np.clip(np.asarray(located, dtype=float), grid.t[0], grid.t[-1]) + 0.0  # + 0.0: no −0
        times = np.unique(np.round(times, 14))
        found.append(merge_close(times, grid.mesh_times) if merge else times)
    times = np.unique(np.concatenate(found)) if found else np.zeros(0)
    return merge_close(times, grid.mesh_times, SAME_TIME * (grid.t[-1] - grid.t[0])) if merge else times


def bound_times(functional: Functional, xi: np.ndarray, merge: bool = False) -> np.ndarray:
    """Where a control bound (``control_bounds``) starts or stops binding, located as a sign
    term's stop and break-away: its side g = ±(u_j − limit) ≤ 0 is s, "on" where g = 0, and its
    multiplier over λ, max(0, ℓ + s) (s the augmented Lagrangian's shift,
    :mod:`qdframe.functional.shifts`, 0 without), scaled to λ' = −1 + y/max y, reaches −1 where
    the bound lets go. A control clipped by its bound has a kink there that a mesh point
    restores the order at, as at a switch. A state bound (``state_bounds``) is left out: the
    bounded state is C¹ at its junctions and the least cost fixes them only to second order, so
    a discrete solution lets go on whichever point is near, and a pin there would hold every
    finer solution to where a coarse grid let go (docs/method.md)."""
    bounds, shifts, grid = functional.bounds, functional.shifts, functional.grid
    if bounds is None:
        return np.zeros(0)
    sides = functional.values.bound_sides(functional.arguments(xi))
    # the multiplier over λ: max(0, ℓ + s) (the hinge's own residual at a penalty's minimizer, s = 0)
    multipliers = np.maximum(sides + (shifts.bounds if shifts is not None else 0.0), 0.0)
    times = []
    for j in range(sides.shape[1]):
        if bounds.columns[j] < functional.n:
            continue  # a state's bound (the docstring)
        multiplier = multipliers[:, j]
        top = float(np.max(multiplier))
        if top <= 0.0:
            continue  # never binds
        located = [time for time, _ in _locate(grid.t, grid.mesh, sides[:, j], multiplier / top - 1.0)]
        times.append(np.clip(np.asarray(located, dtype=float), grid.t[0], grid.t[-1]) + 0.0)
    if not times:
        return np.zeros(0)
    out = np.unique(np.round(np.concatenate(times), 14))
    return merge_close(out, grid.mesh_times) if merge else out


def polish(times: np.ndarray, events: Sequence[float], mesh: np.ndarray) -> np.ndarray:
    """`times` located on the trajectory, each replaced by the nearest of `events` — the switch
    times of the true motion, located by the event-driven integrator (:mod:`qdframe.certificates.filippov`)
    to its tolerance — that lies within the larger length of the mesh intervals holding the
    two; a time with no such event stays as located. For an initial-value problem whose
    trajectory is certified (its replay is the solution itself), this gives the solution's
    switch times where the trajectory's own, from a first-order scheme near a curved stop,
    are only as good as its velocity (a stop time's error is the velocity's error over the
    deceleration)."""
    events = np.sort(np.asarray(events, dtype=float))
    if times.size == 0 or events.size == 0:
        return times

    def step(time: float) -> float:
        j = int(np.clip(np.searchsorted(mesh, time, side="right") - 1, 0, mesh.size - 2))
        return float(mesh[j + 1] - mesh[j])

    out = np.array(times, dtype=float)
    for i, time in enumerate(out):
        nearest = float(events[np.argmin(np.abs(events - time))])
        if abs(nearest - time) <= max(step(time), step(nearest)):
            out[i] = nearest
    return np.unique(out)


def merge_close(times: np.ndarray, mesh: np.ndarray, within: float | None = None) -> np.ndarray:
    """Increasing `times` with runs closer than the mesh resolution merged into their mean:
    consecutive times a ≤ b are one when b − a is at most the larger length of the mesh
    intervals of [mesh_0, mesh_K] that hold a and b (or at most `within`, given)."""
    if times.size < 2:
        return times

    def step(time: float) -> float:
        if within is not None:
            return within
        j = int(np.clip(np.searchsorted(mesh, time, side="right") - 1, 0, mesh.size - 2))
        return float(mesh[j + 1] - mesh[j])

    groups = [[float(times[0])]]
    for time in times[1:]:
        if time - groups[-1][-1] <= max(step(groups[-1][-1]), step(float(time))):
            groups[-1].append(float(time))
        else:
            groups.append([float(time)])
    return np.array([float(np.mean(group)) for group in groups])


def _locate(t: np.ndarray, mesh: np.ndarray, s: np.ndarray, lam: np.ndarray) -> list[tuple[float, bool]]:
    """The switch times of one sign term from its s and λ at the points t (mesh: the
    indices of the mesh points). A change between the points a and a + 1 lies in the mesh
    interval [t_first, t_last] around them; the polynomials use only points outside it,
    where the scheme's solution is smooth."""
    small = np.abs(s) <= ON_SURFACE * max(1.0, float(np.max(np.abs(s))))
    # on the surface: s = 0 with λ inside (−1, 1), or s = 0 at HELD points in a row whatever λ (stuck
    # exactly on the threshold, |force| = μ: λ = ±1 all along; a crossing or a reaching has one or two)
    on = small & ((np.abs(lam) < 1.0 - SATURATED) | _in_runs(small, HELD))
    # 0 on the surface; ±1 off it, including a point with s = 0 and λ = ±1 (the switch point itself)
    side = np.where(on, 0, np.where(small, np.sign(lam), np.sign(s))).astype(int)
    # a crossing that falls on a point (a mesh point pinned there): s = 0 and λ inside (−1, 1)
    # at that point alone, between the two sides: one switch, not a stop and a break-away
    alone = np.flatnonzero((side[1:-1] == 0) & (side[:-2] * side[2:] == -1)) + 1
    side[alone] = side[alone - 1]
    changes = np.flatnonzero(side[1:] != side[:-1])  # between the points a and a + 1
    out = []
    for a in changes:
        j = np.searchsorted(mesh, a + 1) - 1  # the mesh interval (mesh[j], mesh[j + 1]] holding a + 1
        first, last = mesh[j], mesh[j + 1]
        before, after = side[first], side[last]
        if before != 0 and after != 0 and before != after:  # a crossing: s changes sign
            points = np.append(_run(side, first, step=-1, length=2), last)
            root = _root(t[points], s[points], t[first], t[last])
        elif before != 0:  # off → on: s reaches 0, from the points up to the interval
            run = _run(side, first, step=-1, length=4)
            clear = run[~small[run]]  # not the switch point itself (its s ≈ 0 is only as good as the solve) …
            run = clear[-3:] if clear.size >= 3 else run[-3:]  # … unless fewer than three points are left
            root = _root(t[run], s[run], t[first], t[last]) if run.size >= 2 else None
        elif after != 0:  # on → off: λ reaches sign(s), from the on side, else s leaves 0, from the off side
            run = _run(side, first, step=-1)
            if run.size >= 2:
                root = _root(t[run], lam[run] - after, t[first], t[last])
            else:
                run = _run(side, last, step=1)
                root = _root(t[run], s[run], t[first], t[last]) if run.size >= 2 else None
        else:  # the same regime at both ends: the change is inside the interval (a stage point)
            root = None
        if root is not None:
            out.append((root, before != 0 and after != 0 and before != after))
    return out


def _in_runs(mask: np.ndarray, length: int) -> np.ndarray:
    """Where `mask` holds at `length` or more consecutive points."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    out = np.zeros(mask.size, dtype=bool)
    for a, b in zip(starts, ends):
        if b - a >= length:
            out[a:b] = True
    return out


def _ball_regimes(s: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A vector sign's s (N, k) and λ (N, k) as one scalar pair for :func:`_locate`: ±|s| and
    ±|λ|. Off the surface (s ≠ 0, |λ| = 1) the motion's regime is one side; it stops where |s|
    reaches 0 (from the off side, |s| is smooth there: (t* − t)·|a + O(t* − t)|) and breaks
    away where |λ| (the equivalent control while stuck) reaches 1. The sign flips where s
    passes through 0 without sticking (its direction reverses between two points off the
    surface, ⟨ŝ_k, ŝ_{k+1}⟩ < 0): a crossing; points on the surface take the sign of the next
    point off it (the side they break away to), so that |λ| − 1 is what reaches 0 there."""
    radius, size = np.linalg.norm(s, axis=1), np.linalg.norm(lam, axis=1)
    small = radius <= ON_SURFACE * max(1.0, float(np.max(radius, initial=0.0)))
    off = np.flatnonzero(~small)
    sign = np.ones(s.shape[0])
    if off.size:
        unit = s[off] / radius[off, None]
        flips = np.sum(unit[1:] * unit[:-1], axis=1) < 0.0
        flips &= np.diff(off) == 1  # consecutive points off the surface: no stop between them
        signs_off = np.concatenate([[1.0], np.cumprod(np.where(flips, -1.0, 1.0))])
        following = np.clip(np.searchsorted(off, np.arange(s.shape[0])), 0, off.size - 1)
        sign = signs_off[following]
        sign[off] = signs_off
    return sign * radius, sign * size


def _run(side: np.ndarray, start: int, step: int, length: int = 3) -> np.ndarray:
    """Up to `length` consecutive points from `start` (walking by `step`) in start's regime, in time order."""
    points = [start]
    while len(points) < length:
        nxt = points[-1] + step
        if not 0 <= nxt < side.size or side[nxt] != side[start]:
            break
        points.append(nxt)
    return np.sort(np.asarray(points))


def _root(t: np.ndarray, values: np.ndarray, lo: float, hi: float) -> float | None:
    """The zero of the polynomial of degree ≤ 2 through (t, values) nearest to [lo, hi],
    within one interval's length of it (a point classified by the solve's tolerances may
    sit just before the switch), None if there is none."""
    degree = min(2, t.size - 1)
    if degree < 1:
        return None
    centre, scale = 0.5 * (lo + hi), max(hi - lo, 1e-300)
    with warnings.catch_warnings():  # three points of one interval's size apart: well posed after scaling
        warnings.simplefilter("ignore", np.exceptions.RankWarning)
        coefficients = np.polyfit((t - centre) / scale, values, degree)
    roots = np.roots(coefficients)
    roots = roots[np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots.real))].real * scale + centre
    roots = roots[(roots >= lo - (hi - lo)) & (roots <= hi + (hi - lo))]
    if roots.size == 0:
        return None
    return float(roots[np.argmin(np.abs(roots - centre))])
