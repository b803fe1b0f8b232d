"""A qdframe model's own Filippov system x' ∈ g + B·Sgn(s), read from its functional's
pieces at one point at a time (:func:`model_system`), for the event-driven integrator of
:mod:`qdframe.certificates.filippov`: the replay certificate, the simulated start, `qdframe simulate`."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

from .filippov import Fields, FilippovError, FilippovSystem
from ..functional.nearest import nearest

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
    where every piece carries the `formulas` hook (:mod:`qdframe.model`) the whole system is one
    compiled call (:class:`_Compiled`), else the pieces are called with one row (N = 1)
    directly, without the functional's checks (a non-finite value raises FilippovError).
    Raises FilippovError for a model with a set-valued block and no `choice`.
    """
    model = functional.model
    n, m = functional.n, functional.m
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
    compiled = _Compiled.build(functional)
    fields = _fields_by_pieces(functional, controls, choice) if compiled is None else \
        _fields_compiled(functional, compiled, controls, choice)
    names = tuple(functional.selection_names)
    return FilippovSystem(fields, names, model.name, tuple(float(b) for b in breaks), tuple(functional.balls))


def _fields_by_pieces(functional, controls: Input | None, choice: Input | None) -> Callable[[float, np.ndarray], Fields]:
    """`fields(t, x)` one piece at a time: each block's, term's and switch's callable with one row."""
    model, n, m, p = functional.model, functional.n, functional.m, functional.p
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
        return _checked(model, t, x, Fields(g, B, s, ds))

    return fields


def _fields_compiled(functional, compiled: "_Compiled", controls: Input | None,
                     choice: Input | None) -> Callable[[float, np.ndarray], Fields]:
    """`fields(t, x)` from the model's :class:`_Compiled` formulas: one compiled call a point."""
    model, n, m, p = functional.model, functional.n, functional.m, functional.p
    coords = compiled.coords
    resolved = list(functional.resolved.items())

    def fields(t: float, x: np.ndarray) -> Fields:
        y = x if not m else np.concatenate([x, np.asarray(controls(t), dtype=float)])  # type: ignore[misc]
        lo, hi, amplitudes, s, ds = compiled(y)
        g = np.empty(n)
        if choice is None:
            g[coords] = lo
        else:
            wanted = np.asarray(choice(t), dtype=float)[coords]
            g[coords] = np.where(lo == hi, lo, np.minimum(np.maximum(wanted, lo), hi))
        for i, j in resolved:
            g[i] = x[j]
        B = np.zeros((n, p))
        if compiled.one_term:
            B[compiled.term_places] = compiled.senses * amplitudes
        else:
            np.add.at(B, compiled.term_places, compiled.senses * amplitudes)
        return _checked(model, t, x, Fields(g, B, s, ds))

    return fields


def _checked(model, t: float, x: np.ndarray, fields: Fields) -> Fields:
    if not np.isfinite(fields.g.sum() + fields.B.sum() + fields.s.sum() + fields.ds.sum()):
        raise FilippovError(f"{model.name}: the model is non-finite at t = {t:.6g}, x = {np.array2string(x)}")
    return fields


