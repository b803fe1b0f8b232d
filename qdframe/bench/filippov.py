"""An independent event-driven Filippov integrator: reference solutions for the benchmarks.

It solves separable Filippov systems

    x' ∈ g(t, x) − Σ_i a_i(t, x)·Sgn(c_i(x))·b_i,

b_i a constant vector, a_i ≥ 0 a gain, c_i a scalar switching function, with
scipy's DOP853 (rtol = atol = 1e-12) between events, and nothing of qdframe's solver.
Each switch is in a mode m_i: +1 (c_i > 0, Sgn = +1), −1 (c_i < 0) or 0 (sliding or
sticking on c_i = 0). On the sliding set S the selections σ_S ∈ [−1, 1] are the
equivalent control, the solution of

    M·σ_S = r,   M_ik = ∇c_i·b_k·a_k,   r_i = ∇c_i·(g − Σ_{k∉S} a_k·m_k·b_k)   (i, k ∈ S),

which keeps every dc_i/dt = 0. A piece ends at a terminal event: a c_i (i ∉ S) reaching
0 from its side, or a sliding |σ_i| reaching 1. There the new mode is chosen by
enumerating the modes {+1, −1, 0} of the switches at the surface: a mode is consistent
when its σ_S lie in [−1, 1] and every other switch at the surface moves to its own side
(m_i·dc_i/dt ≥ 0). Both conditions are measured in σ units (dc_i/dt is divided by
a_i·|∇c_i·b_i|), so that at a transversal crossing or an attractive surface exactly one
mode has a non-negative margin (Filippov's rule: attractive → slide, transversal →
cross), and the mode of largest smallest margin is taken. A switch whose σ reached ±1
(a stick release) leaves to the side sign(σ).

:func:`statement` writes qdframe's friction and sliding models in this form (reading
their constants), :func:`reference` integrates them from their start over [0, T].
"""

from __future__ import annotations

import itertools
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.integrate import OdeSolution, solve_ivp

Input = Callable[[float], np.ndarray]

SURFACE_TOL = 1e-11  # |c_i| at most this: switch i is at its surface (events locate c to ~1e-16)
MARGIN_TOL = 1e-9  # a mode is consistent when every margin (σ units) is ≥ −MARGIN_TOL
MAX_EVENTS = 100_000  # mode changes and events, beyond the declared breaks
MAX_STALLS = 20  # consecutive events without progress in t before giving up (Zeno, chattering)


class FilippovError(RuntimeError):
    """The integration cannot continue: no consistent mode, an ODE failure, or no progress."""


@dataclass(frozen=True)
class SignSwitch:
    """One sign term −a(t, x)·Sgn(c(x))·b of x': switch c, its gradient ∇c, direction b, gain a ≥ 0."""

    switch: Callable[[np.ndarray], float]
    gradient: Callable[[np.ndarray], np.ndarray]
    direction: np.ndarray
    gain: Callable[[float, np.ndarray], float]
    name: str = ""


@dataclass(frozen=True)
class FilippovSystem:
    """x' ∈ drift(t, x) − Σ_i gain_i(t, x)·Sgn(switch_i(x))·direction_i.

    `breaks`: times where the drift is not smooth in t (an input's jumps); the
    integrator ends a piece there and chooses the mode afresh.
    """

    drift: Callable[[float, np.ndarray], np.ndarray]
    switches: tuple[SignSwitch, ...]
    name: str = ""
    breaks: tuple[float, ...] = ()


