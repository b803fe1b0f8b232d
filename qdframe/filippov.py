"""Event-driven Filippov integration: the true motion of a system with sign terms.

It solves

    x' ∈ g(t, x) + B(t, x)·Sgn(s(t, x)),      s: k switching functions, B: (n, k),

with scipy's DOP853 between events (rtol = atol = 1e-12 by default), the selection
λ_i ∈ Sgn(s_i) of each switch given by its *mode* m_i: +1 (s_i > 0, λ_i = +1), −1 (λ_i = −1)
or 0 (sliding or sticking on s_i = 0). On the sliding set S the selections are the
equivalent control, the solution of

    (∇s_S·B_S)·λ_S = −∇s_S·(g + B_{¬S}·m_{¬S}),

which keeps every ds_i/dt = 0 (i ∈ S). A piece ends at a terminal event: an s_i (i ∉ S)
reaching 0 from its side, or a sliding |λ_i| reaching 1, or a break of the drift in t
(an input's jump). There the new mode is chosen by enumerating the modes {+1, −1, 0} of
the switches at the surface: a mode is consistent when its λ_S lie in [−1, 1] and every
other switch at the surface moves to its own side (m_i·ds_i/dt ≥ 0). Both are measured
in λ units (ds_i/dt divided by |∇s_i·B_i|), so that at a transversal crossing or an
attractive surface exactly one mode has a non-negative margin (Filippov's rule: attractive
→ slide, transversal → cross); the mode of largest smallest margin is taken.

:func:`model_system` states a qdframe model in this form (its equations and sets as the
drift, its sign terms as B and s, the sets' choice and the controls as inputs of time);
the error certificate by replay (:mod:`qdframe.estimates`), the default start of a solve
and the benchmark's references use it.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import OdeSolution, solve_ivp

from .errors import QdframeError

SURFACE_TOL = 1e-11  # |s_i| at most this (relative to max(1, |x|)): switch i is at its surface
MARGIN_TOL = 1e-9  # a mode is consistent when every margin (λ units) is ≥ −MARGIN_TOL
MAX_EVENTS = 100_000  # mode changes and events, beyond the declared breaks
MAX_STALLS = 20  # consecutive events without progress in t before giving up (Zeno, chattering)


class FilippovError(QdframeError):
    """The integration cannot continue: no consistent mode, an ODE failure, or no progress."""


@dataclass(frozen=True)
class Fields:
    """The system at one (t, x): drift g (n,), B (n, k), switches s (k,) and ∇_x s (k, n)."""

    g: np.ndarray
    B: np.ndarray
    s: np.ndarray
    ds: np.ndarray


@dataclass(frozen=True)
class FilippovSystem:
    """x' ∈ g(t, x) + B(t, x)·Sgn(s(t, x)), evaluated by `fields(t, x)`.

    `names`: one per switch; `breaks`: times where the drift is not smooth in t (an
    input's jumps), where the integrator ends a piece and chooses the mode afresh.
    """

    fields: Callable[[float, np.ndarray], Fields]
    names: tuple[str, ...]
    name: str = ""
    breaks: tuple[float, ...] = ()

    @property
    def switch_count(self) -> int:
        return len(self.names)


@dataclass
class FilippovTrajectory:
    """The integrated motion: DOP853 dense outputs of the pieces between events.

    `switch_times`: the times the mode changed (entering or leaving sliding, crossing);
    `modes`: (start time, mode) of every mode taken, the first at t0.
    """

    starts: np.ndarray  # (P,) start time of each piece
    pieces: list[OdeSolution]
    switch_times: tuple[float, ...]
    modes: list[tuple[float, tuple[int, ...]]]
    T: float
    events: int = 0  # terminal events met (mode changes, re-choices, breaks)
    seconds: float = field(default=0.0, compare=False)

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """x(t), (K, n), for the times t (K,): each time from the piece containing it."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        which = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.pieces) - 1)
        n = np.atleast_1d(self.pieces[0](self.starts[0])).size
        out = np.empty((t.size, n))
        for index in np.unique(which):
            chosen = which == index
            out[chosen] = np.atleast_2d(self.pieces[index](t[chosen])).T
        return out


class _Cached:
    """`fields` with a one-entry memory: DOP853's last stage and the events ask for the same point."""

    def __init__(self, system: FilippovSystem) -> None:
        self.system = system
        self.key: tuple | None = None
        self.value: Fields | None = None
        self.calls = 0

    def __call__(self, t: float, x: np.ndarray) -> Fields:
        key = (float(t), np.asarray(x, dtype=float).tobytes())
        if key != self.key:
            self.value = self.system.fields(float(t), np.asarray(x, dtype=float))
            self.key = key
            self.calls += 1
        return self.value  # type: ignore[return-value]


# ----------------------------------------------------------------- modes and fields
def velocity(fields: Fields, mode: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """x' = g + B·λ in `mode` and the selections λ (k,): m_i off the surface, the
    equivalent control on it. Raises numpy.linalg.LinAlgError when ∇s_S·B_S is singular."""
    lam = np.array(mode, dtype=float)
    sliding = [i for i, m in enumerate(mode) if m == 0]
    base = fields.g + fields.B @ lam  # λ_S = 0 here
    if sliding:
        grads = fields.ds[sliding]
        lam[sliding] = np.linalg.solve(grads @ fields.B[:, sliding], -(grads @ base))
        base = base + fields.B[:, sliding] @ lam[sliding]
    return base, lam


def _margins(fields: Fields, mode: tuple[int, ...], at: Sequence[int]) -> np.ndarray:
    """For the switches `at` the surface, in λ units: 1 − |λ_i| when sliding,
    m_i·(ds_i/dt)/|∇s_i·B_i| when moving (≥ 0 means consistent)."""
    try:
        f, lam = velocity(fields, mode)
    except np.linalg.LinAlgError:
        return np.array([-np.inf])
    out = []
    for i in at:
        if mode[i] == 0:
            out.append(1.0 - abs(lam[i]))
            continue
        grad = fields.ds[i]
        scale = abs(grad @ fields.B[:, i])
        out.append(mode[i] * (grad @ f) / (scale if scale > 1e-14 else 1.0))
    return np.array(out)


def choose_mode(fields: Fields, x: np.ndarray, current: tuple[int, ...] | None = None, crossed: int | None = None,
                released: tuple[int, int] | None = None, name: str = "", t: float = 0.0) -> tuple[int, ...]:
    """The Filippov mode at a point: enumerate {0, +1, −1} for every switch at its surface
    (|s_i| ≤ SURFACE_TOL·max(1, |x|), sliding in `current`, or the `crossed` one), keep
    the consistent modes (every margin ≥ −MARGIN_TOL) and take the one of largest smallest
    margin. `crossed`: switch i reached s_i = 0 from side current[i], which it cannot keep;
    `released`: (i, ±1), sliding switch i's λ reached ±1: it leaves to that side."""
    values = fields.s
    near = SURFACE_TOL * max(1.0, float(np.max(np.abs(x), initial=0.0)))
    at = {i for i, c in enumerate(values) if abs(c) <= near}
    if current is not None:
        at |= {i for i, m in enumerate(current) if m == 0}
    if crossed is not None:
        at.add(crossed)
    if released is not None:
        at.add(released[0])
    at_sorted = sorted(at)
    fixed = [1 if c > 0 else -1 for c in values]
    best, best_margin = None, -np.inf
    for choice in itertools.product((0, 1, -1), repeat=len(at_sorted)):
        mode = list(fixed)
        for i, m in zip(at_sorted, choice):
            mode[i] = m
        if crossed is not None and current is not None and mode[crossed] == current[crossed]:
            continue
        if released is not None and mode[released[0]] != released[1]:
            continue
        margins = _margins(fields, tuple(mode), at_sorted)
        smallest = float(margins.min()) if margins.size else np.inf
        if smallest >= -MARGIN_TOL and smallest > best_margin:
            best, best_margin = tuple(mode), smallest
    if best is None:
        raise FilippovError(f"{name}: no consistent Filippov mode at t = {t:.17g} (switches at the surface: "
                            f"{', '.join(str(i) for i in at_sorted)})")
    return best


# ------------------------------------------------------------------------ integrate
def integrate(system: FilippovSystem, x0: Sequence[float], T: float, rtol: float = 1e-12, atol: float = 1e-12, *,
              t0: float = 0.0) -> FilippovTrajectory:
    """The Filippov motion of `system` from x(t0) = x0 over [t0, T]: DOP853 (dense output)
    between terminal events, the mode re-chosen by :func:`choose_mode` at every event."""
    clock = time.perf_counter()
    x = np.array(x0, dtype=float)
    if not np.all(np.isfinite(x)):
        raise FilippovError(f"{system.name}: x0 must be finite, got {x}")
    fields = _Cached(system)
    t, T = float(t0), float(T)
    stops = sorted({b for b in system.breaks if t < b < T} | {T})
    mode = choose_mode(fields(t, x), x, name=system.name, t=t)
    starts, pieces, switches, modes = [], [], [], [(t, mode)]
    events = stalls = 0
    while t < T:
        stop = next(s for s in stops if s > t)
        inside = _inside(t, stop)
        current = mode
        run = solve_ivp(lambda s, y: velocity(fields(inside(s), y), current)[0], (t, stop), x, method="DOP853",
                        rtol=rtol, atol=atol, dense_output=True, events=_events(fields, current, inside))
        if run.status == -1:
            raise FilippovError(f"{system.name}: DOP853 failed at t = {run.t[-1]:.17g} in mode {mode}: {run.message}")
        end = float(run.t[-1])
        if end > t:
            starts.append(t)
            pieces.append(run.sol)
        stalls = stalls + 1 if end <= t + 1e-14 * max(1.0, abs(t)) else 0
        events += 1
        if stalls > MAX_STALLS or events > MAX_EVENTS + len(stops):
            raise FilippovError(f"{system.name}: no progress at t = {t:.17g} ({events} events): Zeno or chattering")
        t, x = end, run.y[:, -1].copy()
        if run.status == 1:
            (i,) = [j for j, hits in enumerate(run.t_events) if hits.size][:1]
            t, x = float(run.t_events[i][0]), run.y_events[i][0].copy()
            here = fields(_inside(t, stop)(t), x)
            if mode[i] == 0:
                lam = velocity(here, mode)[1][i]
                new = choose_mode(here, x, mode, released=(i, 1 if lam > 0 else -1), name=system.name, t=t)
            else:
                new = choose_mode(here, x, mode, crossed=i, name=system.name, t=t)
        elif t < T:  # a break in the drift: choose afresh just after it
            new = choose_mode(fields(_inside(t, next(s for s in stops if s > t))(t), x), x, mode,
                              name=system.name, t=t)
        else:
            break
        if new != mode and t < T:
            switches.append(t)
            modes.append((t, new))
        mode = new
    if not pieces:
        raise FilippovError(f"{system.name}: nothing integrated over [{t0}, {T}]")
    return FilippovTrajectory(np.array(starts), pieces, tuple(switches), modes, T, events,
                              time.perf_counter() - clock)


def _events(fields: _Cached, mode: tuple[int, ...], inside: Callable[[float], float]) -> list[Callable]:
    out = []
    for i, m in enumerate(mode):
        if m == 0:
            def release(t: float, x: np.ndarray, i: int = i) -> float:
                try:
                    return abs(velocity(fields(inside(t), x), mode)[1][i]) - 1.0
                except np.linalg.LinAlgError:
                    return 1.0

            release.terminal, release.direction = True, 1.0
            out.append(release)
        else:
            def crossing(t: float, x: np.ndarray, i: int = i) -> float:
                return float(fields(inside(t), x).s[i])

            crossing.terminal, crossing.direction = True, -float(m)
            out.append(crossing)
    return out


def _inside(start: float, stop: float) -> Callable[[float], float]:
    """t clipped into the open piece (start, stop), one ulp in from each end: DOP853's last
    stage t + h can round past `stop`, where an input's jump (a break) would be seen too early."""
    low, high = np.nextafter(start, stop), np.nextafter(stop, start)
    return lambda t: min(max(t, low), high)


# -------------------------------------------------------------------- a model's system
Input = Callable[[float], np.ndarray]


def model_system(functional, controls: Input | None = None, choice: Input | None = None,
                 breaks: Sequence[float] = ()) -> FilippovSystem:
    """A qdframe model in the form x' ∈ g + B·Sgn(s), from its functional (exact signs).

    g: each block's set without its sign terms, G_b(y) with y = (x, u(t)): its point where
    G_b is one (an equation), else the point of G_b nearest to `choice(t)`'s coordinates (a
    clip for an interval; :func:`~qdframe.functional.nearest.nearest` for a block of k ≥ 2
    coordinates); a resolved state z_i ≡ x_j gives x_j. B: column k of selection k holds
    sense·a(y) of each sign term on it, in its block's coordinate. s: the selections'
    switches. `controls(t)` gives u (m,), `choice(t)` the velocities whose nearest points in
    the sets are taken (n,), `breaks` the times where either jumps. One point at a time:
    the pieces are called with one row (N = 1) directly, without the functional's checks
    (a non-finite value raises FilippovError naming the piece). Raises FilippovError for a
    model with a set-valued block and no `choice`.
    """
    from .functional.nearest import nearest

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
    switches = [term.switch for _, term in functional.selection_terms]
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
        for k, switch in enumerate(switches):
            value, gradient = switch(y)
            s[k], ds[k] = value[0], gradient[0, :n]
        if not np.isfinite(g.sum() + B.sum() + s.sum() + ds.sum()):
            raise FilippovError(f"{model.name}: the model is non-finite at t = {t:.6g}, x = {np.array2string(x)}")
        return Fields(g, B, s, ds)

    names = tuple(term.name for _, term in functional.selection_terms)
    return FilippovSystem(fields, names, model.name, tuple(float(b) for b in breaks))


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