class _Compiled:
    """A model's whole Filippov system at one point as one lambdified function of y = (x, u),
    built from its pieces' `formulas` hooks (:mod:`qdframe.model`): each one-coordinate
    block's interval G_b(y) = [lo, hi] (as :class:`_Interval` adds it up, in the same order),
    each sign term's amplitude a(y) = Σ_i max_q a_iq(y), each switch's s and ∇_x s. One call
    costs a few µs where a call per piece costs 10–20 µs each, ~1e4–1e5 times in a replay."""

    def __init__(self, functional, ys: tuple, segments: list[list], switches: list, kinds: list[tuple]) -> None:
        n, p = functional.n, functional.p
        states = {symbol: j for j, symbol in enumerate(ys[:n])}
        gradients = [(row, states[symbol], sp.diff(formula, symbol)) for row, formula in enumerate(switches)
                     for symbol in sorted(sp.sympify(formula).free_symbols & states.keys(), key=states.get)]
        gradients = [entry for entry in gradients if entry[2] != 0]
        outputs = [f for part in segments for f in part] + list(switches) + [d for _, _, d in gradients]
        self.function = sp.lambdify(ys, outputs, modules="numpy", cse=True)
        lengths = [len(part) for part in segments]
        self.size = sum(lengths)
        self.starts = np.cumsum([0] + lengths[:-1]).astype(int)
        intervals = [kind for kind in kinds if kind[0] == "interval"]
        self.interval_segments = len(intervals)
        self.segment_block = np.array([kind[1] for kind in intervals], dtype=int)
        self.weights = np.array([kind[2:] for kind in intervals], dtype=float).reshape(-1, 3)  # lo, hi·max, hi·min
        self.blocks = len(functional.blocks)
        self.coords = np.array([block.coords[0] for block in functional.blocks], dtype=int)
        terms = functional.sign_terms
        self.constant = np.array([float(t.amplitude) if isinstance(t.amplitude, (int, float)) else 0.0
                                  for _, t in terms])
        self.amplitude_term = np.array([kind[1] for kind in kinds if kind[0] == "amplitude"], dtype=int)
        self.term_places = (np.array([functional.blocks[b].coords[0] for b, _ in terms], dtype=int),
                            np.array(functional.sign_columns, dtype=int))
        self.senses = np.array([t.sense for _, t in terms], dtype=float)
        self.switch_count = len(switches)
        # shortcuts that give the same numbers: one piece a segment (no min/max to take), one
        # segment a block in block order (nothing to add up), one term a place of B
        self.one_piece = all(length == 1 for length in lengths)
        self.one_segment = self.segment_block.tolist() == list(range(self.blocks)) and bool(
            np.all(self.weights == (1.0, 1.0, 0.0)))
        self.one_term = len(set(zip(*(places.tolist() for places in self.term_places)))) == len(terms)
        self.gradient_places = (np.array([r for r, _, _ in gradients], dtype=int),
                                np.array([j for _, j, _ in gradients], dtype=int))
        self.shape = (p, n)

    @classmethod
    def build(cls, functional) -> "_Compiled | None":
        """The compiled system, or None where a block has several coordinates (its nearest point
        is a search) or a piece has no `formulas` hook."""
        if any(block.size != 1 for block in functional.blocks):
            return None
        ys = sp.symbols(f"y0:{functional.n + functional.m}", real=True)
        segments: list[list] = []
        kinds: list[tuple] = []  # ("interval", block, lo weight, hi weight of the max, of the min) or ("amplitude", term)
        try:
            for b, block in enumerate(functional.blocks):
                for group in block.max_groups:  # lo += min f_q, hi += max f_q
                    segments.append(list(group.pieces.formulas(ys)))
                    kinds.append(("interval", b, 1.0, 1.0, 0.0))
                for group in block.min_groups:  # lo −= min_p g_p(−1), hi += min_p g_p(+1)
                    segments += [list(group.pieces.formulas(ys, (-1,))), list(group.pieces.formulas(ys, (1,)))]
                    kinds += [("interval", b, -1.0, 0.0, 0.0), ("interval", b, 0.0, 0.0, 1.0)]
            for index, (_, term) in enumerate(functional.sign_terms):
                for group in () if isinstance(term.amplitude, (int, float)) else term.amplitude:
                    segments.append(list(group.formulas(ys)))
                    kinds.append(("amplitude", index))
            switches = [f for group in functional.selection_groups
                        for f in getattr(group.term.switch, "function", group.term.switch).formulas(ys)]
        except AttributeError:  # a piece without the `formulas` hook
            return None
        formulas = [sp.sympify(f) for part in segments for f in part] + [sp.sympify(f) for f in switches]
        if any(not part for part in segments) or not set().union(*(f.free_symbols for f in formulas)) <= set(ys):
            return None  # an empty group, or formulas in more than y (a model's unknown parameters)
        return cls(functional, ys, segments, switches, kinds)

    def __call__(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(lo, hi) per block, the sign terms' amplitudes, s (p,) and ∇_x s (p, n) at y."""
        with np.errstate(all="ignore"):  # a non-finite value is named by the caller's check
            out = np.array(self.function(*y), dtype=float)
        values = out[: self.size]
        if self.one_piece or not self.size:
            lowest = highest = values
        else:
            lowest, highest = np.minimum.reduceat(values, self.starts), np.maximum.reduceat(values, self.starts)
        k = self.interval_segments
        if self.one_segment:
            lo, hi = lowest[:k], highest[:k]
        else:
            lo = np.bincount(self.segment_block, weights=lowest[:k] * self.weights[:, 0], minlength=self.blocks)
            hi = np.bincount(self.segment_block, minlength=self.blocks,
                             weights=highest[:k] * self.weights[:, 1] + lowest[:k] * self.weights[:, 2])
        amplitudes = self.constant
        if self.amplitude_term.size:
            amplitudes = amplitudes.copy()
            np.add.at(amplitudes, self.amplitude_term, highest[k:])
        s = out[self.size : self.size + self.switch_count]
        ds = np.zeros(self.shape)
        ds[self.gradient_places] = out[self.size + self.switch_count :]
        return lo, hi, amplitudes, s, ds


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
