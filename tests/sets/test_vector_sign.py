"""The vector sign Sgn(v1, v2, …) (issue 38 items 2 and 3): isotropic friction in the set
language and the low-level model, one selection vector λ ∈ B per node tied by the ball's
natural map, and formulas that are undefined or not C¹ at v = 0 refused, naming Sgn(v1, v2)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import qdframe
from qdframe.ready_pieces import affine, ball_switch, coordinate
from qdframe.functional import Functional
from qdframe.functional.pieces import _ball_band_kappa
from qdframe.schemes.grid import Grid
from qdframe.model import BallSwitch, InclusionModel, SetBlock, SignTerm
from qdframe.sets import Ball, Interval, Point, SetModel, SetStructureError, Sgn, compile_sets, define_model, hull, sqrt

v1, v2, v3, x = sp.symbols("v1 v2 v3 x", real=True)
MU, F1, F2 = 0.7, 0.3, -0.2


class Planar(SetModel):
    """v' ∈ f − μ·Sgn(v1, v2), written per coordinate."""

    name = "planar-sign"
    state_names = "v1 v2"
    default_x0 = (1.0, 0.5)

    def sets(self, v1, v2):
        S = Sgn(v1, v2)
        return {v1: F1 - MU * S[0], v2: F2 - MU * S[1]}


class PlanarBlock(Planar):
    """The same, as one block of two coordinates: the compiler splits it."""

    name = "planar-sign-block"

    def sets(self, v1, v2):
        return {(v1, v2): (F1, F2) - MU * Sgn(v1, v2)}


def _functional(model, nodes: int = 5, signs: str = "exact") -> Functional:
    """The model's functional with x(0) free, so that every node holds the state it is given."""
    free = type(model)(x0=[float("nan")] * model.n_states)
    return Functional(free, Grid(model.T, nodes, "implicit-euler"), signs=signs)


def _at(f: Functional, v: np.ndarray, z: np.ndarray, lam: np.ndarray) -> np.ndarray:
    nodes = f.grid.nodes
    return f.pack(np.tile(v, (nodes, 1)), np.tile(z, (nodes, 1)), selections=np.tile(lam, (nodes, 1)))


@pytest.mark.parametrize("model", [Planar(), PlanarBlock()])
def test_one_selection_vector_shared_by_the_coordinates(model):
    f = _functional(model)
    assert f.p == 2 and f.balls == [(0, 2)]  # one λ ∈ B, two columns
    assert f.sign_columns == [0, 1] and [term.sense for _, term in f.sign_terms] == [-1.0, -1.0]
    assert f.selection_names == ["Sgn(v1, v2)[0]", "Sgn(v1, v2)[1]"]
    assert isinstance(f.sign_terms[0][1].switch, BallSwitch) and f.sign_terms[0][1].switch is f.sign_terms[1][1].switch


def test_constant_multiples_of_the_vector_switch_share_its_selection():
    """Sgn(c·v) = sign(c)·Sgn(v) for a constant c ≠ 0, for the vector sign too."""
    compiled = compile_sets({v1: -Sgn(v1, v2)[0] + Sgn(-2 * v1, -2 * v2)[0], v2: 3 * Sgn(0.5 * v1, 0.5 * v2)[1]}, (v1, v2))
    terms = [term for block in compiled.blocks for term in block.signs]
    assert len({id(term.switch) for term in terms}) == 1
    assert [(term.sense, term.component) for term in terms] == [(-1.0, 0), (-1.0, 0), (1.0, 1)]


