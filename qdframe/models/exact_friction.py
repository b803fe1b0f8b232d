"""Filippov test problems (dry friction, sliding modes) with exact closed-form solutions.

Each model is a plain initial-value (or two-point) problem as a user would pose it:
the Filippov sign terms a·Sgn(s) carry the default band, and no sliding surface is
declared: where the exact solution sticks or slides, the solver has to find the
Filippov selection λ ∈ Sgn(0) = [−1, 1] itself. The horizons do not end at a switch
time, so every stick or sliding phase is a real part of the interval.

A sign term a·Sgn(s) needs a ≥ 0, so a friction force −μg·Sgn(v) is coded as
μg·Sgn(−v), and so on. `exact_multipliers(t)` gives the selection of the CODED
switches, (N, k), one column per distinct switch in the order they first appear in
`blocks()`: λ_j = sign(s_j) off the surface, the equivalent control on it.

========================  ====================================================  ==========================
model                     exact solution (default data)                         switch times
========================  ====================================================  ==========================
block-stop-stick          p = 2t − t², v = 2 − 2t; p ≡ 1, v ≡ 0 for t ≥ 1         (1,)
block-stop-stick-bvp      the same, with p(3) = 1 imposed                       (1,)
block-breakaway           p = v = 0 for t ≤ 1; v = (t−1)²/2, p = (t−1)³/6, c = t  (1,)
slide-on-line             x1 = e^{−t}, x2 = −e^{−t} (on s = x1 + x2 = 0)          ()
slide-after-reaching      x1 = 1 − t², x2 = −2t; then x1 = −x2 = 2r·e^{−(t−r)}   (r,) r = √2 − 1
two-surface-sliding       piecewise linear, x2 ≡ 0 after 0.4, x1 ≡ 0 after 1.04  (0.4, 1.04)
stick-slip-oscillator     arcs p = ±μ + r_k·cos(t − kπ); p ≡ 0 after 25π        (π, 2π, …, 25π)
========================  ====================================================  ==========================
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from ..ready_pieces import affine, constant, coordinate
from ..model import InclusionModel, SetBlock, SignTerm


def _times(t: np.ndarray) -> np.ndarray:
    return np.atleast_1d(np.asarray(t, dtype=float))


class _ExactModel(InclusionModel):
    """A model whose `motion(t)` is the exact Filippov solution for the default data."""

    switch_times: ClassVar[tuple[float, ...]] = ()

    def motion(self, t: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def multipliers(self, t: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def is_default(self) -> bool:
        return (
            self.T == self.default_T
            and np.array_equal(self.x0, self.default_x0, equal_nan=True)
            and np.array_equal(self.end_values, np.asarray(self.default_end_values, dtype=float))
        )

    def exact_solution(self, t: np.ndarray) -> np.ndarray | None:
        return self.motion(t) if self.is_default() else None

    def exact_multipliers(self, t: np.ndarray) -> np.ndarray | None:
        """λ (N, k) of the coded switches along the exact solution, or None off the defaults."""
        return self.multipliers(t) if self.is_default() else None


# ------------------------------------------------------------------ block-stop-stick
STOP_FRICTION, STOP_PULL, STOP_V0 = 3.0, 1.0, 2.0  # μg, f, v(0)
STOP_DECELERATION = STOP_FRICTION - STOP_PULL  # 2
STOP_TIME = STOP_V0 / STOP_DECELERATION  # 1


def block_stop_stick_motion(t: np.ndarray) -> np.ndarray:
    """(p, v): v = v0 − a·t, p = v0·t − a·t²/2 until v = 0 at t = v0/a, then at rest (|f| < μg)."""
    s = np.minimum(_times(t), STOP_TIME)
    return np.stack([STOP_V0 * s - 0.5 * STOP_DECELERATION * s**2, STOP_V0 - STOP_DECELERATION * s], axis=1)


class BlockStopStick(_ExactModel):
    """A sliding block decelerated by Coulomb friction against a pull, coming to rest and sticking.

        p' = v,   v' ∈ −μg·Sgn(v) + f,   μg = 3, f = 1,   x(0) = (0, 2),   T = 3.

    Exact Filippov solution: v = 2 − 2t, p = 2t − t² for t ≤ 1; at t = 1 the block stops
    and sticks, v ≡ 0, p ≡ 1 for 1 ≤ t ≤ 3, since |f| < μg: the selection is
    Sgn(v) ∋ λ_v = f/μg = 1/3 (coded switch s = −v: λ = −1 sliding, −1/3 sticking).
    """

    name = "block-stop-stick"
    description = "Coulomb block v' ∈ −3·Sgn(v) + 1 from v = 2: stops at t = 1 and sticks until T = 3"
    state_names = ("position", "velocity")
    default_T = 3.0
    default_x0 = (0.0, STOP_V0)
    switch_times = (STOP_TIME,)

    def blocks(self) -> tuple[SetBlock, ...]:
        return (
            SetBlock.equation(0, coordinate(1, 2), "p' = v"),
            SetBlock.equation(1, constant(STOP_PULL, 2), "v' ∈ −μg·Sgn(v) + f",
                              (SignTerm(STOP_FRICTION, affine({1: -1.0}, 2), name="μg·Sgn(−v)"),)),
        )

    def motion(self, t: np.ndarray) -> np.ndarray:
        return block_stop_stick_motion(t)

    def multipliers(self, t: np.ndarray) -> np.ndarray:
        return np.where(_times(t) < STOP_TIME, -1.0, -STOP_PULL / STOP_FRICTION)[:, None]


class BlockStopStickBVP(BlockStopStick):
    """:class:`BlockStopStick` as a two-point problem: v(0) = 2 and p(3) = 1 given, p(0) free.

    The exact solution is the same: the block stops at t = 1 after travelling 1 and sticks,
    so p(3) = 1 gives p(0) = 0 (a given x(0) and p(3) would fix p twice).
    """

    name = "block-stop-stick-bvp"
    description = "Coulomb block v' ∈ −3·Sgn(v) + 1, v(0) = 2, p(3) = 1, p(0) free: stops at t = 1 and sticks"
    default_x0 = (float("nan"), STOP_V0)
    end_indices = (0,)
    default_end_values = (1.0,)


# ------------------------------------------------------------------- block-breakaway
BREAK_FRICTION, BREAK_RAMP = 1.0, 1.0  # μg, k
BREAK_TIME = BREAK_FRICTION / BREAK_RAMP  # 1


def breakaway_motion(t: np.ndarray) -> np.ndarray:
    """(p, v, c): at rest while k·t ≤ μg, then v = k(t − t_b)²/2, p = k(t − t_b)³/6; c = t."""
    t = _times(t)
    w = np.maximum(t - BREAK_TIME, 0.0)
    return np.stack([BREAK_RAMP * w**3 / 6, BREAK_RAMP * w**2 / 2, t], axis=1)


class BlockBreakaway(_ExactModel):
    """A block at rest under a ramped pull f = k·t: sticks until the pull exceeds friction.

        p' = v,   v' ∈ −μg·Sgn(v) + k·c,   c' = 1,   μg = k = 1,   x(0) = (0, 0, 0),   T = 2.2.

    The clock c = t makes the ramp autonomous. Exact Filippov solution: v ≡ 0, p ≡ 0 for
    t ≤ 1 (the selection λ_v = c/μg = t ∈ [0, 1] of Sgn(0)); breakaway at t = 1, then
    v' = t − 1: v = (t − 1)²/2, p = (t − 1)³/6. Coded switch s = −v: λ = −t, then −1.
    """

    name = "block-breakaway"
    description = "Block at rest, pull f = t against friction 1: sticks until t = 1, then v = (t−1)²/2"
    state_names = ("position", "velocity", "clock")
    default_T = 2.2  # no switch on a node of N = 101, 1001, 10001 (h = 0.022, ...)
    default_x0 = (0.0, 0.0, 0.0)
    switch_times = (BREAK_TIME,)

    def blocks(self) -> tuple[SetBlock, ...]:
        return (
            SetBlock.equation(0, coordinate(1, 3), "p' = v"),
            SetBlock.equation(1, affine({2: BREAK_RAMP}, 3), "v' ∈ −μg·Sgn(v) + k·c",
                              (SignTerm(BREAK_FRICTION, affine({1: -1.0}, 3), name="μg·Sgn(−v)"),)),
            SetBlock.equation(2, constant(1.0, 3), "c' = 1"),
        )

    def motion(self, t: np.ndarray) -> np.ndarray:
        return breakaway_motion(t)

    def multipliers(self, t: np.ndarray) -> np.ndarray:
        return -np.minimum(BREAK_RAMP * _times(t) / BREAK_FRICTION, 1.0)[:, None]


# ---------------------------------------------------- slide-on-line, slide-after-reaching
LINE_GAIN = 2.0  # a
REACH_X0 = (1.0, 0.0)
REACH_TIME = float(np.sqrt(2.0) - 1.0)  # root of s = 1 − 2t − t²


def slide_on_line_motion(t: np.ndarray) -> np.ndarray:
    """(x1, x2) = (e^{−t}, −e^{−t}): the sliding motion on x1 + x2 = 0 from (1, −1)."""
    decay = np.exp(-_times(t))
    return np.stack([decay, -decay], axis=1)


def slide_after_reaching_motion(t: np.ndarray) -> np.ndarray:
    """(x1, x2) from (1, 0): x1 = 1 − t², x2 = −2t until s = x1 + x2 = 0 at r = √2 − 1
    (where x1 = −x2 = 2r), then sliding x1 = −x2 = 2r·e^{−(t − r)}."""
    t = _times(t)
    before = np.minimum(t, REACH_TIME)
    sliding = 2 * REACH_TIME * np.exp(-(t - REACH_TIME))
    x1 = np.where(t < REACH_TIME, 1.0 - before**2, sliding)
    x2 = np.where(t < REACH_TIME, -LINE_GAIN * before, -sliding)
    return np.stack([x1, x2], axis=1)


class SlideOnLine(_ExactModel):
    """The double integrator under a relay on s = x1 + x2, started on the surface.

        x1' = x2,   x2' ∈ −a·Sgn(x1 + x2),   a = 2,   x(0) = (1, −1),   T = 2.

    Both fields point at s = 0 while |x2| < a (s' = x2 ∓ a), so the motion slides:
    x1 = e^{−t}, x2 = −e^{−t}. Equivalent control: Sgn(s) ∋ λ_eq = x2/a = −e^{−t}/2,
    inside (−1, 1) (coded switch −s: λ = e^{−t}/2).
    """

    name = "slide-on-line"
    description = "x1' = x2, x2' ∈ −2·Sgn(x1 + x2) from (1, −1): slides on x1 + x2 = 0, x1 = e^{−t}"
    state_names = ("x1", "x2")
    default_T = 2.0
    default_x0 = (1.0, -1.0)

    def blocks(self) -> tuple[SetBlock, ...]:
        return (
            SetBlock.equation(0, coordinate(1, 2), "x1' = x2"),
            SetBlock.equation(1, constant(0.0, 2), "x2' ∈ −a·Sgn(x1 + x2)",
                              (SignTerm(LINE_GAIN, affine({0: -1.0, 1: -1.0}, 2), name="a·Sgn(−x1 − x2)"),)),
        )

    def motion(self, t: np.ndarray) -> np.ndarray:
        return slide_on_line_motion(t)

    def multipliers(self, t: np.ndarray) -> np.ndarray:
        return (np.exp(-_times(t)) / LINE_GAIN)[:, None]


class SlideAfterReaching(SlideOnLine):
    """:class:`SlideOnLine` started off the surface at x(0) = (1, 0), s(0) = 1.

    Reaching phase x2' = −2: x1 = 1 − t², x2 = −2t, s = 1 − 2t − t², reaching s = 0 at
    r = √2 − 1 ≈ 0.4142 with x = (2r, −2r), |x2| < a. Then it slides: x1 = −x2 =
    2r·e^{−(t − r)}, λ_eq = x2/a = −r·e^{−(t − r)} (coded switch −s: λ = −1, then +r·e^{−(t−r)}).
    """

    name = "slide-after-reaching"
    description = "x1' = x2, x2' ∈ −2·Sgn(x1 + x2) from (1, 0): reaches x1 + x2 = 0 at √2 − 1, then slides"
    default_x0 = REACH_X0
    switch_times = (REACH_TIME,)

    def motion(self, t: np.ndarray) -> np.ndarray:
        return slide_after_reaching_motion(t)

    def multipliers(self, t: np.ndarray) -> np.ndarray:
        t = _times(t)
        return np.where(t < REACH_TIME, -1.0, REACH_TIME * np.exp(-(t - REACH_TIME)))[:, None]


# ---------------------------------------------------------------- two-surface-sliding
TWO_A1, TWO_A2, TWO_B = 0.25, -0.25, 0.5
TWO_X0 = (0.5, -0.3)
TWO_REACH2 = -TWO_X0[1] / (1.0 + TWO_A2)  # x2' = a2 + 1 = 0.75 while x2 < 0: 0.4
TWO_X1_AT_REACH2 = TWO_X0[0] + (TWO_A1 - 1.0 + TWO_B) * TWO_REACH2  # x1' = a1 − 1 + b = −0.25: 0.4
TWO_SLIDE2_RATE = TWO_A1 - 1.0 - TWO_B * TWO_A2  # x1' on x2 = 0 (λ2 = a2): −0.625
TWO_REACH1 = TWO_REACH2 - TWO_X1_AT_REACH2 / TWO_SLIDE2_RATE  # 1.04


def two_surface_motion(t: np.ndarray) -> np.ndarray:
    """(x1, x2): piecewise linear, x2 reaches 0 at 0.4 and stays; x1 reaches 0 at 1.04 and stays."""
    t = _times(t)
    x2 = np.minimum(TWO_X0[1] + (1.0 + TWO_A2) * t, 0.0)
    first = TWO_X0[0] + (TWO_A1 - 1.0 + TWO_B) * t
    second = np.maximum(TWO_X1_AT_REACH2 + TWO_SLIDE2_RATE * (t - TWO_REACH2), 0.0)
    return np.stack([np.where(t < TWO_REACH2, first, second), x2], axis=1)


class TwoSurfaceSliding(_ExactModel):
    """Two relays coupled through the sign of x2, sliding on x2 = 0 and then on x1 = x2 = 0.

        x1' ∈ a1 − Sgn(x1) − b·Sgn(x2),   x2' ∈ a2 − Sgn(x2),
        a1 = 0.25, a2 = −0.25, b = 0.5,   x(0) = (0.5, −0.3),   T = 2.2.

    Exact Filippov solution (Sgn(x2) ∋ λ2, Sgn(x1) ∋ λ1):
      t ≤ 0.4:         x2' = 0.75, x1' = −0.25 (λ1 = 1, λ2 = −1); x(0.4) = (0.4, 0);
      0.4 ≤ t ≤ 1.04:  sliding on x2 = 0 with λ2 = a2 = −0.25, x1' = −0.625; x1(1.04) = 0;
      t ≥ 1.04:        sliding on x1 = x2 = 0 with λ2 = −0.25, λ1 = a1 − b·λ2 = 0.375.
    Both surfaces attract (x2' = a2 ∓ 1, x1' = a1 − bλ2 ∓ 1 on their two sides), so the
    solution is unique. Filippov's hull of the four neighbouring fields equals the sum of
    the sign intervals here (the field is affine in the signs). Coded switches −x1, −x2:
    λ = (−λ1, −λ2).
    """

    name = "two-surface-sliding"
    description = "x1' ∈ 0.25 − Sgn(x1) − 0.5·Sgn(x2), x2' ∈ −0.25 − Sgn(x2): slides on x2 = 0, then x1 = x2 = 0"
    state_names = ("x1", "x2")
    default_T = 2.2  # no switch on a node of N = 101, 1001, 10001 (h = 0.022, ...)
    default_x0 = TWO_X0
    switch_times = (TWO_REACH2, TWO_REACH1)

    def blocks(self) -> tuple[SetBlock, ...]:
        minus_x1, minus_x2 = affine({0: -1.0}, 2), affine({1: -1.0}, 2)  # x2's switch shared by both
        return (
            SetBlock.equation(0, constant(TWO_A1, 2), "x1' ∈ a1 − Sgn(x1) − b·Sgn(x2)",
                              (SignTerm(1.0, minus_x1, name="Sgn(−x1)"), SignTerm(TWO_B, minus_x2, name="b·Sgn(−x2)"))),
            SetBlock.equation(1, constant(TWO_A2, 2), "x2' ∈ a2 − Sgn(x2)",
                              (SignTerm(1.0, minus_x2, name="Sgn(−x2)"),)),
        )

    def motion(self, t: np.ndarray) -> np.ndarray:
        return two_surface_motion(t)

    def multipliers(self, t: np.ndarray) -> np.ndarray:
        t = _times(t)
        lambda1 = np.where(t < TWO_REACH1, 1.0, TWO_A1 - TWO_B * TWO_A2)
        lambda2 = np.where(t < TWO_REACH2, -1.0, TWO_A2)
        return -np.stack([lambda1, lambda2], axis=1)


# ------------------------------------------------------------- stick-slip-oscillator
OSC_FRICTION, OSC_P0, OSC_T = 0.1, 5.0, 100.0  # μ, p(0), T


def _oscillator_stop_count(p0: float = OSC_P0, mu: float = OSC_FRICTION) -> int:
    """K, the first k with |p_k| = |p0| − 2μk ≤ μ: the turning point where the mass stays stuck."""
    return max(int(np.ceil((abs(p0) - mu) / (2 * mu) - 1e-9)), 0)


OSC_STOP_COUNT = _oscillator_stop_count()  # 25: |p_25| = 0
OSC_STOP_TIME = OSC_STOP_COUNT * np.pi  # 25π ≈ 78.54


def _oscillator_turning_points(k: np.ndarray) -> np.ndarray:
    """p_k = (−1)^k·(p0 − 2μk): each half cycle shortens the swing by 2μ."""
    return np.where(k % 2 == 0, 1.0, -1.0) * (OSC_P0 - 2 * OSC_FRICTION * k)


def stick_slip_oscillator_motion(t: np.ndarray) -> np.ndarray:
    """(p, v) of p'' ∈ −p − μ·Sgn(p') from (p0, 0), p0 > μ.

    Arc k (kπ ≤ t ≤ (k + 1)π, k < K) starts at rest at p_k and moves against p_k's sign,
    friction pushing back, so it is harmonic about c_k = μ·sign(p_k):
        p = c_k + r_k·cos(t − kπ),   v = −r_k·sin(t − kπ),   r_k = p_k − c_k = (−1)^k(p0 − μ − 2μk),
    ending at rest at p_{k+1} = c_k − r_k = −p_k + 2μ·sign(p_k). From t = Kπ the mass is stuck at p_K.
    """
    t = _times(t)
    k = np.clip(np.floor(t / np.pi), 0, OSC_STOP_COUNT).astype(int)
    start = _oscillator_turning_points(k)
    radius = start - OSC_FRICTION * np.sign(start)
    phase = t - k * np.pi
    moving = k < OSC_STOP_COUNT
    p = np.where(moving, start - radius + radius * np.cos(phase), start)
    v = np.where(moving, -radius * np.sin(phase), 0.0)
    return np.stack([p, v], axis=1)


class StickSlipOscillator(_ExactModel):
    """A mass on a spring with Coulomb friction: decaying stick-slip swings, then stuck for good.

        p' = v,   v' ∈ −p − μ·Sgn(v),   μ = 0.1,   x(0) = (5, 0),   T = 100.

    The start is a release: at rest with |p| = 5 > μ the spring beats friction (Sgn(0)
    would need λ = −p/μ = −50). Each half cycle is a harmonic arc of length π about ±μ
    (see :func:`stick_slip_oscillator_motion`), the turning points p_k = (−1)^k(5 − 0.2k)
    shrinking by 2μ. At a turning point the mass stays stuck iff |p_k| ≤ μ: p_24 = 0.2
    is a reversal, p_25 = 0 at t = 25π ≈ 78.54 a stop, stuck until T = 100 (λ = p_25/μ = 0).
    Switch times: the 24 reversals kπ and the stop 25π. Coded switch s = −v:
    λ = (−1)^k on arc k, then p_25/μ.
    """

    name = "stick-slip-oscillator"
    description = "Spring-mass v' ∈ −p − 0.1·Sgn(v) from p = 5: 24 reversals at kπ, stuck at p = 0 from 25π to T = 100"
    state_names = ("position", "velocity")
    default_T = OSC_T  # a long horizon: 25 arcs, then a 21.5 stick; no kπ on a node of N = 101, 1001, 10001
    default_x0 = (OSC_P0, 0.0)
    switch_times = tuple(float(k * np.pi) for k in range(1, OSC_STOP_COUNT + 1))

    def blocks(self) -> tuple[SetBlock, ...]:
        return (
            SetBlock.equation(0, coordinate(1, 2), "p' = v"),
            SetBlock.equation(1, affine({0: -1.0}, 2), "v' ∈ −p − μ·Sgn(v)",
                              (SignTerm(OSC_FRICTION, affine({1: -1.0}, 2), name="μ·Sgn(−v)"),)),
        )

    def motion(self, t: np.ndarray) -> np.ndarray:
        return stick_slip_oscillator_motion(t)

    def multipliers(self, t: np.ndarray) -> np.ndarray:
        k = np.clip(np.floor(_times(t) / np.pi), 0, OSC_STOP_COUNT).astype(int)
        arcs = np.where(k % 2 == 0, 1.0, -1.0)
        stuck = _oscillator_turning_points(np.array(OSC_STOP_COUNT)) / OSC_FRICTION
        return np.where(k < OSC_STOP_COUNT, arcs, stuck)[:, None]


FRICTION_MODELS: dict[str, type[InclusionModel]] = {
    cls.name: cls
    for cls in (BlockStopStick, BlockStopStickBVP, BlockBreakaway, SlideOnLine, SlideAfterReaching, TwoSurfaceSliding,
                StickSlipOscillator)
}
