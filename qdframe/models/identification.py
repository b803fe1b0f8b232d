"""Problems whose end time or coefficients are unknown (:mod:`qdframe.unknowns`), with exact answers.

==========================  ===============================================================
model                       what is found
==========================  ===============================================================
block-stopping-time         when a Coulomb block thrown at v = 2 (deceleration 2) reaches
                            p = 0.75: T* = 0.5 (guess T = 1)
relay-period                the period of the relay oscillator x1' = x2, x2' ∈ −Sgn(x1)
                            through (1, 0): T* = 4√2 (guess T = 5)
block-friction-coefficient  the friction coefficient μ that stops a block thrown at v = 2
                            at p = 1 (it sticks from t = 1 to T = 1.5): μ* = 2 (guess 1)
block-time-optimal          the shortest time to move a Coulomb block (friction 1) by a
                            force |u| ≤ 2 from rest at 0 to rest at 1: T* = (4/3)·√1.5,
                            full force forward until t = √1.5, then full force back (a cost
                            ∫1 dt = T, :mod:`qdframe.solve.optimum`; guess T = 2)
==========================  ===============================================================

Each one's ``exact_solution(t)`` is the closed form at the true T and coefficients, at the
user's times t; ``exact_T`` and ``exact_parameters`` are the true values.
"""

from __future__ import annotations

import numpy as np

from ..sets import Interval, SetModel, Sgn


class _Known(SetModel):
    """A model with the closed form `motion(t)` for its default data."""

    def motion(self, t: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def exact_solution(self, t: np.ndarray) -> np.ndarray | None:
        default = (np.array_equal(self.x0, self.default_x0) and np.array_equal(self.end_values, self.default_end_values)
                   and (self.free_T or self.T == self.default_T))
        return self.motion(np.asarray(t, dtype=float)) if default else None


def _braking(t: np.ndarray, v0: float, rate: float) -> np.ndarray:
    """p, v of a block from (0, v0) decelerated at `rate` until it stops, then stuck."""
    stop = v0 / rate
    moving = np.minimum(t, stop)
    return np.stack([v0 * moving - rate * moving**2 / 2, v0 - rate * moving], axis=1)


class BlockStoppingTime(_Known):
    """A Coulomb block thrown at v = 2 with deceleration 2 (p' = v, v' ∈ −2 Sgn(v)): when does
    it reach p = 0.75? T free, guessed 1; T* = 0.5."""

    name = "block-stopping-time"
    description = "When a Coulomb block thrown at v = 2 (v' ∈ −2 Sgn(v)) reaches p = 0.75: T free, T* = 0.5"
    state_names = "p v"
    default_x0 = (0.0, 2.0)
    default_xT = {"p": 0.75}
    default_T = 1.0
    free_T = True
    exact_T = 0.5

    def sets(self, p, v):
        return {p: v, v: -2 * Sgn(v)}

    def motion(self, t: np.ndarray) -> np.ndarray:
        return _braking(t, 2.0, 2.0)


class RelayPeriod(_Known):
    """The period of the relay oscillator x1' = x2, x2' ∈ −Sgn(x1) through (1, 0): periodic
    in both states, T free, guessed 5; T* = 4√2."""

    name = "relay-period"
    description = "The period of the relay oscillator x1' = x2, x2' ∈ −Sgn(x1) through (1, 0): T* = 4√2 (guess 5)"
    state_names = "x1 x2"
    default_x0 = (1.0, 0.0)
    periodic = (0, 1)
    default_T = 5.0
    free_T = True
    exact_T = 4 * np.sqrt(2.0)

    def sets(self, x1, x2):
        return {x1: x2, x2: -Sgn(x1)}

    def motion(self, t: np.ndarray) -> np.ndarray:
        """Parabolas: x2' = −1 while x1 > 0, +1 while x1 < 0; crossings at √2·(1, 3, 5, …)."""
        quarter = np.sqrt(2.0)
        phase = np.mod(t - quarter, 4 * quarter)  # 0 at a downward crossing (x1 = 0, x2 = −√2)
        left = phase < 2 * quarter  # x1 < 0: x2 = −√2 + τ
        tau = np.where(left, phase, phase - 2 * quarter)
        x2 = np.where(left, -quarter + tau, quarter - tau)
        x1 = np.where(left, -quarter * tau + tau**2 / 2, quarter * tau - tau**2 / 2)
        return np.stack([x1, x2], axis=1)


class BlockFrictionCoefficient(_Known):
    """Which friction coefficient μ stops a block thrown at v = 2 at p = 1? p' = v,
    v' ∈ −μ Sgn(v), T = 1.5, p(T) = 1: μ unknown in (0, ∞), guessed 1; μ* = 2 (it stops at
    t = 1 and sticks)."""

    name = "block-friction-coefficient"
    description = "The friction coefficient μ that stops a block thrown at v = 2 at p = 1 by T = 1.5: μ* = 2 (guess 1)"
    state_names = "p v"
    parameter_names = "mu"
    default_parameters = (1.0,)
    parameter_bounds = {"mu": (0.0, np.inf)}
    default_x0 = (0.0, 2.0)
    default_xT = {"p": 1.0}
    default_T = 1.5
    exact_parameters = {"mu": 2.0}

    def sets(self, p, v, mu):
        return {p: v, v: -mu * Sgn(v)}

    def motion(self, t: np.ndarray) -> np.ndarray:
        return _braking(t, 2.0, 2.0)


class BlockTimeOptimal(_Known):
    """The shortest time to move a Coulomb block from rest at 0 to rest at 1 with a force
    |u| ≤ 2 (p' = v, v' ∈ [−2, 2] − Sgn(v)): T free, the cost ∫1 dt = T. Bang-bang: v' = 1
    until t₁ = √1.5, then v' = −3 until T* = (4/3)·t₁, where v = 0 and p = 1."""

    name = "block-time-optimal"
    description = "The shortest time to move a Coulomb block by |u| ≤ 2 from rest at 0 to rest at 1: T* = (4/3)·√1.5"
    state_names = "p v"
    default_x0 = (0.0, 0.0)
    default_xT = {"p": 1.0, "v": 0.0}
    default_T = 2.0
    free_T = True
    exact_T = 4 / 3 * np.sqrt(1.5)
    exact_cost = exact_T  # the cost is the time

    def sets(self, p, v):
        return {p: v, v: Interval(-2, 2) - Sgn(v)}

    def running_cost(self, p, v):
        return 1.0 + 0 * p  # ∫1 dt: the time

    def motion(self, t: np.ndarray) -> np.ndarray:
        switch = np.sqrt(1.5)
        ahead, back = np.minimum(t, switch), np.maximum(t - switch, 0.0)
        return np.stack([ahead**2 / 2 + switch * back - 1.5 * back**2, ahead - 3 * back], axis=1)