@dataclass
class FilippovTrajectory:
    """The integrated motion: DOP853 dense outputs of the pieces between mode changes.

    `switch_times`: the times the mode changed (entering or leaving sliding, crossing);
    `modes`: (start time, mode) of every mode taken, the first at t = 0.
    """

    starts: np.ndarray  # (P,) start time of each piece
    pieces: list[OdeSolution]
    switch_times: tuple[float, ...]
    modes: list[tuple[float, tuple[int, ...]]]
    T: float
    events: int = 0  # terminal events met (mode changes and re-choices)
    seconds: float = field(default=0.0, compare=False)

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """x(t), (K, n), for the times t (K,) in [0, T]: each time from the piece containing it."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        which = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.pieces) - 1)
        n = self.pieces[0](self.starts[0]).size
        out = np.empty((t.size, n))
        for index in np.unique(which):
            chosen = which == index
            out[chosen] = np.atleast_2d(self.pieces[index](t[chosen])).T
        return out


# ----------------------------------------------------------------- modes and fields
def _slopes(system: FilippovSystem, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """g (n,), the gains a (k,), and B (n, k) with columns a_i·b_i."""
    g = np.asarray(system.drift(t, x), dtype=float)
    gains = np.array([float(s.gain(t, x)) for s in system.switches])
    directions = np.stack([np.asarray(s.direction, dtype=float) for s in system.switches], axis=1)
    return g, gains, directions * gains


def velocity(system: FilippovSystem, mode: Sequence[int], t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x' = g − Σ a_i·σ_i·b_i in `mode` and the selections σ (k,): m_i off the surface,
    the equivalent control on it (M·σ_S = r, M_ik = ∇c_i·b_k·a_k, r_i = ∇c_i·(g − Σ_{k∉S} a_k m_k b_k)).

    Raises numpy.linalg.LinAlgError when M is singular.
    """
    g, _, scaled = _slopes(system, t, x)
    sigma = np.array(mode, dtype=float)
    sliding = [i for i, m in enumerate(mode) if m == 0]
    base = g - scaled @ sigma  # the σ_S entries are 0 here
    if sliding:
        grads = np.stack([np.asarray(system.switches[i].gradient(x), dtype=float) for i in sliding])
        sigma[sliding] = np.linalg.solve(grads @ scaled[:, sliding], grads @ base)
        base = base - scaled[:, sliding] @ sigma[sliding]
    return base, sigma


def _margins(system: FilippovSystem, mode: tuple[int, ...], at: Sequence[int], t: float, x: np.ndarray) -> np.ndarray:
    """For the switches `at` the surface, in σ units: 1 − |σ_i| when sliding, m_i·(dc_i/dt)/(a_i·|∇c_i·b_i|)
    when moving (the distance of the far field from tangency; ≥ 0 means consistent)."""
    try:
        f, sigma = velocity(system, mode, t, x)
    except np.linalg.LinAlgError:
        return np.array([-np.inf])
    _, _, scaled = _slopes(system, t, x)
    out = []
    for i in at:
        if mode[i] == 0:
            out.append(1.0 - abs(sigma[i]))
            continue
        grad = np.asarray(system.switches[i].gradient(x), dtype=float)
        scale = abs(grad @ scaled[:, i])
        out.append(mode[i] * (grad @ f) / (scale if scale > 1e-14 else 1.0))
    return np.array(out)


def choose_mode(system: FilippovSystem, t: float, x: np.ndarray, current: tuple[int, ...] | None = None,
                crossed: int | None = None, released: tuple[int, int] | None = None) -> tuple[int, ...]:
    """The Filippov mode at (t, x): enumerate {+1, −1, 0} for every switch at its surface
    (|c_i| ≤ SURFACE_TOL, sliding in `current`, or the `crossed` one), keep the consistent
    modes (every margin ≥ −MARGIN_TOL) and take the one of largest smallest margin.

    `crossed`: switch i reached c_i = 0 from side current[i], which it cannot keep.
    `released`: (i, ±1), switch i's σ reached ±1: it leaves to that side.
    """
    values = np.array([float(s.switch(x)) for s in system.switches])
    at = {i for i, c in enumerate(values) if abs(c) <= SURFACE_TOL}
    if current is not None:
        at |= {i for i, m in enumerate(current) if m == 0}
    if crossed is not None:
        at.add(crossed)
    if released is not None:
        at.add(released[0])
    at = sorted(at)
    fixed = [1 if c > 0 else -1 for c in values]
    best, best_margin = None, -np.inf
    for choice in itertools.product((0, 1, -1), repeat=len(at)):
        mode = list(fixed)
        for i, m in zip(at, choice):
            mode[i] = m
        if crossed is not None and current is not None and mode[crossed] == current[crossed]:
            continue
        if released is not None and mode[released[0]] != released[1]:
            continue
        margins = _margins(system, tuple(mode), at, t, x)
        smallest = float(margins.min()) if margins.size else np.inf
        if smallest >= -MARGIN_TOL and smallest > best_margin:
            best, best_margin = tuple(mode), smallest
    if best is None:
        names = ", ".join(system.switches[i].name or str(i) for i in at)
        raise FilippovError(f"{system.name}: no consistent Filippov mode at t = {t:.17g} (switches at the surface: {names})")
    return best


