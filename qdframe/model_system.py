"""A qdframe model's own Filippov system x' ∈ g + B·Sgn(s), read from its functional's
pieces one point at a time (:func:`model_system`), for the event-driven integrator of
:mod:`qdframe.filippov`: the replay certificate, the simulated start, `qdframe simulate`."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from .filippov import Fields, FilippovError, FilippovSystem
from .functional.nearest import nearest

Input = Callable[[float], np.ndarray]


def model_system(functional, controls: Input | None = None, choice: Input | None = None,
                 breaks: Sequence[float] = ()) -> FilippovSystem:
    """A qdframe model in the form x' ∈ g + B·Sgn(s), from its functional (exact signs).

    g: each block's set without its sign terms, G_b(y) with y = (x, u(t)): its point where
    G_b is one (an equation), else the point of G_b nearest to `choice(t)`'s coordinates (a
    clip for an interval; :func:`~qdframe.functional.nearest.nearest` for a block of k ≥ 2
    coordinates); a resolved state z_i ≡ x_j gives x_j. B: column k of selection k holds
    sense·a(y) of each sign term on it, in its block's coordinate. s: the selections'
    switches (a vector sign's k components, one of the system's `balls`). `controls(t)` gives u (m,), `choice(t)` the velocities whose nearest points in
    the sets are taken (n,), `breaks` the times where either jumps. One point at a time:
    the pieces are called with one row (N = 1) directly, without the functional's checks
    (a non-finite value raises FilippovError naming the piece). Raises FilippovError for a
    model with a set-valued block and no `choice`.
    """
    model = functional.model
    n, m, p = functional.n, functional.m, functional.p
    if functional.signs != "exact":
        raise FilippovError(f"{model.name}: model_system needs a functional with exact signs")
    probe = np.zeros((1, functional.dim))
    probe[0, :n] = np.nan_to_num(model.x0)
    set_valued = [not sides.equation for sides in functional.distance_sides(probe)]
    if any(set_valued) and choice is None:
        names = ", ".join(block.name or str(block.coords) for block, flag in zip(functional.blocks, set_valued) if flag)
        raise FilippovError(f"{model.name}: the sets of {names} are not points: the motion needs a choice of velocity")
    if m and controls is None:
        raise FilippovError(f"{model.name}: the model has controls: the motion needs u(t)")
    intervals = [_Interval(block) for block in functional.blocks]
    terms = [(functional.blocks[b].coords[0], k, term) for (b, term), k in zip(functional.sign_terms,
                                                                              functional.sign_columns)]
    switches = [(group.columns, group.term.switch) for group in functional.selection_groups]
    row = np.zeros((1, functional.dim))
    y = np.zeros((1, n + m))

    def fields(t: float, x: np.ndarray) -> Fields:
        y[0, :n] = x
        if m:
            y[0, n:] = controls(t)  # type: ignore[misc]
        wanted = None if choice is None else choice(t)
        g = np.empty(n)
        for block, interval in zip(functional.blocks, intervals):
            if block.size == 1:
                lo, hi = interval(y)
                c = block.coords[0]
                g[c] = lo if lo == hi or wanted is None else min(max(wanted[c], lo), hi)
                continue
            row[0, :n], row[0, n: 2 * n], row[0, 2 * n: 2 * n + m], row[0, 2 * n + m:] = x, wanted, y[0, n:], 0.0
            g[list(block.coords)] = nearest(functional, row)[0][0, list(block.coords)]
        for i, j in functional.resolved.items():
            g[i] = x[j]
        B = np.zeros((n, p))
        for coord, k, term in terms:
            B[coord, k] += term.sense * _amplitude(term, y)
        s, ds = np.empty(p), np.empty((p, n))
        for columns, switch in switches:  # a vector sign: its k components in its k columns
            value, gradient = switch(y)
            s[columns], ds[columns] = value[0], gradient[0, ..., :n]
        if not np.isfinite(g.sum() + B.sum() + s.sum() + ds.sum()):
            raise FilippovError(f"{model.name}: the model is non-finite at t = {t:.6g}, x = {np.array2string(x)}")
        return Fields(g, B, s, ds)

    names = tuple(functional.selection_names)
    return FilippovSystem(fields, names, model.name, tuple(float(b) for b in breaks), tuple(functional.balls))


class _Interval:
    """G_b(y) = [lo, hi] of a one-coordinate block without its sign terms, at one point:
    Σ over max-groups of [min_q f_q, max_q f_q] plus Σ over min-groups of
    [−min_p g_p(−1), min_p g_p(+1)] (paper (supf), (subf) at ψ = ±1)."""

    PSI = np.array([[1.0], [-1.0]])

    def __init__(self, block) -> None:
        self.block = block

    def __call__(self, y: np.ndarray) -> tuple[float, float]:
        lo = hi = 0.0
        for group in self.block.max_groups:
            f = group.pieces(y)[0][0, :, 0]
            lo, hi = lo + float(f.min()), hi + float(f.max())
        if self.block.min_groups:
            both = np.repeat(y, 2, axis=0)
            for group in self.block.min_groups:
                g = group.values(both, self.PSI) if group.values is not None else group.pieces(both, self.PSI)[0]
                lo, hi = lo - float(g[1].min()), hi + float(g[0].min())
        return lo, hi


def _amplitude(term, y: np.ndarray) -> float:
    """a(y) = Σ_i max_q a_iq(y) of a sign term at one point."""
    if isinstance(term.amplitude, (int, float)):
        return float(term.amplitude)
    return sum(float(group(y)[0].max()) for group in term.amplitude)
