"""Continuation over grids: the ladder of grids a solve runs on (coarsest first) and a
coarser grid's solution carried to a finer one as its start."""

from __future__ import annotations

from collections.abc import Sequence
from types import SimpleNamespace

import numpy as np

from ..certificates import estimates
from ..errors import InputError
from ..functional import Functional
from ..schemes.grid import Grid, make_scheme
from ..result import SolveResult

COARSEST_NODES = 11  # step T/10, the paper's final step in Section 7
BAND_START_ITERATIONS = 10  # at most this many iterations of the band start of an exact solve
COARSE_EPS_FACTOR = 10  # a stage that only starts a later one stops when every node's deviation is ≤ 10·ε


def grid_schedule(nodes: int, continuation: Sequence[int] | str, coarsest: int = COARSEST_NODES,
                  steps: Sequence[int] = (1,)) -> list[int]:
    """The grids a solve runs on, coarsest first, ending with `nodes`.

    "auto": `coarsest` (11: step T/10) intervals times each of `steps` per decade, below
    `nodes`: 11, 101, 1001, … with steps (1,); 101, 301, 1001, 3001, … from 101 with
    steps (1, 3) (gauss-newton's: a switch found on one grid is at most a few nodes off on
    the next, and semismooth Newton moves it about one node per iteration); "none" or ():
    `nodes` alone; a sequence: those node counts (increasing, below `nodes`), then `nodes`.
    Starting the paper's first-order descent from a coarse solution keeps its iteration
    count flat in N: on a fine grid alone the δ-active kinks of many nodes cut its steps.
    """
    if isinstance(continuation, str):
        if continuation == "auto":
            coarse, decade = [], coarsest - 1
            while decade + 1 < nodes:
                coarse += [decade * step + 1 for step in steps if decade * step + 1 < nodes]
                decade *= 10
            return coarse + [nodes]
        if continuation == "none":
            return [nodes]
        raise InputError("continuation", '"auto", "none" or increasing node counts', continuation)
    counts = list(continuation)
    if any(isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2 for n in counts):
        raise InputError("continuation", "node counts ≥ 2", tuple(continuation))
    grids = [int(n) for n in counts] + [nodes]
    if any(b <= a for a, b in zip(grids, grids[1:])):
        raise InputError("continuation", f"increasing node counts below nodes = {nodes}", tuple(continuation))
    return grids


def interpolate(functional: Functional, previous: SolveResult) -> np.ndarray:
    """The previous grid's x, z, u and λ on `functional`'s grid: by the previous scheme's own
    interpolants where its grid is known (x by the polynomial through each interval's
    points, z, u and λ by the scheme's rule for x′, λ clipped to [−1, 1]; a switch pinned
    on a mesh point is not smeared across it), else linearly."""
    t = functional.grid.t
    source = _source_grid(previous)
    if source is None:
        def on_grid(values: np.ndarray) -> np.ndarray:
            return np.stack([np.interp(t, previous.t, column) for column in values.T], axis=1)
        position = velocity = on_grid
    else:
        def position(values: np.ndarray) -> np.ndarray:
            return estimates.dense(source, values, t)

        def velocity(values: np.ndarray) -> np.ndarray:
            # at a point shared with the source's mesh, the value there (left-continuous like the rule)
            out = source.scheme.velocity(source.t, source.mesh, values, t)
            same = np.searchsorted(source.t, t).clip(0, source.t.size - 1)
            exact = source.t[same] == t
            out[exact] = values[same[exact]]
            return out

    u = None if previous.u is None else velocity(previous.u)
    selections = None if previous.selections is None else velocity(previous.selections)
    if selections is not None and source is not None:  # a polynomial may overshoot [−1, 1]
        selections = np.clip(selections, -1.0, 1.0)
    return functional.pack(position(previous.x), velocity(previous.z), u, selections)  # λ None: the band's


def _source_grid(previous: SolveResult) -> Grid | None:
    """The grid a result was solved on, where its points say it (its scheme's layout on the
    mesh of every `stages`-th point); None for anything else (a plain t)."""
    name = getattr(previous, "options", {}).get("scheme")
    if name is None:
        return None
    try:
        scheme = make_scheme(name)
        grid = Grid.from_mesh(np.asarray(previous.t)[:: scheme.stages], scheme)
    except Exception:  # noqa: BLE001 - not a layout of that scheme
        return None
    return grid if grid.t.shape == np.shape(previous.t) and np.allclose(grid.t, previous.t, rtol=0, atol=1e-12) else None


def iterate_view(functional: Functional, xi: np.ndarray) -> SimpleNamespace:
    """ξ on `functional`'s grid as `interpolate` reads a result: t, x, z, u, selections."""
    x, z = functional.split(xi)
    return SimpleNamespace(t=functional.grid.t, x=x, z=z, u=functional.controls(xi) if functional.m else None,
                           selections=functional.selections(xi) if functional.p else None)