# ------------------------------------------------------------------------- events
def _crossing_event(system: FilippovSystem, i: int, side: int) -> Callable:
    """c_i(x), terminal, triggered only on the way to 0 from `side`."""

    def event(_t: float, x: np.ndarray) -> float:
        return float(system.switches[i].switch(x))

    event.terminal, event.direction = True, -float(side)
    return event


def _release_event(system: FilippovSystem, mode: tuple[int, ...], i: int, inside: Callable[[float], float]) -> Callable:
    """|σ_i| − 1 of a sliding switch, terminal when it rises through 0."""

    def event(t: float, x: np.ndarray) -> float:
        try:
            return abs(velocity(system, mode, inside(t), x)[1][i]) - 1.0
        except np.linalg.LinAlgError:
            return 1.0

    event.terminal, event.direction = True, 1.0
    return event


def _events(system: FilippovSystem, mode: tuple[int, ...], inside: Callable[[float], float]) -> list[Callable]:
    return [_release_event(system, mode, i, inside) if m == 0 else _crossing_event(system, i, m)
            for i, m in enumerate(mode)]


def _inside(start: float, stop: float) -> Callable[[float], float]:
    """t clipped into the open piece (start, stop), one ulp in from each end: DOP853's last
    stage t + h can round past `stop`, where an input's jump (a break) would be seen too early."""
    low, high = np.nextafter(start, stop), np.nextafter(stop, start)
    return lambda t: min(max(t, low), high)


# ------------------------------------------------------------------------ integrate
def integrate(system: FilippovSystem, x0: Sequence[float], T: float, rtol: float = 1e-12,
              atol: float = 1e-12) -> FilippovTrajectory:
    """The Filippov solution of `system` from x(0) = x0 over [0, T]: DOP853 (dense output)
    between terminal events, the mode re-chosen by :func:`choose_mode` at every event."""
    clock = time.perf_counter()
    x = np.array(x0, dtype=float)
    if not np.all(np.isfinite(x)):
        raise FilippovError(f"{system.name}: x0 must be finite, got {x}")
    t, T = 0.0, float(T)
    stops = sorted({b for b in system.breaks if 0.0 < b < T} | {T})
    mode = choose_mode(system, t, x)
    starts, pieces, switches, modes = [], [], [], [(t, mode)]
    events = stalls = 0
    while t < T:
        stop = next(s for s in stops if s > t)
        inside = _inside(t, stop)
        run = solve_ivp(lambda s, y: velocity(system, mode, inside(s), y)[0], (t, stop), x, method="DOP853",
                        rtol=rtol, atol=atol, dense_output=True, events=_events(system, mode, inside))
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
            if mode[i] == 0:
                sigma = velocity(system, mode, t, x)[1][i]
                new = choose_mode(system, t, x, mode, released=(i, 1 if sigma > 0 else -1))
            else:
                new = choose_mode(system, t, x, mode, crossed=i)
        elif t < T:  # a break in the drift: choose afresh
            new = choose_mode(system, t, x, mode)
        else:
            break
        if new != mode and t < T:
            switches.append(t)
            modes.append((t, new))
        mode = new
    if not pieces:
        raise FilippovError(f"{system.name}: nothing integrated over [0, {T}]")
    return FilippovTrajectory(np.array(starts), pieces, tuple(switches), modes, T, events, time.perf_counter() - clock)


# ------------------------------------------------------------------------ statements
def _unit(index: int, n: int) -> np.ndarray:
    e = np.zeros(n)
    e[index] = 1.0
    return e


def _coordinate_switch(index: int, n: int, gain: Callable[[float, np.ndarray], float], name: str,
                       direction: np.ndarray | None = None) -> SignSwitch:
    """−gain·Sgn(x_index)·b with c = x_index, ∇c = e_index, b = e_index unless given."""
    unit = _unit(index, n)
    return SignSwitch(lambda x: x[index], lambda x: unit, unit if direction is None else np.asarray(direction, float),
                      gain, name)


def _constant(a: float) -> Callable[[float, np.ndarray], float]:
    return lambda _t, _x: a


