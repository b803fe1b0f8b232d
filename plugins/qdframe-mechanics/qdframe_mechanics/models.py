"""The model families of the paper's Section 5, written with qdframe's modeling layer.

Each model's boundary data is feasible by construction: its end values are those of a
trajectory known in closed form or simulated (`reference_solution`), which lies in the
inclusion. Where that trajectory is the only solution it is also `exact_solution` (the
solver then reports the error against it); where the inclusion has many solutions with
the same boundary data it is not, since an error against one of many means nothing.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from qdframe.sets import Ball, Interval, SetModel, Sgn, hull, intersection, norm1

INF = float("inf")


# ------------------------------------------------------------------ coulomb-block
MASS, MU, GRAVITY, PULL = 1.0, 0.5, 10.0, 3.5  # friction μ·F_N = 5 > pull 3.5: the block decelerates, then sticks
BLOCK_V0, BLOCK_T = 3.0, 3.0
DECELERATION = (MU * MASS * GRAVITY - PULL) / MASS  # 1.5: v = 0 at t = v0/a = 2, at rest after
STOP_TIME = BLOCK_V0 / DECELERATION


def block_motion(t: np.ndarray) -> np.ndarray:
    """The Filippov solution: p = v0·t − a·t²/2, v = v0 − a·t until v = 0 at t = v0/a, then at rest."""
    s = np.minimum(np.atleast_1d(np.asarray(t, dtype=float)), STOP_TIME)
    return np.stack([BLOCK_V0 * s - 0.5 * DECELERATION * s**2, BLOCK_V0 - DECELERATION * s], axis=1)


class CoulombBlock(SetModel):
    """A block pulled by g against Coulomb friction, m·v' ∈ −μ·F_N·Sgn(v) + g, from v(0) = 3.

    m = 1, μ = 0.5, F_N = m·10, g = 3.5: the block slides with v' = −1.5 and comes to rest at
    t = 2, p = 3; since |g| < μ·F_N it then sticks (v ≡ 0, the friction selection
    Sgn(0) ∋ g/(μ·F_N) = 0.7) until T = 3. An initial-value problem: x(0) is given, no end
    values; the motion is the only solution.
    """

    name = "coulomb-block"
    state_names = "position velocity"
    default_T = BLOCK_T
    default_x0 = (0.0, BLOCK_V0)
    mass, mu, normal_force, pull = MASS, MU, MASS * GRAVITY, PULL
    switch_times = (STOP_TIME,)

    def sets(self, position, velocity):
        return {
            position: velocity,
            velocity: (-self.mu * self.normal_force * Sgn(velocity) + self.pull) / self.mass,
        }

    def exact_solution(self, t):
        return block_motion(t) if self.T == BLOCK_T and np.allclose(self.x0, (0.0, BLOCK_V0)) else None

    def reference_solution(self, t):
        return block_motion(t)


# ------------------------------------------------------------------- sliding-mode
SLOPE, GAIN = 2.0, 2.0


class SlidingMode(SetModel):
    """Utkin's sliding mode: x1' = x2, x2' = x1 + u, u = −a·|x|·sgn(s), on the surface s = 2·x1 + x2 = 0.

    On the surface Filippov's set is the whole x1 + a·|x|·[−1, 1] (band inf; the surface
    term enforces s = 0, where this is exact), as paper-7.3 does for x4. The equivalent
    control u = 3·x1 lies within a·|x| = 6·|x1|, so the motion slides: x1 = e^{−2t},
    x2 = −2·e^{−2t}, the only solution from x(0) = (1, −2). That motion is fixed by x(0)
    (Filippov's equivalent control), so no end value is imposed: J is empty, and
    an end value e^{−2T} would disagree with the trapezoid rule by O(h²).
    """

    name = "sliding-mode"
    state_names = "x1 x2"
    default_T = 1.0
    default_x0 = (1.0, -SLOPE)
    gain, slope = GAIN, SLOPE

    def sets(self, x1, x2):
        s = self.slope * x1 + x2
        return {x1: x2, x2: x1 - self.gain * norm1(x1, x2) * Sgn(s, band=INF)}

    def surface_equations(self, x1, x2):
        return self.slope * x1 + x2

    def exact_solution(self, t):
        decay = self.x0[0] * np.exp(-self.slope * t)
        return np.stack([decay, -self.slope * decay], axis=1)

    reference_solution = exact_solution


# ---------------------------------------------------------------- double-pendulum
NU, MU_PENDULUM = 1.0, 0.5  # the paper's ν = m1/m2 and μ = g/l
PENDULUM_X0, PENDULUM_T = (0.4, 0.2, 0.0, 0.0), 2.0
# x1(T), x2(T) of `_pendulum_run` (stored, so that loading the plugin runs no simulation;
# the tests compare them with a fresh run)
PENDULUM_END = (-0.22919822941274098, 0.22839986053169853)


def _pendulum_coefficients() -> tuple[float, float, float, float]:
    return NU**2 * (1 + 2 * MU_PENDULUM**2), NU**2 * MU_PENDULUM**2, NU**2, NU**2


@lru_cache(maxsize=1)
def _pendulum_run():
    """The pendulum with sin x_i itself (sin x ∈ [0.5x, 1.5x] for |x| ≤ 1.89): one solution of the inclusion."""
    from scipy.integrate import solve_ivp

    a, b, c, d = _pendulum_coefficients()

    def rhs(_t, x):
        return [x[2], x[3], -a * np.sin(x[0]) + b * np.sin(x[1]), c * np.sin(x[0]) - d * np.sin(x[1])]

    return solve_ivp(rhs, (0.0, PENDULUM_T), PENDULUM_X0, method="DOP853", rtol=1e-12, atol=1e-13, dense_output=True)


class DoublePendulum(SetModel):
    """Double pendulum with the segments [0.5·x_i, 1.5·x_i] in place of sin x_i (Section 5).

    x1'' ∈ −ν²(1 + 2μ²)·[0.5x1, 1.5x1] + ν²μ²·[0.5x2, 1.5x2],
    x2'' ∈ ν²·[0.5x1, 1.5x1] − ν²·[0.5x2, 1.5x2],
    with x3 = x1', x4 = x2'. The end angles are those of the pendulum with sin x_i, which
    lies in the inclusion; the inclusion has many other solutions.
    """

    name = "double-pendulum"
    state_names = "x1 x2 x3 x4"
    default_T = PENDULUM_T
    default_x0 = PENDULUM_X0
    default_xT = {"x1": PENDULUM_END[0], "x2": PENDULUM_END[1]}

    def sets(self, x1, x2, x3, x4):
        a, b, c, d = _pendulum_coefficients()
        sin1, sin2 = Interval(0.5 * x1, 1.5 * x1), Interval(0.5 * x2, 1.5 * x2)
        return {x1: x3, x2: x4, x3: -a * sin1 + b * sin2, x4: c * sin1 - d * sin2}

    def reference_solution(self, t):
        return _pendulum_run().sol(t).T


# ----------------------------------------------------------------- velocity-range
class VelocityRange(SetModel):
    """x1' ∈ [min{x1, x2, x3}, max{x1, x2, x3}] = co{x1, x2, x3}, x2' = x3, x3' = −x2 (Section 5).

    x2 = cos t, x3 = −sin t; x1 = sin t (velocity x2) is one solution, so x1(T) = sin T.
    """

    name = "velocity-range"
    state_names = "x1 x2 x3"
    default_T = 2.0
    default_x0 = (0.0, 1.0, 0.0)
    default_xT = {"x1": float(np.sin(2.0))}

    def sets(self, x1, x2, x3):
        return {x1: hull(x1, x2, x3), x2: x3, x3: -x2}

    def reference_solution(self, t):
        return np.stack([np.sin(t), np.cos(t), -np.sin(t)], axis=1)


# -------------------------------------------------------------- disturbed-control
DISTURBED_A = np.array([[0.0, 1.0], [-1.0, -0.5]])
FEEDBACK, SPREAD, DISTURBANCE = 2.0, 0.5, 0.1


def _linear_motion(matrix: np.ndarray, start: np.ndarray, t) -> np.ndarray:
    """e^{Ct}·x0 at the times t, (N, n), by C's eigenvectors (C diagonalizable)."""
    values, vectors = np.linalg.eig(matrix)
    weights = np.linalg.solve(vectors, np.asarray(start, dtype=complex))
    modes = np.exp(np.outer(np.atleast_1d(t), values)) * weights
    return np.real(modes @ vectors.T)


class DisturbedControl(SetModel):
    """x' = Ax + Bu + ϖ with u ∈ U(x) = [−1, 1] ∩ [−2x1 − 0.5, −2x1 + 0.5], ϖ ∈ 0.1·|x|·[−1, 1] (Section 5).

    The control lies in a saturated band around the feedback −2x1, the disturbance in a
    ball growing with |x| = |x1| + |x2|. u = −2x1, ϖ = 0 is one admissible motion (|x1| ≤ 0.5
    keeps u within [−1, 1]); its end state is the boundary data.
    """

    name = "disturbed-control"
    state_names = "x1 x2"
    default_T = 2.0
    default_x0 = (0.5, 0.0)
    closed_loop = DISTURBED_A + np.array([[0.0, 0.0], [-FEEDBACK, 0.0]])
    default_xT = dict(zip(("x1", "x2"), _linear_motion(closed_loop, np.array([0.5, 0.0]), 2.0)[0].tolist()))

    def sets(self, x1, x2):
        (a11, a12), (a21, a22) = DISTURBED_A.tolist()
        controls = intersection(Interval(-1, 1), Interval(-FEEDBACK * x1 - SPREAD, -FEEDBACK * x1 + SPREAD))
        disturbance = DISTURBANCE * norm1(x1, x2) * Interval(-1, 1)
        return {x1: a11 * x1 + a12 * x2, x2: a21 * x1 + a22 * x2 + controls + disturbance}

    def reference_solution(self, t):
        """x(t) = e^{Ct}·x0 for the closed loop C (u = −2x1, ϖ = 0)."""
        return _linear_motion(self.closed_loop, self.x0, t)


# ------------------------------------------------------------- intersecting-balls
RADIUS, DRIFT, LENS_VELOCITY = 1.5, 0.5, (0.2, 0.7)


class IntersectingBalls(SetModel):
    """x' ∈ −0.5·x + B_1.5((−1, 0)) ∩ B_1.5((1, 0)): Remark 5.1's two balls, a lens, ψ ∈ S_2.

    c̃(F, ψ) = −0.5⟨x, ψ⟩ + min{−ψ1 + 1.5, ψ1 + 1.5}. At the first iterate z − (−0.5x) = (0, 2)
    is equidistant from both balls, where ψ* is not unique (Remark 5.1). x' = −0.5x + w
    with the constant w = (0.2, 0.7) in the lens gives x = 2w(1 − e^{−t/2}), one solution
    of many; its end state is the boundary data.
    """

    name = "intersecting-balls"
    state_names = "x1 x2"
    default_T = 1.0
    default_x0 = (0.0, 0.0)
    default_xT = dict(zip(("x1", "x2"), (2 * np.array(LENS_VELOCITY) * (1 - np.exp(-0.5))).tolist()))

    def sets(self, x1, x2):
        lens = intersection(Ball((-1, 0), RADIUS), Ball((1, 0), RADIUS))
        return {(x1, x2): (-DRIFT * x1, -DRIFT * x2) + lens}

    def initial_guess(self, t):
        return np.zeros((t.size, 2)), np.tile([0.0, 2.0], (t.size, 1))

    def reference_solution(self, t):
        return 2 * np.asarray(LENS_VELOCITY) * (1 - np.exp(-DRIFT * np.asarray(t)))[:, None]
