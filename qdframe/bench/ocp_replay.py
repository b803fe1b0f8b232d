"""The yardstick of `qdframe bench ocp`: a control replayed through the true dynamics.

Every optimal-control run, qdframe's or a peer's, returns a control u(t). Its worth is the
motion that control drives from x(0) and what that motion costs: the run's own cost and
its own end state are those of its discrete problem, which another scheme discretizes
otherwise. So each control is replayed here, by the same code for every run,

    x' ∈ g(x, u(t)) − a·e_j·Sgn(x_j),   x(0) = x0,      J = ∫_0^T c(x, u) dt + M(x(T)),

with at most one Coulomb term (state j, amplitude a > 0; none for a smooth problem), event
by event: while x_j ≠ 0 the sign is x_j's; where x_j reaches 0 the contact sticks (x_j' = 0)
if |g_j| ≤ a there, else it crosses to the side of g_j; a stuck contact breaks away where
|g_j| reaches a. Between events scipy's DOP853 at rtol = atol = 1e-12 integrates x and the
running cost together, restarted at each of the control's breaks (where it jumps or kinks).
It is independent of qdframe's own Filippov integrator (:mod:`qdframe.certificates.filippov`),
which certifies qdframe's answers: a judge must not share the code it judges.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

TOL = 1e-12  # DOP853's rtol and atol
STICK_TOL = 1e-12  # |x_j| at most this (relative to max(1, |x|)): the contact is at its surface


@dataclass(frozen=True)
class Replayed:
    """The motion a control drives: its end state, its cost and the largest |x| and bound
    excess of its states along the way (sampled at the integrator's steps)."""

    x_end: np.ndarray
    cost: float
    events: int
    samples: np.ndarray  # (K, n): the states at the integrator's steps


def replay(field: Callable[[np.ndarray, np.ndarray], np.ndarray], running: Callable[[np.ndarray, np.ndarray], float],
           terminal: Callable[[np.ndarray], float] | None, x0: Sequence[float], T: float,
           control: Callable[[float], np.ndarray], breaks: Sequence[float],
           friction: tuple[int, float] | None = None) -> Replayed:
    """The motion of x' ∈ g(x, u) − a·e_j·Sgn(x_j) under `control` (module docstring): `field`
    is g(x, u) (n,), `running` c(x, u), `terminal` M(x(T)) or None, `breaks` the times in
    (0, T) where the control jumps or kinks, `friction` (j, a) or None."""
    x = np.asarray(x0, dtype=float).copy()
    n = x.size
    times = [0.0, *sorted(float(b) for b in breaks if 0.0 < b < T), float(T)]
    cost, events, samples = 0.0, 0, [x.copy()]
    for start, end in zip(times[:-1], times[1:]):
        t = start
        while t < end:
            mode = _mode(field, control, x, t, friction)
            piece = _piece(field, running, control, friction, mode, n)
            event = _event(field, control, friction, mode)
            solution = solve_ivp(piece, (t, end), np.concatenate([x, [0.0]]), method="DOP853", rtol=TOL, atol=TOL,
                                 events=event)
            if solution.status < 0:
                raise RuntimeError(f"the replay's integration failed at t = {t:.6g}: {solution.message}")
            x, t = solution.y[:n, -1].copy(), float(solution.t[-1])
            cost += float(solution.y[n, -1])
            samples.extend(solution.y[:n].T)
            if solution.status == 1 and t < end:  # an event: the contact reached its surface or broke away
                events += 1
                if friction is not None and mode != 0:
                    x[friction[0]] = 0.0
                if events > 10_000:
                    raise RuntimeError(f"the replay's contact changed mode 10000 times by t = {t:.6g} (chattering)")
            else:
                t = end
    cost += float(terminal(x)) if terminal is not None else 0.0
    return Replayed(x, cost, events, np.asarray(samples))


def _mode(field, control, x: np.ndarray, t: float, friction) -> int:
    """+1 or −1 (sliding, x_j's sign or, at the surface, the side g_j pushes to) or 0 (stuck)."""
    if friction is None:
        return 1
    j, a = friction
    if abs(x[j]) > STICK_TOL * max(1.0, float(np.max(np.abs(x)))):
        return 1 if x[j] > 0 else -1
    force = float(field(x, control(t))[j])
    return 0 if abs(force) <= a else (1 if force > 0 else -1)


def _piece(field, running, control, friction, mode: int, n: int) -> Callable[[float, np.ndarray], np.ndarray]:
    """The right-hand side of (x, ∫c) in `mode`."""
    def rhs(t: float, state: np.ndarray) -> np.ndarray:
        x, u = state[:n], control(t)
        velocity = np.array(field(x, u), dtype=float)
        if friction is not None:
            j, a = friction
            velocity[j] = 0.0 if mode == 0 else velocity[j] - a * mode
        return np.concatenate([velocity, [float(running(x, u))]])

    return rhs


def _event(field, control, friction, mode: int) -> list:
    """The terminal event of a piece: x_j reaching 0 while sliding, |g_j| reaching a while stuck."""
    if friction is None:
        return []
    j, a = friction
    if mode == 0:
        def breakaway(t: float, state: np.ndarray) -> float:
            return abs(float(field(state[:-1], control(t))[j])) - a
        breakaway.terminal, breakaway.direction = True, 1
        return [breakaway]

    def stop(t: float, state: np.ndarray) -> float:
        return state[j]
    stop.terminal, stop.direction = True, -float(mode)
    return [stop]
