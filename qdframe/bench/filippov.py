"""Independent statements of qdframe's friction and sliding models: reference solutions for the benchmarks.

Each model is written here by hand, from its equations (its parameters read from the model),
in the separable form

    x' ∈ g(t, x) − Σ_i a_i(t, x)·Sgn(c_i(x))·b_i,

b_i a constant vector, a_i ≥ 0 a gain, c_i a scalar switching function, and integrated by
the event-driven Filippov integrator (:func:`qdframe.filippov.integrate`: DOP853 between
events, rtol = atol = 1e-12, sliding by its equivalent control). Nothing of qdframe's model
layer or solver is used: these statements are the benchmark's second reading of each model.

:func:`statement` writes the models in this form, :func:`reference` integrates them from
their start over [0, T].
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ..filippov import FilippovError, Fields, FilippovSystem, FilippovTrajectory, integrate

__all__ = ["FilippovError", "FilippovSystem", "FilippovTrajectory", "SignSwitch", "integrate", "reference",
           "separable", "start", "statement"]

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


def _block_stop_stick(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    pull, friction = k["STOP_PULL"], k["STOP_FRICTION"]
    return separable(lambda t, x: np.array([x[1], pull]),
                     (_coordinate_switch(1, 2, _constant(friction), "μg·Sgn(v)"),), model.name)


def _block_breakaway(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    ramp, friction = k["BREAK_RAMP"], k["BREAK_FRICTION"]
    return separable(lambda t, x: np.array([x[1], ramp * x[2], 1.0]),
                          (_coordinate_switch(1, 3, _constant(friction), "μg·Sgn(v)"),), model.name)


def _slide_on_line(model, inputs: Input | None) -> FilippovSystem:
    gain = _constants(model)["LINE_GAIN"]
    surface = SignSwitch(lambda x: x[0] + x[1], lambda x: np.array([1.0, 1.0]), _unit(1, 2), _constant(gain),
                         "a·Sgn(x1 + x2)")
    return separable(lambda t, x: np.array([x[1], 0.0]), (surface,), model.name)


def _two_surface(model, inputs: Input | None) -> FilippovSystem:
    k = _constants(model)
    a1, a2, b = k["TWO_A1"], k["TWO_A2"], k["TWO_B"]
    return separable(lambda t, x: np.array([a1, a2]),
                          (_coordinate_switch(0, 2, _constant(1.0), "Sgn(x1)"),
                           _coordinate_switch(1, 2, _constant(1.0), "Sgn(x2)", np.array([b, 1.0]))), model.name)


def _stick_slip_oscillator(model, inputs: Input | None) -> FilippovSystem:
    friction = _constants(model)["OSC_FRICTION"]
    return separable(lambda t, x: np.array([x[1], -x[0]]),
                          (_coordinate_switch(1, 2, _constant(friction), "μ·Sgn(v)"),), model.name)


def _coulomb_block(model, inputs: Input | None) -> FilippovSystem:
    pull, gain = model.pull / model.mass, model.mu * model.normal_force / model.mass
    return separable(lambda t, x: np.array([x[1], pull]),
                          (_coordinate_switch(1, 2, _constant(gain), "μ·F_N·Sgn(v)/m"),), model.name)


def _sliding_mode(model, inputs: Input | None) -> FilippovSystem:
    slope, gain = model.slope, model.gain
    surface = SignSwitch(lambda x: slope * x[0] + x[1], lambda x: np.array([slope, 1.0]), _unit(1, 2),
                         lambda _t, x: gain * (abs(x[0]) + abs(x[1])), "a·|x|·Sgn(s)")
    return separable(lambda t, x: np.array([x[1], x[0]]), (surface,), model.name)


def _coulomb_rest_to_rest(model, inputs: Input | None) -> FilippovSystem | None:
    if inputs is None:
        return None
    u = _input(inputs, 1)
    return separable(lambda t, x: np.array([x[1], u(t)[0]]),
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
    return separable(lambda t, x: np.concatenate([x[2:4], w(t)]), (c1, c2), model.name)


def _paper_73(model, inputs: Input | None) -> FilippovSystem | None:
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
