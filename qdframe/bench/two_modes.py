"""An event-driven integration of a two-mode Filippov system: the judge of runs and references.

    x' = f₊(x, u(t)) where c(x) > 0,   x' = f₋(x, u(t)) where c(x) < 0,

and on c = 0 Filippov's convex combination x' = θ·f₊ + (1 − θ)·f₋ that keeps c there,
θ = a/(a − b) with a = ∇c·f₋ and b = ∇c·f₊, while the surface attracts (a ≥ 0 ≥ b): a Coulomb
contact that sticks, a relay that slides. A mode lasts until its terminal event: c reaching 0
(then the surface is crossed where a and b have one sign, else slid on), or, sliding, b rising
through 0 (it leaves to c > 0) or a falling through 0 (to c < 0). A surface that repels
(a < 0 < b) has no unique motion and ends the integration. Between events scipy's DOP853 at
rtol = atol = 1e-12 integrates x and a running cost ∫c(x, u) dt together, restarted at each
of the input's breaks (where u jumps or kinks).

It shares no code with qdframe's own Filippov integrator (:mod:`qdframe.certificates.filippov`,
which certifies qdframe's answers): `qdframe bench run --suite ocp` judges every run's control
with it (:mod:`.ocp`: a contact x' ∈ g − a·e_j·Sgn(x_j) is f± = g ∓ a·e_j on c = x_j), and the
tests hold qdframe's solutions of nosnoc's switched models (:func:`qdframe.sets.Modes`) to it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

TOL = 1e-12  # DOP853's rtol and atol
SURFACE_TOL = 1e-10  # |c| at most this (relative to max(1, |x|)): x is on the surface
MAX_EVENTS = 10_000

Field = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Motion:
    """The end state, the cost ∫c dt (+ M(x(T))), the mode changes, and x at the integrator's
    steps with their times (a dense record, not interpolated)."""

    x_end: np.ndarray
    cost: float
    events: int
    t: np.ndarray  # (K,)
    samples: np.ndarray  # (K, n)

    def at(self, times: np.ndarray) -> np.ndarray:
        """x at `times`, linearly between the recorded steps (for a reference, record densely: `dense`)."""
        return np.stack([np.interp(times, self.t, column) for column in self.samples.T], axis=1)


@dataclass(frozen=True)
class TwoModes:
    """f₊ and f₋ (functions of x and u, each (n,)), the switch c(x) and its gradient ∇c(x) (n,);
    `switch` None: one smooth field f₊ (no surface)."""

    positive: Field
    negative: Field
    switch: Callable[[np.ndarray], float] | None = None
    gradient: Callable[[np.ndarray], np.ndarray] | None = None


def integrate(system: TwoModes, x0: Sequence[float], T: float, control: Callable[[float], np.ndarray] | None = None,
              breaks: Sequence[float] = (), running: Callable[[np.ndarray, np.ndarray], float] | None = None,
              terminal: Callable[[np.ndarray], float] | None = None, dense: Sequence[float] = ()) -> Motion:
    """The motion from x0 over [0, T] (module docstring); `control` u(t) (none: an empty u), its
    `breaks` in (0, T), the running cost c(x, u) and terminal cost M(x(T)) (none: 0), `dense`
    times where x is recorded besides the integrator's steps."""
    control = control if control is not None else (lambda t: np.zeros(0))
    x = np.asarray(x0, dtype=float).copy()
    n = x.size
    times = sorted({0.0, float(T), *(float(b) for b in breaks if 0.0 < b < T)})
    wanted = np.unique(np.asarray(dense, dtype=float))
    cost, events, record_t, record_x = 0.0, 0, [0.0], [x.copy()]
    forced = None  # the side a slide just left to (at b = 0 or a = 0 the next mode is that side's)
    for start, end in zip(times[:-1], times[1:]):
        t = start
        while t < end:
            mode = forced if forced is not None else _mode(system, control, x, t)
            forced = None
            inside = wanted[(wanted > t) & (wanted < end)]
            solution = solve_ivp(_rhs(system, control, running, mode, n), (t, end), np.concatenate([x, [0.0]]),
                                 method="DOP853", rtol=TOL, atol=TOL, events=_events(system, control, mode),
                                 t_eval=None, dense_output=bool(inside.size))
            if solution.status < 0:
                raise RuntimeError(f"the integration failed at t = {t:.6g}: {solution.message}")
            reached = float(solution.t[-1])
            if inside.size:
                kept = inside[inside <= reached]
                record_t.extend(kept)
                record_x.extend(solution.sol(kept)[:n].T)
            record_t.extend(solution.t[1:])
            record_x.extend(solution.y[:n, 1:].T)
            x, t = solution.y[:n, -1].copy(), reached
            cost += float(solution.y[n, -1])
            if solution.status == 1 and t < end:
                events += 1
                if mode == 0:  # left the surface: to the side whose field turned outward
                    fired = [i for i, hit in enumerate(solution.t_events) if hit.size]
                    forced = 1 if fired and fired[0] == 0 else -1
                if events > MAX_EVENTS:
                    raise RuntimeError(f"the mode changed {MAX_EVENTS} times by t = {t:.6g} (chattering)")
            else:
                t = end
    cost += float(terminal(x)) if terminal is not None else 0.0
    order = np.argsort(np.asarray(record_t), kind="stable")
    return Motion(x, cost, events, np.asarray(record_t)[order], np.asarray(record_x)[order])


