"""Dry friction in the plane and in space, written in the set language as a user writes it.

``orthotropic-puck``: a puck on a table whose friction is orthotropic, with principal
axes d1 = (cos θ, sin θ), d2 = (−sin θ, cos θ) at θ = 30° to the world axes, and a
constant force f. In world coordinates (p1, p2, v1, v2):

    p' = v,   v' ∈ f − μ1·Sgn(⟨d1, v⟩)·d1 − μ2·Sgn(⟨d2, v⟩)·d2,

so each switching function s_i = ⟨d_i, v⟩ enters both v1' and v2', once with each sign
of coefficient (s2 enters v1' as +μ2·sin θ·Sgn(s2) and v2' as −μ2·cos θ·Sgn(s2)). Filippov's
set has ONE selection λ_i ∈ Sgn(s_i) per switch: the set language gives the terms on s_i
and −s_i one selection (:class:`~qdframe.model.SignTerm`'s `sense`).

In the principal coordinates w = Rᵀv the motion decouples into two Coulomb blocks,
w_i' ∈ g_i − μ_i·Sgn(w_i), g = Rᵀf: each w_i decelerates at μ_i·sign(w_i0) − g_i until it
stops at t_i = |w_i0|/(μ_i − g_i·sign(w_i0)) and sticks (|g_i| < μ_i). With μ = (1, 0.4),
g = (0.3, −0.1), w(0) = (1.2, −0.6): t_1 = 12/7 ≈ 1.714, t_2 = 2, T = 3.

``isotropic-puck``: isotropic Coulomb friction, the vector sign Sgn(v1, v2) = v/|v| (the
closed unit disc at v = 0), and a pull F·d along the fixed direction d = (0.6, 0.8) that
ramps up, F' = κ:

    p' = v,   v' ∈ F·d − μ·Sgn(v1, v2),   F' = κ,   μ = 1/2, κ = 1/4, F(0) = 0,

from v(0) = V·n, n = (−0.8, 0.6) ⊥ d, T = 2.7. It slides on a curve (the pull turns its
velocity towards d), stops at t_s = 1, sticks (the friction force F·d inside the disc of
radius μ: the selection λ = (F/μ)·d), and breaks away along d at t_b = 2, where F = κt
reaches μ: then v = (t − 2)²/8·d, p = p_s + (t − 2)³/24·d.

The slide has no closed form. Its reference is its equations written by hand in polar
form, v = r·(cos θ·d + sin θ·n): r' = F·cos θ − μ, θ' = −F·sin θ/r (a stop is r reaching 0,
transversally), integrated by DOP853 at rtol = atol = 2.3e-14 with the stop as an event
(nothing of qdframe's integrator); V = 0.4496641297701067 is chosen (by shooting) so that
it stops at t_s = 1, where F = μ/2: the velocity then turns towards d as θ ∝ t_s − t, a
smooth approach to rest (for F(t_s) = μ/k, θ ∝ (t_s − t)^{1/(k−1)}).

``isotropic-slide-3d``: the same law in space with a constant pull,
v' ∈ F0·d − μ·Sgn(v1, v2, v3), μ = 1, F0 = μ/2, d = (1, 2, 2)/3, v(0) = n = (2, −2, 1)/3 ⊥ d,
T = 2. The motion stays in the plane of d and n and has a closed form there (the classic
sled on an incline): with v = r·(cos θ·d + sin θ·n) and u = tan(θ/2), r' = F0·cos θ − μ and
r·θ' = −F0·sin θ give r = (C/2)·u^{k−1}(1 + u²), k = μ/F0 = 2, so from r = 1, θ = π/2 (u = 1,
C = 1): v = (u(1 − u²)/2)·d + u²·n, t = (1 − u) + (1 − u³)/3 (u(t) the real root of
u³ + 3u = 4 − 3t), p = ((1 − u²)/4 − (1 − u⁶)/12)·d + ((1 − u³)/3 + (1 − u⁵)/5)·n. It stops
at u = 0, t = 4/3, p = d/6 + 8n/15, and sticks (F0 < μ).
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.integrate import OdeSolution, solve_ivp

from ..sets import SetModel, Sgn

PUCK_ANGLE = np.pi / 6  # θ: the principal axes against the world axes
PUCK_FRICTION = (1.0, 0.4)  # μ1, μ2 along d1, d2
PUCK_FORCE = (0.3, -0.1)  # g = Rᵀf, the force in the principal axes
PUCK_W0 = (1.2, -0.6)  # w(0) = Rᵀv(0)
PUCK_T = 3.0


def _rotation() -> np.ndarray:
    """R = [d1 d2]: principal-axis coordinates to world coordinates."""
    c, s = np.cos(PUCK_ANGLE), np.sin(PUCK_ANGLE)
    return np.array([[c, -s], [s, c]])


def _stop_times() -> np.ndarray:
    w0, g, mu = np.array(PUCK_W0), np.array(PUCK_FORCE), np.array(PUCK_FRICTION)
    return np.abs(w0) / (mu - g * np.sign(w0))


def orthotropic_puck_motion(t: np.ndarray) -> np.ndarray:
    """(p1, p2, v1, v2) at t: each principal velocity w_i linear until its stop, then 0."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    w0, g, mu = np.array(PUCK_W0), np.array(PUCK_FORCE), np.array(PUCK_FRICTION)
    rate = g - mu * np.sign(w0)  # w_i' while sliding
    s = np.minimum(t[:, None], _stop_times()[None, :])
    w = w0 + rate * s
    q = w0 * s + 0.5 * rate * s**2  # ∫w, constant after the stop
    R = _rotation()
    return np.concatenate([q @ R.T, w @ R.T], axis=1)


