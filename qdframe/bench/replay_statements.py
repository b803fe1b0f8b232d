"""Independent statements of qdframe's friction and sliding models: reference solutions for the benchmarks
(the problem catalogue, :mod:`.problems`, says which model has which).

Each model is written here by hand, from its equations (its parameters read from the model),
in the separable form

    x' ∈ g(t, x) − Σ_i a_i(t, x)·Sgn(c_i(x))·b_i,

b_i a constant vector, a_i ≥ 0 a gain, c_i a scalar switching function, and integrated by
the event-driven Filippov integrator (:func:`qdframe.certificates.filippov.integrate`: DOP853 between
events, rtol = atol = 1e-12, sliding by its equivalent control). Nothing of qdframe's model
layer or solver is used: these statements are the benchmark's second reading of each model.

:func:`.problems.statement` states a catalogue problem in this form,
:func:`.problems.reference` integrates it from its start over [0, T]. A model judged by
the motion its input drives recovers that input from a trajectory by one of the
functions at the end (:func:`coulomb_force`, :func:`sliding_inputs`, :func:`paper_control`).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..certificates.filippov import Fields, FilippovSystem

Input = Callable[[float], np.ndarray]


@dataclass(frozen=True)
class SignSwitch:
    """One sign term −a(t, x)·Sgn(c(x))·b of x': switch c, its gradient ∇c, direction b, gain a ≥ 0."""

    switch: Callable[[np.ndarray], float]
    gradient: Callable[[np.ndarray], np.ndarray]
    direction: np.ndarray
    gain: Callable[[float, np.ndarray], float]
    name: str = ""


def separable(drift: Callable[[float, np.ndarray], np.ndarray], switches: tuple[SignSwitch, ...], name: str = "",
              breaks: tuple[float, ...] = ()) -> FilippovSystem:
    """x' ∈ drift(t, x) − Σ_i gain_i(t, x)·Sgn(switch_i(x))·direction_i as a FilippovSystem
    (B's column i is −gain_i·direction_i)."""
    directions = np.stack([np.asarray(s.direction, dtype=float) for s in switches], axis=1)

    def fields(t: float, x: np.ndarray) -> Fields:
        gains = np.array([float(s.gain(t, x)) for s in switches])
        return Fields(np.asarray(drift(t, x), dtype=float), -directions * gains,
                      np.array([float(s.switch(x)) for s in switches]),
                      np.stack([np.asarray(s.gradient(x), dtype=float) for s in switches]))

    return FilippovSystem(fields, tuple(s.name for s in switches), name, breaks)


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