def _rates(system: TwoModes, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """f₊, f₋, a = ∇c·f₋ and b = ∇c·f₊ at (x, u)."""
    plus, minus = np.asarray(system.positive(x, u), float), np.asarray(system.negative(x, u), float)
    gradient = np.asarray(system.gradient(x), float)
    return plus, minus, float(gradient @ minus), float(gradient @ plus)


def _mode(system: TwoModes, control, x: np.ndarray, t: float) -> int:
    """+1 or −1 (the side of c, or at the surface the side both fields point to) or 0 (sliding)."""
    if system.switch is None:
        return 1
    c = float(system.switch(x))
    if abs(c) > SURFACE_TOL * max(1.0, float(np.max(np.abs(x)))):
        return 1 if c > 0 else -1
    _, _, a, b = _rates(system, x, control(t))
    if a >= 0.0 >= b:
        return 0
    if a > 0.0 and b > 0.0:
        return 1
    if a < 0.0 and b < 0.0:
        return -1
    raise RuntimeError(f"the surface repels at t = {t:.6g} (∇c·f₋ = {a:.3g} < 0 < ∇c·f₊ = {b:.3g}): no unique motion")


def _rhs(system: TwoModes, control, running, mode: int, n: int) -> Callable[[float, np.ndarray], np.ndarray]:
    def rhs(t: float, state: np.ndarray) -> np.ndarray:
        x, u = state[:n], control(t)
        if mode == 0:
            plus, minus, a, b = _rates(system, x, u)
            theta = a / (a - b) if a != b else 0.5
            velocity = theta * plus + (1.0 - theta) * minus
        else:
            velocity = np.asarray((system.positive if mode > 0 else system.negative)(x, u), float)
        return np.concatenate([velocity, [float(running(x, u)) if running is not None else 0.0]])

    return rhs


def _events(system: TwoModes, control, mode: int) -> list:
    """Sliding: b rising through 0 (leave to +), a falling through 0 (leave to −); else c reaching 0."""
    if system.switch is None:
        return []
    if mode == 0:
        def outward_plus(t: float, state: np.ndarray) -> float:
            return _rates(system, state[:-1], control(t))[3]

        def outward_minus(t: float, state: np.ndarray) -> float:
            return _rates(system, state[:-1], control(t))[2]

        outward_plus.terminal, outward_plus.direction = True, 1
        outward_minus.terminal, outward_minus.direction = True, -1
        return [outward_plus, outward_minus]

    def reach(t: float, state: np.ndarray) -> float:
        return float(system.switch(state[:-1]))

    reach.terminal, reach.direction = True, -float(mode)
    return [reach]


def contact(field: Field, friction: tuple[int, object] | None, push: Callable[[np.ndarray], list] | None = None) -> TwoModes:
    """x' ∈ g(x, u) − b(x)·Sgn(x_j): f± = g ∓ b on c = x_j (`friction` (j, a), b = a·e_j, or `push`
    giving b(x)); g alone without one."""
    if friction is None:
        return TwoModes(field, field)
    j, amplitude = friction

    def force(x: np.ndarray) -> np.ndarray:
        if push is not None:
            return np.asarray(push(x), dtype=float)
        out = np.zeros(x.size)
        out[j] = amplitude
        return out

    def mode(sign: float) -> Field:
        def f(x: np.ndarray, u: np.ndarray) -> np.ndarray:
            return np.array(field(x, u), dtype=float) - sign * force(x)
        return f

    def gradient(x: np.ndarray) -> np.ndarray:
        out = np.zeros(x.size)
        out[j] = 1.0
        return out

    return TwoModes(mode(1.0), mode(-1.0), lambda x: float(x[j]), gradient)
