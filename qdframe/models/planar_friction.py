"""Dry friction in the plane, written in the set language as a user writes it.

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
"""

from __future__ import annotations

import numpy as np

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