def _input(inputs: Input, size: int) -> Callable[[float], np.ndarray]:
    """inputs(t) as a vector of `size` (a scalar input may be a float)."""

    def value(t: float) -> np.ndarray:
        u = np.asarray(inputs(t), dtype=float).reshape(-1)
        if u.size != size:
            raise ValueError(f"inputs(t) must give {size} value(s), got {u.size}")
        return u

    return value


def _constants(model) -> dict:
    """The model's module constants (its parameters where the class does not carry them)."""
    return vars(sys.modules[type(model).__module__])


def _block_stop_stick(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    pull, friction = k["STOP_PULL"], k["STOP_FRICTION"]
    return FilippovSystem(lambda t, x: np.array([x[1], pull]),
                          (_coordinate_switch(1, 2, _constant(friction), "μg·Sgn(v)"),), model.name)


def _block_breakaway(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    ramp, friction = k["BREAK_RAMP"], k["BREAK_FRICTION"]
    return FilippovSystem(lambda t, x: np.array([x[1], ramp * x[2], 1.0]),
                          (_coordinate_switch(1, 3, _constant(friction), "μg·Sgn(v)"),), model.name)


def _slide_on_line(model, inputs: Input | None) -> FilippovSystem:
    gain = _constants(model)["LINE_GAIN"]
    surface = SignSwitch(lambda x: x[0] + x[1], lambda x: np.array([1.0, 1.0]), _unit(1, 2), _constant(gain),
                         "a·Sgn(x1 + x2)")
    return FilippovSystem(lambda t, x: np.array([x[1], 0.0]), (surface,), model.name)


def _two_surface(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    a1, a2, b = k["TWO_A1"], k["TWO_A2"], k["TWO_B"]
    return FilippovSystem(lambda t, x: np.array([a1, a2]),
                          (_coordinate_switch(0, 2, _constant(1.0), "Sgn(x1)"),
                           _coordinate_switch(1, 2, _constant(1.0), "Sgn(x2)", np.array([b, 1.0]))), model.name)


def _stick_slip_oscillator(model, inputs: Input | None) -> FilippovSystem:
    friction = _constants(model)["OSC_FRICTION"]
    return FilippovSystem(lambda t, x: np.array([x[1], -x[0]]),
                          (_coordinate_switch(1, 2, _constant(friction), "μ·Sgn(v)"),), model.name)


def _coulomb_block(model, inputs: Input | None) -> FilippovSystem:
    pull, gain = model.pull / model.mass, model.mu * model.normal_force / model.mass
    return FilippovSystem(lambda t, x: np.array([x[1], pull]),
                          (_coordinate_switch(1, 2, _constant(gain), "μ·F_N·Sgn(v)/m"),), model.name)


def _sliding_mode(model, inputs: Input | None) -> FilippovSystem:
    slope, gain = model.slope, model.gain
    surface = SignSwitch(lambda x: slope * x[0] + x[1], lambda x: np.array([slope, 1.0]), _unit(1, 2),
                         lambda _t, x: gain * (abs(x[0]) + abs(x[1])), "a·|x|·Sgn(s)")
    return FilippovSystem(lambda t, x: np.array([x[1], x[0]]), (surface,), model.name)


def _coulomb_rest_to_rest(model, inputs: Input | None) -> FilippovSystem | None:
    if inputs is None:
        return None
    u = _input(inputs, 1)
    return FilippovSystem(lambda t, x: np.array([x[1], u(t)[0]]),
                          (_coordinate_switch(1, 2, _constant(model.friction), "F·Sgn(v)"),), model.name)


def _sliding_mode_terminal(model, inputs: Input | None) -> FilippovSystem | None:
    if inputs is None:
        return None
    k = _constants(model)
    a, b = k["SLIDING_A"], k["SLIDING_B"]
    w = _input(inputs, 2)
    c1 = SignSwitch(lambda x: x[0] + a * x[1] ** 2, lambda x: np.array([1.0, 2 * a * x[1], 0.0, 0.0]), _unit(0, 4),
                    _constant(1.0), "Sgn(c1)")
    c2 = SignSwitch(lambda x: x[1] + b * x[0] ** 3, lambda x: np.array([3 * b * x[0] ** 2, 1.0, 0.0, 0.0]),
                    _unit(1, 4), _constant(1.0), "Sgn(c2)")
    return FilippovSystem(lambda t, x: np.concatenate([x[2:4], w(t)]), (c1, c2), model.name)


def _paper_73(model, inputs: Input | None) -> FilippovSystem | None:
    if inputs is None:
        return None
    k = _constants(model)
    gain, friction = k["GAIN"], k["FRICTION"]
    u = _input(inputs, 1)

    def drift(t: float, x: np.ndarray) -> np.ndarray:
        x1, x2, x3, x4, x5, x6 = x
        return np.array([x4, x5, x6, -2 * x1 + x2 - x4, x1 - 2 * x2 + x3 - x5, x2 - x3 - x6 + u(t)[0]])

    return FilippovSystem(drift, (_coordinate_switch(3, 6, lambda _t, x: gain * float(np.sum(np.abs(x))), "1.05|x|Sgn(x4)"),
                                  _coordinate_switch(4, 6, _constant(friction), "0.3 Sgn(x5)"),
                                  _coordinate_switch(5, 6, _constant(friction), "0.3 Sgn(x6)")),
                          model.name)


STATEMENTS: dict[str, Callable] = {
    "block-stop-stick": _block_stop_stick,
    "block-stop-stick-bvp": _block_stop_stick,
    "block-breakaway": _block_breakaway,
    "slide-on-line": _slide_on_line,
    "slide-after-reaching": _slide_on_line,
    "two-surface-sliding": _two_surface,
    "stick-slip-oscillator": _stick_slip_oscillator,
    "coulomb-block": _coulomb_block,
    "sliding-mode": _sliding_mode,
    "coulomb-rest-to-rest": _coulomb_rest_to_rest,
    "sliding-mode-terminal": _sliding_mode_terminal,
    "paper-7.3": _paper_73,
    "paper-7.3-reduced": _paper_73,
}


def statement(model, inputs: Input | None = None) -> FilippovSystem | None:
    """The separable Filippov system x' ∈ g − Σ a_i·Sgn(c_i)·b_i of a qdframe model, by `model.name`,
    its parameters read from the model (class attributes, module constants); None for a model
    it cannot state, or one that needs `inputs` when none is given.

    Friction −μ·Sgn(v) (coded by qdframe as μ·Sgn(−v)) is stated with c = v, a = μ, b = e_v.
    Covered: block-stop-stick (and -bvp: the same system; its p(0) is free, :func:`reference`
    starts from the model's exact solution at 0), block-breakaway (x = (p, v, clock), the pull
    k·clock), slide-on-line, slide-after-reaching, two-surface-sliding (x2's switch acts on
    both coordinates, b = (0.5, 1)), stick-slip-oscillator, coulomb-block, sliding-mode
    (Utkin, a = gain·(|x1| + |x2|)), and with `inputs(t)`: coulomb-rest-to-rest (the force
    u(t): p' = v, v' ∈ u − F·Sgn(v)), sliding-mode-terminal (w(t) = (v1', v2'):
    x1' ∈ v1 − Sgn(c1), x2' ∈ v2 − Sgn(c2), v' = w), paper-7.3 and paper-7.3-reduced
    (u(t) on x6'; a = 1.05·|x|_1 on x4, 0.3 on x5 and x6). An `inputs` with a `breaks`
    attribute (times of its jumps) passes them to the system.
    """
    build = STATEMENTS.get(getattr(model, "name", ""))
    system = None if build is None else build(model, inputs)
    if system is None or not getattr(inputs, "breaks", ()):
        return system
    return replace(system, breaks=tuple(inputs.breaks))


def start(model) -> np.ndarray | None:
    """model.x0, its NaN entries (free starts) taken from the model's exact solution at 0; None if unknown."""
    x0 = np.array(model.x0, dtype=float)
    if np.all(np.isfinite(x0)):
        return x0
    exact = model.exact_solution(np.array([0.0]))
    if exact is None:
        return None
    return np.where(np.isfinite(x0), x0, exact[0])


def reference(model, inputs: Input | None = None, rtol: float = 1e-12, atol: float = 1e-12) -> FilippovTrajectory | None:
    """The Filippov motion of `model` over [0, model.T] from :func:`start`, by :func:`integrate`;
    None when :func:`statement` cannot state the model or its start is unknown."""
    system, x0 = statement(model, inputs), start(model)
    if system is None or x0 is None:
        return None
    return integrate(system, x0, model.T, rtol, atol)
