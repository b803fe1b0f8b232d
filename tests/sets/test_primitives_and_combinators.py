"""The primitive sets (qdframe/sets/primitives.py) and the combinators (algebra.py):
each compiles to the support function of its definition."""

import numpy as np
import pytest
import sympy as sp

from qdframe.model import SetBlock
from qdframe.sets import (
    Abs, Ball, Box, Ellipse, Interval, SetStructureError, Sgn, compile_sets, hull, intersection, norm1,
)

x1, x2, x3, u = sp.symbols("x1 x2 x3 u", real=True)


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
