"""The error estimate of a result, switch location and refinement to a requested accuracy.

**Error estimate.** The same problem is solved again on the bisected mesh (every interval
halved: :meth:`~qdframe.grid.Grid.bisected`), from the result interpolated, by
gauss-newton. With x_h and x_{h/2} the two discrete solutions and p ≥ 1 the order,
x_h − x* ≈ (x_h − x_{h/2})·2^p/(2^p − 1), a factor ≤ 2 for every p ≥ 1; the estimate
takes 2.5 (p = 1 with a quarter's margin for the higher-order terms on coarse grids):

    error_estimate = 2.5·max_t |x_h(t) − x_{h/2}(t)| + consistency error + 8ε·max(1, |x|)
                                                       over the points of the result's grid,

1.25 times the error in the limit for a first-order scheme and 2.2 times for p = 3 on
smooth problems, and still on the safe side where a switch inside an interval drops
the order to 1. x_{h/2} between its points is the scheme's own interpolant (the
polynomial through the points of its interval). The estimate is defined for a `solved`
result (it compares two solutions); it is None otherwise, or when the bisected solve
does not end `solved` (the message says so).

**Accuracy.** `accuracy=` refines until the estimate meets it: each round moves mesh
points onto the located switch times (:mod:`qdframe.switches`) and re-solves until they
settle, estimates, and lays out a new mesh that equidistributes the local error (the
change of x_h − x_{h/2} within each interval), sized to meet the accuracy
(:func:`refine`), until the estimate is ≤ accuracy or the next mesh would pass
`max_nodes`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
import numpy as np

from .functional import Functional
from .grid import Grid
from .result import SolveResult
from .switches import switch_times

ESTIMATE_FACTOR = 2.5  # 2^p/(2^p − 1) ≤ 2 for every order p ≥ 1, with a quarter's margin
ROUNDING = 8 * np.finfo(float).eps  # relative: the estimate never claims less than rounding
SWITCH_SETTLED = 1e-12  # relative to T: a switch time that moves less between rounds has settled
SWITCH_ROUNDS = 6  # at most this many re-solves to settle the switch times on one mesh
REFINE_MARGIN = 0.85  # a refined mesh aims at this fraction of the accuracy
MONITOR_FLOOR = 0.05  # the error density never falls below this fraction of its mean

Resolve = Callable[[Functional, SolveResult], SolveResult]  # a descent on a functional from a result


@dataclasses.dataclass
class Estimate:
    """The estimate, the local error per mesh interval (K,) and the bisected solve."""

    value: float | None
    local: np.ndarray | None
    companion: SolveResult | None


def estimate(functional: Functional, result: SolveResult, resolve: Resolve) -> Estimate:
    """The error estimate of a solved `result` on `functional`'s grid (module docstring)."""
    if result.status != "solved":
        return Estimate(None, None, None)
    finer = like(functional, functional.grid.bisected())
    companion = resolve(finer, result)
    if companion.status != "solved":
        return Estimate(None, None, companion)
    grid = functional.grid
    difference = dense(finer.grid, companion.x, grid.t) - result.x  # (N, n)
    # plus what the two discrete solutions cannot see: x's own consistency error and rounding
    floor = result.consistency_error + ROUNDING * max(1.0, float(np.max(np.abs(result.x))))
    value = ESTIMATE_FACTOR * float(np.max(np.abs(difference))) + floor
    # local error of interval k: how far x_h − x_{h/2} moves within it, from its first mesh point
    start = grid.mesh[np.searchsorted(grid.mesh, np.arange(1, grid.nodes)) - 1]  # base(p) of the points p ≥ 1
    moved = np.max(np.abs(difference[1:] - difference[start]), axis=1)
    local = np.zeros(grid.mesh.size - 1)
    np.maximum.at(local, np.searchsorted(grid.mesh, np.arange(1, grid.nodes)) - 1, ESTIMATE_FACTOR * moved)
    return Estimate(value, local, companion)


