"""The modeling layer (qdframe.sets): the paper's examples written with it give the
hand-written models' functional, quasidifferential and solves; its structural rules."""

import numpy as np
import pytest
import sympy as sp

import qdframe
from qdframe.functional import Functional
from qdframe.grid import Grid
from qdframe.model import SetBlock
from qdframe.models.paper_sets import Paper71Sets, Paper72Sets, Paper73Sets
from qdframe.sets import (
    Abs,
    Ball,
    Box,
    Ellipse,
    Interval,
    Max,
    Min,
    Point,
    SetModel,
    SetStructureError,
    Sgn,
    compile_sets,
    define_model,
    hull,
    intersection,
    norm1,
)

PAIRS = [(Paper71Sets, "paper-7.1"), (Paper72Sets, "paper-7.2"), (Paper73Sets, "paper-7.3")]
x1, x2, x3, u = sp.symbols("x1 x2 x3 u", real=True)


def _random_points(functional, count, rng):
    base = functional.initial_point()
    points = []
    for _ in range(count):
        xi = base + rng.standard_normal(base.shape)
        points.append(functional.pack(*functional.split(xi), functional.controls(xi)))
    return points


@pytest.mark.parametrize("layer, name", PAIRS)
def test_layer_model_has_the_hand_written_functional_and_quasidifferential(layer, name):
    mine, theirs = layer(), qdframe.load_model(name)
    assert mine.end_indices == theirs.end_indices and np.allclose(mine.x0, theirs.x0)
    ours, hand = Functional(mine, Grid(mine.T, 21)), Functional(theirs, Grid(theirs.T, 21))
    rng = np.random.default_rng(1)
    for xi in _random_points(ours, 3, rng):
        a, b = ours.terms(xi), hand.terms(xi)
        for field in ("phi", "chi", "omega", "upsilon", "cost", "I", "objective"):
            assert getattr(a, field) == pytest.approx(getattr(b, field), rel=1e-12, abs=1e-14)
        qa, qb = ours.quasidifferential(xi, 1e-3), hand.quasidifferential(xi, 1e-3)
        for pa, pb in ((qa.sub, qb.sub), (qa.sup, qb.sup)):
            # the same polytopes: equal support values in random directions at every node
            for _ in range(8):
                direction = rng.standard_normal(pa.center.shape)
                # (7.2's ψ* comes from a numerical search on S_2: equal to its precision, ~1e-8)
                assert np.allclose(pa.support(direction), pb.support(direction), rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("layer, name", PAIRS)
def test_layer_model_solves_like_the_hand_written_one(layer, name):
    # the paper's scheme and the band: a smooth path, so both runs take the same iterates
    # (the semismooth path of exact selections follows rounding at its kinks)
    options = dict(nodes=31, scheme="trapezoid", signs="band")
    mine, theirs = qdframe.solve(layer(), **options), qdframe.solve(name, **options)
    assert mine.status == theirs.status == "solved"
    assert mine.iterations == theirs.iterations
    assert mine.I == pytest.approx(theirs.I, rel=1e-6, abs=1e-14)
    assert np.allclose(mine.x, theirs.x, atol=1e-9)


def test_blocks_have_the_papers_structure():
    f1, f2 = Paper71Sets().blocks()
    assert len(f1.min_groups) == 1 and not f1.max_groups  # [x1, x2] ∩ [x2 − 1, x2 + 1]: one min-group
    assert len(f2.max_groups) == 1 and not f2.min_groups  # x2' = x1 + 1: one point
    x4 = Paper73Sets().blocks()[3]
    (term,) = x4.signs
    assert len(term.amplitude) == 6 and np.isinf(term.band)  # 1.05·Σ|x_i|: six groups {±1.05 x_i}
    y = np.zeros((1, 7))
    y[0, 3] = 2.0
    s, grad = term.switch(y)
    assert s[0] == -2.0 and grad[0, 3] == -1.0  # −a·Sgn(x4) = a·Sgn(−x4)


def _one_block(value, states=(x1, x2), controls=()):
    (block,) = compile_sets({states[0]: value}, states, controls).blocks
    return block


def _interval(block: SetBlock, y):
    """[lo, hi] of a one-coordinate block at the points y, through the support function."""
    def c(psi):
        total = np.zeros(y.shape[0])
        p = np.full((y.shape[0], 1), psi)
        for group in block.max_groups:
            f, _ = group.pieces(y)
            total += np.max(f[:, :, 0] * psi, axis=1)
        for group in block.min_groups:
            g, _ = group.pieces(y, p)
            total += np.min(g, axis=1)
        return total

    return -c(-1.0), c(1.0)


def test_sets_have_the_support_functions_of_their_definitions():
    y = np.random.default_rng(0).uniform(-2, 2, size=(50, 2))
    a, b = y[:, 0], y[:, 1]
    cases = [
        (Interval(x1, x2), np.minimum(a, b), np.maximum(a, b)),
        (hull(x1, x2, 1), np.minimum(np.minimum(a, b), 1), np.maximum(np.maximum(a, b), 1)),
        (intersection(Interval(-1, 1), Interval(x1 - 0.5, x1 + 0.5)), np.maximum(-1, a - 0.5), np.minimum(1, a + 0.5)),
        (Interval(0, 1) + 2 * Interval(x1, 0), np.minimum(2 * a, 0), 1 + np.maximum(2 * a, 0)),
        (x2 + Abs(x1) * Interval(-1, 1), b - np.abs(a), b + np.abs(a)),
        (norm1(x1, x2) * Interval(-1, 1), -np.abs(a) - np.abs(b), np.abs(a) + np.abs(b)),
        (-Interval(x1, x1 + 1), -a - 1, -a),
        (Ball(x1, 2), a - 2, a + 2),
        (x1 * Interval(1, 2), np.minimum(a, 2 * a), np.maximum(a, 2 * a)),
        (intersection(Interval(-3, 3), x1 + Interval(-1, 1)) + Interval(0, 1), np.maximum(-3, a - 1), np.minimum(3, a + 1) + 1),
    ]
    for value, lo, hi in cases:
        got_lo, got_hi = _interval(_one_block(value), y)
        assert np.allclose(got_lo, lo) and np.allclose(got_hi, hi), value


def test_sgn_terms_compile_to_sign_terms():
    block = _one_block(x2 - 3 * Sgn(x1, band=0.1))
    (term,) = block.signs
    assert term.amplitude == 3.0 and term.band == 0.1
    s, grad = term.switch(np.array([[0.5, 0.0]]))
    assert s[0] == -0.5 and grad[0, 0] == -1.0
    amplitude = _one_block(Abs(x1 - x2) * Sgn(x2)).signs[0].amplitude
    values, grads = amplitude[0](np.array([[1.0, 3.0]]))
    assert sorted(values[0]) == [-2.0, 2.0] and np.allclose(np.abs(grads), 1.0)


def test_balls_ellipses_and_boxes_in_a_block_of_two():
    (block,) = compile_sets({(x1, x2): intersection(Ball((0, 0), 1), Ellipse((x1, 0), semi_axes=(2, 1)))}, (x1, x2)).blocks
    assert block.coords == (0, 1) and len(block.min_groups) == 1
    psi = np.array([[0.6, 0.8]])
    g, grad = block.min_groups[0].pieces(np.array([[0.5, 0.0]]), psi)
    assert np.allclose(g, [[1.0, 0.5 * 0.6 + np.sqrt(4 * 0.36 + 0.64)]])
    assert np.allclose(grad[0, 1], [0.6, 0.0])
    (box,) = compile_sets({(x1, x2): Box((0, -x1), (1, x1))}, (x1, x2)).blocks
    assert len(box.max_groups) == 2  # a box is the sum of its axis segments
    matrix = Ellipse((0, 0), matrix=[[4, 0], [0, 1]]).formulas(sp.symbols("p q", real=True))[0]
    assert sp.simplify(matrix - sp.sqrt(4 * sp.Symbol("p", real=True) ** 2 + sp.Symbol("q", real=True) ** 2)) == 0


@pytest.mark.parametrize(
    "build, words",
    [
        (lambda: hull(intersection(Interval(x1, x2), Interval(0, 1)), Point(x1)), ["co{", "intersection", "hull"]),
        (lambda: hull(Ball((0, 0), 1), Point((x1, x2))), ["ball"]),
        (lambda: hull(Sgn(x1), 0), ["sign term"]),
        (lambda: intersection(Interval(0, 1), Sgn(x1)), ["sign term", "intersection"]),
        (lambda: intersection(Interval(0, 1), hull(x1, x2, x3)), ["hull of 3 points"]),
        (lambda: Point(Abs(x1)), ["continuously differentiable"]),
        (lambda: Interval(Max(x1, x2), 3), ["continuously differentiable"]),
        (lambda: x1 * Ball((0, 0), 1), ["state-dependent factor"]),
        (lambda: Abs(x1) * Interval(0, 1), ["symmetric"]),
        (lambda: (Abs(x1) - Abs(x2)) * Interval(-1, 1), ["c_i > 0"]),
        (lambda: Interval(2, 1), ["lo ≤ hi"]),
        (lambda: Interval(0, 1) + Ball((0, 0), 1), ["one dimension"]),
        (lambda: Interval(0, 1) * Interval(0, 1), ["not a set"]),
    ],
)
def test_combinations_outside_the_papers_form_are_clear_errors(build, words):
    with pytest.raises(SetStructureError) as caught:
        build()
    message = str(caught.value)
    for word in words:
        assert word in message, message


def test_model_level_errors_name_the_model_and_the_block():
    with pytest.raises(SetStructureError, match="one dimension"):
        (0, 0) + Sgn(x1)  # a sign term lives in one coordinate
    with pytest.raises(SetStructureError, match="R\\^2"):
        compile_sets({(x1, x2): Interval(0, 1)}, (x1, x2))
    with pytest.raises(qdframe.InputError, match="formulas in the states"):
        compile_sets({x1: x3}, (x1, x2))
    with pytest.raises(qdframe.InputError, match="keys that are states"):
        compile_sets({x3: 1}, (x1, x2))
    with pytest.raises(qdframe.InputError, match="surface"):
        compile_sets({x1: 1}, (x1,), (u,), surface=u)
    with pytest.raises(SetStructureError, match="amplitude"):
        compile_sets({x1: (Abs(x1) - Abs(u)) * Sgn(x1)}, (x1,), (u,))


def test_cost_groups_follow_the_signs_of_their_terms():
    compiled = compile_sets({x1: 0}, (x1, x2), cost=2 * Abs(x1) - Abs(x2) + Max(x1, 0) + 3 * Min(x1, x2) + x2**2, weight=4)
    cost = compiled.cost
    assert cost.weight == 4 and len(cost.max_groups) == 3 and len(cost.min_groups) == 2
    y = np.array([[0.7, -1.3]])
    total = sum(fn(y)[0].max(axis=1) for fn in cost.max_groups) + sum(fn(y)[0].min(axis=1) for fn in cost.min_groups)
    assert total[0] == pytest.approx(2 * 0.7 - 1.3 + 0.7 + 3 * -1.3 + 1.69)


def test_set_model_class_attributes_and_define_model():
    class Tiny(SetModel):
        """x' ∈ [1 − |x|, 1 + |x|]."""

        state_names = "x"
        default_x0 = (0.0,)
        default_xT = {"x": 1.5}

        def sets(self, x):
            return {x: 1 + Abs(x) * Interval(-1, 1)}

    model = Tiny()
    assert model.name == "Tiny" and model.description == "x' ∈ [1 − |x|, 1 + |x|]."
    assert model.state_names == ("x",) and model.end_indices == (0,) and list(model.end_values) == [1.5]
    assert qdframe.solve(model, nodes=51).status == "solved"
    Spread = define_model("spread", "x", lambda x: {x: 1 + Abs(x) * Interval(-1, 1)}, x0=(0.0,), xT={"x": 1.5})
    assert qdframe.solve(Spread(), nodes=51).status == "solved"
    with pytest.raises(qdframe.InputError, match="default_xT"):
        type("Bad", (SetModel,), {"state_names": "x", "default_xT": {"y": 1.0}})


def test_controls_and_surfaces_compile_with_gradients_in_y():
    compiled = compile_sets({x1: x2 + u, x2: -x1 - 0.3 * Sgn(x2)}, (x1, x2), (u,), surface=[x1 + x2])
    e, de = compiled.surface.function(np.array([[1.0, 2.0]]))
    assert e.shape == (1, 1) and np.allclose(de, [[[1.0, 1.0]]])
    f, jac = compiled.blocks[0].max_groups[0].pieces(np.array([[1.0, 2.0, 3.0]]))
    assert f[0, 0, 0] == 5.0 and np.allclose(jac[0, 0, 0], [0.0, 1.0, 1.0])


def test_interval_of_min_and_max_of_the_same_formulas_is_their_hull():
    import sympy

    from qdframe.sets import Hull, Interval, hull

    x1, x2, x3 = sympy.symbols("x1 x2 x3")
    spelled = Interval(sympy.Min(x1, x2, x3), sympy.Max(x3, x2, x1))
    assert isinstance(spelled, Hull)
    assert spelled.polytope() == hull(x1, x2, x3).polytope()


def test_interval_with_a_kinked_end_points_to_hull():
    import sympy

    from qdframe.sets import Interval

    x1, x2, x3 = sympy.symbols("x1 x2 x3")
    with pytest.raises(SetStructureError, match=r"hull\(e_1, …, e_m\)"):
        Interval(sympy.Min(x1, x2), sympy.Max(x2, x3))