def block_stop_stick(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    pull, friction = k["STOP_PULL"], k["STOP_FRICTION"]
    return separable(lambda t, x: np.array([x[1], pull]),
                     (_coordinate_switch(1, 2, _constant(friction), "μg·Sgn(v)"),), model.name)


def block_breakaway(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    ramp, friction = k["BREAK_RAMP"], k["BREAK_FRICTION"]
    return separable(lambda t, x: np.array([x[1], ramp * x[2], 1.0]),
                          (_coordinate_switch(1, 3, _constant(friction), "μg·Sgn(v)"),), model.name)


def slide_on_line(model, inputs: Input | None) -> FilippovSystem:
    gain = _constants(model)["LINE_GAIN"]
    surface = SignSwitch(lambda x: x[0] + x[1], lambda x: np.array([1.0, 1.0]), _unit(1, 2), _constant(gain),
                         "a·Sgn(x1 + x2)")
    return separable(lambda t, x: np.array([x[1], 0.0]), (surface,), model.name)


def two_surface(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    a1, a2, b = k["TWO_A1"], k["TWO_A2"], k["TWO_B"]
    return separable(lambda t, x: np.array([a1, a2]),
                          (_coordinate_switch(0, 2, _constant(1.0), "Sgn(x1)"),
                           _coordinate_switch(1, 2, _constant(1.0), "Sgn(x2)", np.array([b, 1.0]))), model.name)


def stick_slip_oscillator(model, inputs: Input | None) -> FilippovSystem:
    friction = _constants(model)["OSC_FRICTION"]
    return separable(lambda t, x: np.array([x[1], -x[0]]),
                          (_coordinate_switch(1, 2, _constant(friction), "μ·Sgn(v)"),), model.name)


def coulomb_block(model, inputs: Input | None) -> FilippovSystem:
    pull, gain = model.pull / model.mass, model.mu * model.normal_force / model.mass
    return separable(lambda t, x: np.array([x[1], pull]),
                          (_coordinate_switch(1, 2, _constant(gain), "μ·F_N·Sgn(v)/m"),), model.name)


def sliding_mode(model, inputs: Input | None) -> FilippovSystem:
    slope, gain = model.slope, model.gain
    surface = SignSwitch(lambda x: slope * x[0] + x[1], lambda x: np.array([slope, 1.0]), _unit(1, 2),
                         lambda _t, x: gain * (abs(x[0]) + abs(x[1])), "a·|x|·Sgn(s)")
    return separable(lambda t, x: np.array([x[1], x[0]]), (surface,), model.name)


def coulomb_rest_to_rest(model, inputs: Input | None) -> FilippovSystem | None:
    if inputs is None:
        return None
    u = _input(inputs, 1)
    return separable(lambda t, x: np.array([x[1], u(t)[0]]),
                          (_coordinate_switch(1, 2, _constant(model.friction), "F·Sgn(v)"),), model.name)


def sliding_mode_terminal(model, inputs: Input | None) -> FilippovSystem | None:
    if inputs is None:
        return None
    k = _constants(model)
    a, b = k["SLIDING_A"], k["SLIDING_B"]
    w = _input(inputs, 2)
    c1 = SignSwitch(lambda x: x[0] + a * x[1] ** 2, lambda x: np.array([1.0, 2 * a * x[1], 0.0, 0.0]), _unit(0, 4),
                    _constant(1.0), "Sgn(c1)")
    c2 = SignSwitch(lambda x: x[1] + b * x[0] ** 3, lambda x: np.array([3 * b * x[0] ** 2, 1.0, 0.0, 0.0]),
                    _unit(1, 4), _constant(1.0), "Sgn(c2)")
    return separable(lambda t, x: np.concatenate([x[2:4], w(t)]), (c1, c2), model.name)


def paper_73(model, inputs: Input | None) -> FilippovSystem | None:
    if inputs is None:
        return None
    k = _constants(model)
    gain, friction = k["GAIN"], k["FRICTION"]
    u = _input(inputs, 1)

    def drift(t: float, x: np.ndarray) -> np.ndarray:
        x1, x2, x3, x4, x5, x6 = x
        return np.array([x4, x5, x6, -2 * x1 + x2 - x4, x1 - 2 * x2 + x3 - x5, x2 - x3 - x6 + u(t)[0]])

    return separable(drift, (_coordinate_switch(3, 6, lambda _t, x: gain * float(np.sum(np.abs(x))), "1.05|x|Sgn(x4)"),
                                  _coordinate_switch(4, 6, _constant(friction), "0.3 Sgn(x5)"),
                                  _coordinate_switch(5, 6, _constant(friction), "0.3 Sgn(x6)")),
                          model.name)


# ------------------------------------------------------------------ inputs from a trajectory
RESTING = 1e-7  # |v| below this counts as v = 0 when an input is recovered from a trajectory (10× the residual tolerance: a solved block at rest has |v| up to ~1e-8)


def coulomb_force(x, z, u, model, selections=None) -> np.ndarray | list[np.ndarray]:
    """v' = u − F·σ with σ ∈ Sgn(v): u = clip(z_v + F·σ, ±U), σ the trajectory's own
    selection where it gives one (the model's term is F·λ with λ ∈ Sgn(−v): σ = −λ), else
    sign(v), 0 at rest (at rest any |u| ≤ F keeps the block there, and u = z_v = 0 says so).
    Without selections the point where the block comes to rest is undetermined: its z_v may
    be the deceleration of the interval that ends there (σ the sign before it) or already
    the rest's (σ = 0, where the block stops between two points): both candidates."""
    def force(sign: np.ndarray) -> np.ndarray:
        return np.clip(z[:, 1] + model.friction * sign, -model.force_bound, model.force_bound)[:, None]

    if selections is not None:
        return force(-np.asarray(selections, float)[:, 0])
    velocity = x[:, 1]
    rest = np.where(np.abs(velocity) <= RESTING, 0.0, np.sign(velocity))
    stops = np.flatnonzero((rest[1:] == 0.0) & (rest[:-1] != 0.0)) + 1
    keep = rest.copy()
    keep[stops] = rest[stops - 1]
    return [force(keep), force(rest)] if stops.size else force(rest)


def sliding_inputs(x, z, u, model, selections=None) -> np.ndarray:
    """v' = w with |w_i| ≤ 10: w = clip(z_v, ±10)."""
    return np.clip(z[:, 2:4], -model.input_bound, model.input_bound)


def paper_control(x, z, u, model, selections=None) -> np.ndarray:
    """Example 7.3's control u, a column of the trajectory itself."""
    if u is None or np.size(u) == 0:
        raise ValueError("paper-7.3: a trajectory without its control u cannot be replayed")
    return np.asarray(u, float)