class OrthotropicPuck(SetModel):
    """Puck with orthotropic Coulomb friction at 30° to the world axes: slides, stops along
    each principal axis in turn (t = 12/7, 2), sticks until T = 3."""

    name = "orthotropic-puck"
    description = ("Puck, orthotropic friction μ = (1, 0.4) on axes at 30°, written in world coordinates: "
                   "stops at t = 12/7 and 2, sticks until T = 3")
    state_names = "p1 p2 v1 v2"
    default_T = PUCK_T
    default_x0 = (0.0, 0.0, *(_rotation() @ np.array(PUCK_W0)))
    switch_times = tuple(float(t) for t in np.sort(_stop_times()))

    def sets(self, p1, p2, v1, v2):
        (c, s), (mu1, mu2) = (np.cos(PUCK_ANGLE), np.sin(PUCK_ANGLE)), PUCK_FRICTION
        f1, f2 = _rotation() @ np.array(PUCK_FORCE)
        s1, s2 = c * v1 + s * v2, -s * v1 + c * v2  # ⟨d1, v⟩, ⟨d2, v⟩
        return {
            p1: v1,
            p2: v2,
            v1: f1 - mu1 * c * Sgn(s1) + mu2 * s * Sgn(s2),
            v2: f2 - mu1 * s * Sgn(s1) - mu2 * c * Sgn(s2),
        }

    def exact_solution(self, t: np.ndarray) -> np.ndarray | None:
        default = (self.T == self.default_T and np.array_equal(self.x0, self.default_x0)
                   and self.end_values.size == 0)
        return orthotropic_puck_motion(t) if default else None


# ------------------------------------------------------------------ isotropic friction
ISO_FRICTION = 0.5  # μ
ISO_RAMP = 0.25  # κ: F = κ·t
ISO_DIRECTION = (0.6, 0.8)  # d
ISO_NORMAL = (-0.8, 0.6)  # n
ISO_SPEED = 0.4496641297701067  # V: stops at t_s = 1 (shooting on the polar equations below)
ISO_STOP = 1.0  # t_s: F(t_s) = μ/2
ISO_BREAK = ISO_FRICTION / ISO_RAMP  # t_b = 2
REFERENCE_TOL = 2.3e-14  # DOP853's rtol and atol for the slide (its floor)


def puck_slide() -> OdeSolution:
    """The puck's slide by its polar equations (module docstring): (a, b, r, θ), p = a·d + b·n,
    v = r·(cos θ·d + sin θ·n), dense over [0, t_s] (t_s located as r = 0), computed once."""
    cached = _SLIDE.get("solution")
    if cached is None:
        def rhs(t: float, y: np.ndarray) -> list[float]:
            _, _, r, theta = y
            pull = ISO_RAMP * t
            return [r * np.cos(theta), r * np.sin(theta), pull * np.cos(theta) - ISO_FRICTION,
                    -pull * np.sin(theta) / r]

        def stop(t: float, y: np.ndarray) -> float:
            return y[2]

        stop.terminal, stop.direction = True, -1.0
        with warnings.catch_warnings():  # rtol at DOP853's floor: it says so
            warnings.simplefilter("ignore", UserWarning)
            run = solve_ivp(rhs, (0.0, 2 * ISO_BREAK), [0.0, 0.0, ISO_SPEED, np.pi / 2], method="DOP853",
                            rtol=REFERENCE_TOL, atol=REFERENCE_TOL, dense_output=True, events=stop)
        cached = _SLIDE["solution"] = run.sol
        _SLIDE["stop"] = float(run.t_events[0][0])
        _SLIDE["rest"] = run.y_events[0][0][:2].copy()
    return cached


_SLIDE: dict = {}