def test_a_permuted_or_reflected_vector_switch_is_the_same_surface():
    """Sgn(v2, v1) is Sgn(v1, v2) with its coordinates swapped, Sgn(−v1, v2) with the first
    reversed: one selection vector, or the set at v = 0 would be a square, not the disc."""
    compiled = compile_sets({v1: -Sgn(v1, v2)[0], v2: -Sgn(v2, v1)[0] + Sgn(-v1, v2)[0], v3: Sgn(v1, v3)[1]}, (v1, v2, v3))
    terms = [term for block in compiled.blocks for term in block.signs]
    assert len({id(term.switch) for term in terms[:3]}) == 1 and terms[3].switch is not terms[0].switch
    assert [(term.sense, term.component) for term in terms] == [(-1.0, 0), (-1.0, 1), (-1.0, 0), (1.0, 1)]


def test_sliding_the_set_is_the_point_f_minus_mu_v_over_its_norm():
    f = _functional(Planar())
    v = np.array([1.0, 0.5])
    unit = v / np.linalg.norm(v)
    xi = _at(f, v, np.array([F1, F2]) - MU * unit, unit)
    residuals = f.residuals(xi)
    assert residuals.inclusion_residual <= 1e-15 and residuals.selection_residual <= 1e-15
    # the box law, λ = (sign v1, sign v2), is no selection of Sgn(v): its natural map is not 0
    box = np.sign(v)
    assert f.residuals(_at(f, v, np.array([F1, F2]) - MU * box, box)).selection_residual > 0.2


def test_at_rest_the_selection_is_anywhere_in_the_disc_and_nowhere_else():
    f = _functional(Planar())
    rest = np.zeros(2)
    for lam in ([0.3, -0.4], [0.6, 0.8], [-1.0, 0.0]):  # inside, on the circle
        assert f.residuals(_at(f, rest, np.zeros(2), np.array(lam))).selection_residual <= 1e-15
    for lam in ([0.8, 0.8], [1.0, 1.0]):  # in the box [−1, 1]², outside the disc
        assert f.residuals(_at(f, rest, np.zeros(2), np.array(lam))).selection_residual > 0.05


def test_the_natural_maps_jacobian_is_its_derivative_off_the_sphere():
    """λ − P_B(λ + c·s): the generalized Jacobian element against central differences, at points
    where λ + c·s is inside the ball and where it is outside (P_B smooth at both)."""
    f = _functional(Planar(), nodes=4)
    rng = np.random.default_rng(3)
    for lam, v in (([0.1, 0.2], [0.05, -0.1]), ([0.6, 0.7], [1.0, 0.3])):
        xi = _at(f, np.array(v), rng.normal(size=2), np.array(lam))
        _, jacobian = f.selection_residual(xi)
        columns = list(range(f.n)) + list(range(2 * f.n + f.m, f.dim))  # x and λ in ξ's row, (x, u, λ) in y
        for j, column in enumerate(columns):
            step = np.zeros_like(xi)
            step[:, column] = 1e-7
            numeric = (f.selection_residual(xi + step)[0] - f.selection_residual(xi - step)[0]) / 2e-7
            assert np.allclose(numeric, jacobian[:, :, j], atol=1e-7)


def test_the_band_holds_the_direction_and_is_c1():
    rng = np.random.default_rng(0)
    s = rng.normal(size=(200, 2)) * rng.choice([1e-4, 1e-3, 1e-2], size=(200, 1))
    band = 3e-3
    for j in (0, 1):
        for psi in (1.0, -1.0):
            kappa, slope = _ball_band_kappa(band, s, j, psi)
            unit = s[:, j] / np.linalg.norm(s, axis=1)
            assert np.all(psi * unit <= kappa + 1e-15)  # the interval holds s_j/|s|
            for k in (0, 1):
                step = np.zeros_like(s)
                step[:, k] = 1e-9
                numeric = (_ball_band_kappa(band, s + step, j, psi)[0] - _ball_band_kappa(band, s - step, j, psi)[0]) / 2e-9
                assert np.allclose(numeric, slope[:, k], atol=1e-5)
    assert np.all(_ball_band_kappa(band, np.zeros((3, 2)), 0, 1.0)[0] == 1.0)  # the whole [−1, 1] at s = 0


