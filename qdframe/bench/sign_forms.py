"""The peers' statement of each friction and sliding model, written once (the problem
catalogue, :mod:`.problems`, says which model has which).

Every model here is, in Filippov's sense,

    x' ∈ f(x) + Σ_j a_j(x)·Sgn(c_j(x)),

one switching function c_j per sign term (a term that appears in several equations is one
c_j with a vector a_j). A :class:`SignForm` holds f and the pairs (a_j, c_j) as functions of
the state's components, written with + − ×, abs() and :func:`sin` only, so the same form evaluates on
NumPy rows (solve_bvp's regularized right side, :mod:`.solve_bvp_peer`) and on CasADi symbols
(nosnoc's Stewart subsystems, :mod:`.nosnoc_peer`). The physics is the models' docstrings'
(friction −μ·Sgn(v); qdframe codes it as μ·Sgn(−v), the same set).

=======================  ===========================================================
block-stop-stick(-bvp)   p' = v,  v' ∈ −3·Sgn(v) + 1
block-breakaway          p' = v,  v' ∈ −1·Sgn(v) + 1·c,  c' = 1
slide-on-line,           x1' = x2,  x2' ∈ −2·Sgn(x1 + x2)
slide-after-reaching
two-surface-sliding      x1' ∈ 0.25 − Sgn(x1) − 0.5·Sgn(x2),  x2' ∈ −0.25 − Sgn(x2)
coulomb-block            p' = v,  v' ∈ (−μ·F_N·Sgn(v) + g)/m   (the instance's μ, F_N, g, m)
sliding-mode             x1' = x2,  x2' ∈ x1 − a·(|x1| + |x2|)·Sgn(a_s·x1 + x2)   (the instance's a, a_s)
stick-slip-oscillator    p' = v,  v' ∈ −p − 0.1·Sgn(v)
pivot-friction-pendulum  θ' = ω,  ω' ∈ −9.81·sin θ − 0.05·ω − 2·Sgn(ω)
two-block-chain          p1' = v1,  v1' ∈ −p1 + 3·(p2 − p1) − Sgn(v1),
                         p2' = v2,  v2' ∈ 1.5 − 3·(p2 − p1) − 0.5·Sgn(v2)
relay-oscillator         x1' = x2,  x2' ∈ −Sgn(x1)
=======================  ===========================================================

Constants come from :mod:`qdframe.models.friction` and :mod:`qdframe.models.user_friction`, or from the model instance where they
are its attributes (the qdframe-mechanics plugin's coulomb-block and sliding-mode).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..models import exact_friction as friction
from ..models import user_friction

Components = Sequence  # the state's components: NumPy rows or CasADi scalars


@dataclass(frozen=True)
class SignForm:
    """x' ∈ f(x) + Σ_j a_j(x)·Sgn(c_j(x)): `base` gives f's components, `terms` the pairs
    (a_j's components, c_j), both from the state's components."""

    base: Callable[[Components], list]
    terms: Callable[[Components], list[tuple[list, object]]]


def block_stop_stick(model) -> SignForm:
    mu, pull = friction.STOP_FRICTION, friction.STOP_PULL
    return SignForm(lambda x: [x[1], pull], lambda x: [([0.0, -mu], x[1])])


def block_breakaway(model) -> SignForm:
    mu, ramp = friction.BREAK_FRICTION, friction.BREAK_RAMP
    return SignForm(lambda x: [x[1], ramp * x[2], 1.0], lambda x: [([0.0, -mu, 0.0], x[1])])


def slide_on_line(model) -> SignForm:
    gain = friction.LINE_GAIN
    return SignForm(lambda x: [x[1], 0.0], lambda x: [([0.0, -gain], x[0] + x[1])])


def two_surface(model) -> SignForm:
    a1, a2, b = friction.TWO_A1, friction.TWO_A2, friction.TWO_B
    return SignForm(lambda x: [a1, a2], lambda x: [([-1.0, 0.0], x[0]), ([-b, -1.0], x[1])])


def coulomb_block(model) -> SignForm:
    _need(model)
    mass, mu, normal, pull = model.mass, model.mu, model.normal_force, model.pull
    return SignForm(lambda x: [x[1], pull / mass], lambda x: [([0.0, -mu * normal / mass], x[1])])


def sliding_mode(model) -> SignForm:
    _need(model)
    gain, slope = model.gain, model.slope
    return SignForm(lambda x: [x[1], x[0]],
                    lambda x: [([0.0, -gain * (abs(x[0]) + abs(x[1]))], slope * x[0] + x[1])])


def stick_slip(model) -> SignForm:
    mu = friction.OSC_FRICTION
    return SignForm(lambda x: [x[1], -x[0]], lambda x: [([0.0, -mu], x[1])])


def pendulum(model) -> SignForm:
    g, damping, mu = user_friction.PENDULUM_GRAVITY, user_friction.PENDULUM_DAMPING, user_friction.PENDULUM_FRICTION
    return SignForm(lambda x: [x[1], -g * sin(x[0]) - damping * x[1]], lambda x: [([0.0, -mu], x[1])])


def two_block_chain(model) -> SignForm:
    wall, link, pull = user_friction.CHAIN_WALL, user_friction.CHAIN_LINK, user_friction.CHAIN_PULL
    mu1, mu2 = user_friction.CHAIN_FRICTION

    def base(x):
        spring = link * (x[2] - x[0])
        return [x[1], -wall * x[0] + spring, x[3], pull - spring]

    return SignForm(base, lambda x: [([0.0, -mu1, 0.0, 0.0], x[1]), ([0.0, 0.0, 0.0, -mu2], x[3])])


def relay(model) -> SignForm:
    return SignForm(lambda x: [x[1], 0.0], lambda x: [([0.0, -1.0], x[0])])


def sin(value):
    """sin of a NumPy value or of a CasADi symbol (its own sin)."""
    return value.sin() if hasattr(value, "sin") else np.sin(value)


def _need(model) -> None:
    if model is None:
        raise InputError("model", "the model instance (its constants are its attributes)", None)