def puck_motion(t: np.ndarray) -> np.ndarray:
    """(p1, p2, v1, v2, F) of isotropic-puck at the times t: the slide (:func:`puck_slide`),
    rest at p_s, the straight break-away along d after t_b."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    solution = puck_slide()
    stop, (a_s, b_s) = _SLIDE["stop"], _SLIDE["rest"]
    d, n = np.array(ISO_DIRECTION), np.array(ISO_NORMAL)
    a, b, r, theta = solution(np.minimum(t, stop))
    sliding = t < stop
    a, b = np.where(sliding, a, a_s), np.where(sliding, b, b_s)
    r = np.where(sliding, r, 0.0)
    w = np.maximum(t - ISO_BREAK, 0.0)
    along = a + ISO_RAMP * w**3 / 6  # κ/6·(t − t_b)³ = (t − 2)³/24
    speed = ISO_RAMP * w**2 / 2  # κ/2·(t − t_b)² = (t − 2)²/8
    p = along[:, None] * d + b[:, None] * n
    v = (r * np.cos(theta) + speed)[:, None] * d + (r * np.sin(theta))[:, None] * n
    return np.concatenate([p, v, (ISO_RAMP * t)[:, None]], axis=1)


class _Exact(SetModel):
    def exact_solution(self, t: np.ndarray) -> np.ndarray | None:
        default = (self.T == self.default_T and np.array_equal(self.x0, self.default_x0)
                   and self.end_values.size == 0)
        return self.motion(t) if default else None

    def motion(self, t: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class IsotropicPuck(_Exact):
    """Puck with isotropic Coulomb friction μ·Sgn(v1, v2) under a ramped pull: slides on a
    curve, stops at t = 1, sticks, breaks away at t = 2 (the pull reaches μ)."""

    name = "isotropic-puck"
    description = ("Puck, isotropic friction μ·Sgn(v1, v2), pull ramped along (0.6, 0.8): curves, stops at t = 1, "
                   "sticks, breaks away at t = 2")
    state_names = "p1 p2 v1 v2 F"
    default_T = 2.7  # no switch on a node of N = 101, 1001, 10001
    default_x0 = (0.0, 0.0, ISO_SPEED * ISO_NORMAL[0], ISO_SPEED * ISO_NORMAL[1], 0.0)
    switch_times = (ISO_STOP, ISO_BREAK)

    def sets(self, p1, p2, v1, v2, F):
        S = Sgn(v1, v2)  # v/|v|, the closed unit disc at v = 0
        (d1, d2), mu = ISO_DIRECTION, ISO_FRICTION
        return {p1: v1, p2: v2,
                v1: F * d1 - mu * S[0],
                v2: F * d2 - mu * S[1],
                F: ISO_RAMP}

    def motion(self, t: np.ndarray) -> np.ndarray:
        return puck_motion(t)


# the 3-D slide: constant pull F0 = μ/2 (k = 2), |v(0)| = 1 ⊥ d: closed form in the plane of d and v(0)
SLIDE3D_FRICTION, SLIDE3D_PULL = 1.0, 0.5
SLIDE3D_STOP = 4.0 / 3.0


def sled_phase(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The slide under the constant pull F0 = μ/2 from |v| = 1 ⊥ d (μ = 1), in the frame (d, n):
    the distances along d and n and the velocities along d and n at the times t, rest after
    t_s = 4/3 (u the real root of u³ + 3u = 4 − 3t, Cardano's, polished by Newton)."""
    t = np.minimum(np.atleast_1d(np.asarray(t, dtype=float)), SLIDE3D_STOP)
    q = 4.0 - 3.0 * t
    root = np.sqrt(q * q / 4.0 + 1.0)
    u = np.cbrt(q / 2.0 + root) + np.cbrt(q / 2.0 - root)
    for _ in range(3):
        u = u - (u**3 + 3.0 * u - q) / (3.0 * u * u + 3.0)
    u = np.maximum(u, 0.0)
    return (1 - u**2) / 4 - (1 - u**6) / 12, (1 - u**3) / 3 + (1 - u**5) / 5, u * (1 - u**2) / 2, u**2


SLIDE3D_DIRECTION = (1 / 3, 2 / 3, 2 / 3)
SLIDE3D_V0 = (2 / 3, -2 / 3, 1 / 3)


class IsotropicSlide3D(_Exact):
    """A body sliding in space under isotropic Coulomb friction μ·Sgn(v1, v2, v3) and a
    constant pull: curves in the plane of the pull and v(0), stops at t = 4/3, sticks."""

    name = "isotropic-slide-3d"
    description = "Isotropic friction in space, μ·Sgn(v1, v2, v3), constant pull: curves, stops at t = 4/3, sticks"
    state_names = "p1 p2 p3 v1 v2 v3"
    default_T = 2.0
    default_x0 = (0.0, 0.0, 0.0, *SLIDE3D_V0)
    switch_times = (SLIDE3D_STOP,)

    def sets(self, p1, p2, p3, v1, v2, v3):
        pull = tuple(SLIDE3D_PULL * d for d in SLIDE3D_DIRECTION)
        return {p1: v1, p2: v2, p3: v3,
                (v1, v2, v3): pull - SLIDE3D_FRICTION * Sgn(v1, v2, v3)}  # split into v1, v2, v3 on one λ ∈ B

    def motion(self, t: np.ndarray) -> np.ndarray:
        d, n = np.array(SLIDE3D_DIRECTION), np.array(SLIDE3D_V0)
        along, across, v_along, v_across = sled_phase(t)
        return np.concatenate([along[:, None] * d + across[:, None] * n, v_along[:, None] * d + v_across[:, None] * n],
                              axis=1)