def test_band_mode_solves_a_fixed_grid():
    result = qdframe.solve(Planar(), nodes=51, signs="band", estimate=False)
    assert result.converged, result.message


def test_a_weighted_norm_is_elliptic_friction():
    """Sgn(v, matrix=W) = Wᵀ·Sgn(W·v), the subdifferential of |W·v|: the friction force of
    v' ∈ f − Sgn(v1, v2, matrix=W) is −W²v/|Wv| for W = diag(μ1, μ2)."""
    W = np.diag([2.0, 0.5])

    class Elliptic(Planar):
        name = "elliptic"

        def sets(self, v1, v2):
            S = Sgn(v1, v2, matrix=W)
            return {v1: F1 - S[0], v2: F2 - S[1]}

    f = _functional(Elliptic())
    v = np.array([0.3, -0.4])
    lam = W @ v / np.linalg.norm(W @ v)
    xi = _at(f, v, np.array([F1, F2]) - W.T @ lam, lam)
    assert f.residuals(xi).inclusion_residual <= 1e-15 and f.residuals(xi).selection_residual <= 1e-15
    force = -W @ W @ v / np.linalg.norm(W @ v)
    assert np.allclose(np.array([F1, F2]) - W.T @ lam, np.array([F1, F2]) + force)
    # at rest, the friction forces fill the ellipse W·B: (2, 0) is one, (0, 1) is not
    assert f.residuals(_at(f, np.zeros(2), np.array([F1 - 2.0, F2]), np.array([1.0, 0.0]))).inclusion_residual <= 1e-15
    rotated = np.array([[np.cos(0.4), -np.sin(0.4)], [np.sin(0.4), np.cos(0.4)]])
    compiled = compile_sets({v1: -Sgn(v1, v2, matrix=W @ rotated.T)[0], v2: -Sgn(v1, v2, matrix=W @ rotated.T)[1]},
                            (v1, v2))
    terms = [term for block in compiled.blocks for term in block.signs]
    assert len(terms) == 4 and len({id(term.switch) for term in terms}) == 1  # Σ_j W_ji λ_j, one λ


def test_a_hand_written_model_uses_a_ball_switch():
    """An InclusionModel with the ready-made BallSwitch: the same functional as the set language's."""

    class Hand(InclusionModel):
        name = "hand-planar"
        state_names = ("v1", "v2")
        default_x0 = (1.0, 0.5)

        def blocks(self):
            S = ball_switch([0, 1], 2, name="Sgn(v1, v2)")
            return (SetBlock.equation(0, affine({}, 2, F1), signs=(SignTerm(MU, S, name="μ·S0", sense=-1.0, component=0),)),
                    SetBlock.equation(1, affine({}, 2, F2), signs=(SignTerm(MU, S, name="μ·S1", sense=-1.0, component=1),)))

    hand, layer = _functional(Hand()), _functional(Planar())
    rng = np.random.default_rng(1)
    for _ in range(5):
        xi = hand.pack(rng.normal(size=(5, 2)), rng.normal(size=(5, 2)), selections=rng.uniform(-1, 1, size=(5, 2)))
        assert hand.terms(xi).I == pytest.approx(layer.terms(xi).I, rel=1e-14)
        assert np.allclose(hand.selection_residual(xi)[1], layer.selection_residual(xi)[1])


@pytest.mark.parametrize("term, field", [
    (lambda S: SignTerm(1.0, S, component=None), "component"),
    (lambda S: SignTerm(1.0, S, component=2), "component"),
    (lambda S: SignTerm(1.0, coordinate(0, 2), component=0), "component"),
    (lambda S: SignTerm(1.0, BallSwitch(S.function, 1), component=0), "dim"),
])
def test_bad_low_level_vector_signs_are_one_line_naming_the_field(term, field):
    S = ball_switch([0, 1], 2)

    class Bad(InclusionModel):
        name = "bad"
        state_names = ("v1", "v2")
        default_x0 = (0.0, 0.0)

        def blocks(self):
            return (SetBlock.equation(0, affine({}, 2), signs=(term(S),)), SetBlock.equation(1, affine({}, 2)))

    with pytest.raises(qdframe.InputError, match=field) as caught:
        Bad()
    assert "\n" not in str(caught.value)