def dense(grid: Grid, values: np.ndarray, times: np.ndarray) -> np.ndarray:
    """`values` (at grid.t) at `times` by the scheme's interpolant: on each mesh interval the
    polynomial through its points (linear for one-step schemes)."""
    tau = grid.mesh_times
    interval = np.clip(np.searchsorted(tau, times, side="right") - 1, 0, tau.size - 2)
    stages = grid.scheme.stages
    first = grid.mesh[interval]  # the interval's mesh point; its points are first … first + stages
    out = np.zeros((times.size, values.shape[1]))
    for i in range(stages + 1):  # Lagrange basis over the interval's stages + 1 points
        basis = np.ones(times.size)
        for j in range(stages + 1):
            if j != i:
                basis *= (times - grid.t[first + j]) / (grid.t[first + i] - grid.t[first + j])
        out += basis[:, None] * values[first + i]
    return out


def pin(mesh: np.ndarray, times: np.ndarray) -> np.ndarray:
    """`mesh` with a point on every switch time: the nearest interior point not already
    pinned is moved there (it stays between its neighbours), else a point is inserted."""
    tau = np.array(mesh, dtype=float)
    T = tau[-1]
    used: set[float] = set()
    for time in np.sort(times):
        if not 0.0 < time < T:
            continue
        j = int(np.argmin(np.abs(tau - time)))
        if tau[j] in used and abs(tau[j] - time) <= SWITCH_SETTLED * T:
            continue
        if 0 < j < tau.size - 1 and tau[j] not in used:
            tau[j] = time
        else:
            tau = np.sort(np.append(tau, time))
        used.add(float(time))
    return tau


def settle_switches(functional: Functional, result: SolveResult, resolve: Resolve) -> tuple[Functional, SolveResult]:
    """Move mesh points onto the switch times and re-solve until the times settle."""
    times = switch_times(functional, iterate(functional, result))
    for _ in range(SWITCH_ROUNDS):
        if times.size == 0 or result.status != "solved":
            break
        tau = pin(functional.grid.mesh_times, times)
        if np.array_equal(tau, functional.grid.mesh_times):
            break
        functional = like(functional, Grid.from_mesh(tau, functional.grid.scheme))
        result = resolve(functional, result)
        moved = switch_times(functional, iterate(functional, result))
        settled = moved.size == times.size and np.max(np.abs(moved - times)) <= SWITCH_SETTLED * functional.grid.T
        times = moved
        if settled:
            break
    return functional, result


def refine(grid: Grid, local: np.ndarray, accuracy: float, estimate: float) -> np.ndarray:
    """A new mesh that equidistributes the local error (de Boor's monitor).

    With p the scheme's order, interval k's local error behaves as (M_k·h_k)^{p+1}, so
    M_k = local_k^{1/(p+1)}/h_k is the error density. K' intervals with equal shares of
    ∫M give a sum of local errors (∫M)^{p+1}/K'^p; K' is chosen so that this sum, scaled by
    estimate/Σ local (how much of the sum reaches the global error), is REFINE_MARGIN·
    accuracy, and at least 1.25·K. The mesh points follow by inverting the cumulative ∫M.
    """
    tau = grid.mesh_times
    h = np.diff(tau)
    p = grid.scheme.order
    density = np.power(np.maximum(local, 0.0), 1.0 / (p + 1)) / h
    density = density + MONITOR_FLOOR * float(np.sum(density * h)) / grid.T + 1e-300  # no interval spans all
    mass = np.concatenate([[0.0], np.cumsum(density * h)])
    reach = estimate / max(float(np.sum(local)), 1e-300)
    wanted = (mass[-1] ** (p + 1) * reach / (REFINE_MARGIN * accuracy)) ** (1.0 / p)
    count = int(min(max(np.ceil(wanted), np.ceil(1.25 * h.size)), 4 * h.size))
    finer = np.interp(np.linspace(0.0, mass[-1], count + 1), mass, tau)
    finer[0], finer[-1] = 0.0, grid.T
    return finer


def like(functional: Functional, grid: Grid) -> Functional:
    """A functional of the same model and sign treatment on `grid`."""
    return Functional(functional.model, grid, signs=functional.signs, selection_scale=functional.selection_scale)


def iterate(functional: Functional, result: SolveResult) -> np.ndarray:
    """ξ of a result on `functional`'s grid (x, z, u and the selections λ)."""
    return functional.pack(result.x, result.z, result.u, result.selections)

