"""One switching function, one Filippov selection (issue 38, item 1): Sgn(s), Sgn(−s) and
Sgn(c·s) share one λ ∈ Sgn(s) per node, whatever the sign or scale of their coefficients,
so that F is Filippov's set and not a larger one."""

from __future__ import annotations

import numpy as np
import pytest

import qdframe
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.models.planar_friction import PUCK_ANGLE, PUCK_FRICTION, OrthotropicPuck
from qdframe.sets import SetModel, Sgn


def _functional(model) -> Functional:
    return Functional(model, Grid(model.T, 5, "implicit-euler"))


class _Scaled(SetModel):
    """x1' ∈ −Sgn(x1 − x2), x2' ∈ 2·Sgn(−3·x1 + 3·x2) + 0.5·Sgn(0.25·x1 − 0.25·x2), x3' ∈ Sgn(x1 − x2 + 1)."""

    name = "scaled-switches"
    state_names = "x1 x2 x3"
    default_x0 = (0.0, 0.0, 0.0)

    def sets(self, x1, x2, x3):
        return {x1: -Sgn(x1 - x2), x2: 2 * Sgn(-3 * x1 + 3 * x2) + 0.5 * Sgn(0.25 * x1 - 0.25 * x2),
                x3: Sgn(x1 - x2 + 1)}


def test_constant_multiples_of_one_switch_share_one_selection():
    f = _functional(_Scaled())
    # x1 − x2 in three scalings and signs: one column; x1 − x2 + 1 is another surface. The
    # first term, −Sgn(x1 − x2) = Sgn(x2 − x1), sets the selection's switch s0 = x2 − x1
    assert f.p == 2
    assert f.sign_columns == [0, 0, 0, 1]
    assert [term.sense for _, term in f.sign_terms] == [1.0, 1.0, -1.0, 1.0]


def test_the_shared_selection_enters_each_term_with_its_sign():
    """At x1 = x2 (s0 = x2 − x1 = 0) with λ = 0.4 ∈ Sgn(s0): x1' = λ, x2' = 2λ − 0.5λ; any
    other pair is outside F."""
    f = _functional(_Scaled())
    x = np.zeros((f.grid.nodes, 3))
    lam = np.tile([0.4, 1.0], (f.grid.nodes, 1))
    inside = np.tile([0.4, 2 * 0.4 - 0.5 * 0.4, 1.0], (f.grid.nodes, 1))
    xi = f.pack(x, inside, selections=lam)
    assert np.max(f.residuals(xi).inclusion_residual) <= 1e-15
    outside = inside + np.array([0.0, 0.1, 0.0])
    assert f.residuals(f.pack(x, outside, selections=lam)).inclusion_residual == pytest.approx(0.1)


def test_a_rotated_friction_law_has_one_selection_per_axis():
    """The orthotropic puck: s2 = ⟨d2, v⟩ enters v1' as +μ2·sin θ·Sgn(s2) and v2' as −μ2·cos θ·Sgn(s2).
    Filippov's set ties both to one λ2; with two selections (the bug), a velocity that uses
    λ2 = +1 in v1' and −1 in v2' at v = 0 would be in F."""
    f = _functional(OrthotropicPuck(x0=(0.0, 0.0, 0.0, 0.0)))
    assert f.p == 2
    c, s = np.cos(PUCK_ANGLE), np.sin(PUCK_ANGLE)
    mu1, mu2 = PUCK_FRICTION
    x = np.zeros((f.grid.nodes, 4))  # at rest: both switches at 0
    f_world = np.array([c * 0.3 + s * 0.1, s * 0.3 - c * 0.1])  # R·g, g = (0.3, −0.1)

    def velocity(l1: float, l2_first: float, l2_second: float) -> np.ndarray:
        dv1 = f_world[0] - mu1 * c * l1 + mu2 * s * l2_first
        dv2 = f_world[1] - mu1 * s * l1 - mu2 * c * l2_second
        return np.tile([0.0, 0.0, dv1, dv2], (f.grid.nodes, 1))

    def distance(z: np.ndarray) -> float:
        """min over selections (a grid holding ±0.2, ±0.5) of the distance of z from F."""
        grid = np.linspace(-1, 1, 21)
        return min(f.residuals(f.pack(x, z, selections=np.tile([a, b], (f.grid.nodes, 1)))).inclusion_residual
                   for a in grid for b in grid)

    assert distance(velocity(0.2, -0.5, -0.5)) <= 1e-15  # one λ2 in both coordinates: in F
    # λ2 = +1 in v1' and −1 in v2': outside Filippov's set whatever selections the solver picks
    assert distance(velocity(0.2, 1.0, -1.0)) > 0.02


def test_the_rotated_law_is_solved_to_its_exact_solution():
    result = qdframe.solve("orthotropic-puck", accuracy=1e-6)
    assert result.solved, result.message
    assert result.solution_error <= 1e-6 and result.solution_error <= result.error_estimate
    assert result.switch_times == pytest.approx(OrthotropicPuck.switch_times, abs=1e-8)