# ---------------------------------------------------------------------- item 3: refusals
NORM = sqrt(v1**2 + v2**2)


@pytest.mark.parametrize("sets", [
    lambda: {v1: F1 - MU * v1 / NORM, v2: F2 - MU * v2 / NORM},  # v/|v| as a formula
    lambda: {v1: Point(F1 - NORM), v2: 0},  # |v| inside a smooth part
    lambda: {v1: F1 - MU * (v1 / NORM) * Sgn(NORM), v2: F2 - MU * (v2 / NORM) * Sgn(NORM)},  # (v_i/|v|)·Sgn(|v|)
    lambda: {v1: F1 - MU * (v1 / NORM) * Sgn(v1), v2: 0},  # v_i/|v| as an amplitude
    lambda: {v1: NORM * Interval(-1, 1), v2: 0},  # |v| scaling a set
    lambda: {v1: Interval(-NORM, NORM), v2: 0},
    lambda: {(v1, v2): Ball((0, 0), NORM)},
])
def test_formulas_undefined_or_not_c1_at_rest_are_refused_naming_the_vector_sign(sets):
    Model = define_model("norm-written", "v1 v2", lambda a, b: sets(), x0=(1.0, 0.5))
    with pytest.raises(SetStructureError) as caught:
        qdframe.solve(Model(), nodes=11)
    message = str(caught.value)
    assert "\n" not in message and "Sgn(v1, v2)" in message and "not C¹" in message, message


def test_smooth_roots_and_powers_stay_allowed():
    compile_sets({v1: sqrt(v1**2 + 3) - Sgn(v1), v2: v2 ** sp.Rational(3, 2) + x**2}, (v1, v2, x))


@pytest.mark.parametrize("build, words", [
    (lambda: compile_sets({v1: 1 - Sgn(v1, v2), v2: 0}, (v1, v2)), ["S[i]"]),
    (lambda: compile_sets({(v1, v2): Ball((0, 0), 1) - Sgn(v1, v2)}, (v1, v2)), ["S[0]", "coordinates"]),
    (lambda: Sgn(v1, v2)[2], ["index in 0..1"]),
    (lambda: hull(Sgn(v1, v2), (0, 0)), ["vector sign"]),
    (lambda: Sgn(v1, v2, matrix=[[1, 0]]), ["matrix"]),
    (lambda: Sgn(v1, v2, matrix=[[1, 0], [0, 0]]), ["rows that are not zero"]),
    (lambda: Ball((0, 0), 1)[0], ["coordinates are sets of their own"]),
])
def test_misplaced_vector_signs_are_clear_errors(build, words):
    with pytest.raises(SetStructureError) as caught:
        build()
    for word in words:
        assert word in str(caught.value), str(caught.value)


def test_three_coordinates_and_a_box_split_too():
    from qdframe.sets import Box

    compiled = compile_sets({(v1, v2, v3): (1, 0, 0) - Sgn(v1, v2, v3)}, (v1, v2, v3))
    assert [block.coords for block in compiled.blocks] == [(0,), (1,), (2,)]
    assert len({id(term.switch) for block in compiled.blocks for term in block.signs}) == 1
    boxed = compile_sets({(v1, v2): Box((-0.1, -0.2), (0.1, 0.2)) - Sgn(v1, v2)}, (v1, v2))
    assert [block.coords for block in boxed.blocks] == [(0,), (1,)]
    assert all(len(block.max_groups[0].pieces(np.zeros((1, 2)))[0][0]) == 2 for block in boxed.blocks)  # an interval each
