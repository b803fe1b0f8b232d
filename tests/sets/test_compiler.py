"""The compiler (qdframe/sets/compiler.py): costs, controls and surfaces become pieces with
gradients in y = (x, u)."""

import numpy as np
import pytest
import sympy as sp

from qdframe.sets import Abs, Max, Min, Sgn, compile_sets

x1, x2, x3, u = sp.symbols("x1 x2 x3 u", real=True)


def test_cost_groups_follow_the_signs_of_their_terms():
    compiled = compile_sets({x1: 0}, (x1, x2), cost=2 * Abs(x1) - Abs(x2) + Max(x1, 0) + 3 * Min(x1, x2) + x2**2, weight=4)
    cost = compiled.cost
    assert cost.weight == 4 and len(cost.max_groups) == 3 and len(cost.min_groups) == 2
    y = np.array([[0.7, -1.3]])
    total = sum(fn(y)[0].max(axis=1) for fn in cost.max_groups) + sum(fn(y)[0].min(axis=1) for fn in cost.min_groups)
    assert total[0] == pytest.approx(2 * 0.7 - 1.3 + 0.7 + 3 * -1.3 + 1.69)


def test_controls_and_surfaces_compile_with_gradients_in_y():
    compiled = compile_sets({x1: x2 + u, x2: -x1 - 0.3 * Sgn(x2)}, (x1, x2), (u,), surface=[x1 + x2])
    e, de = compiled.surface.function(np.array([[1.0, 2.0]]))
    assert e.shape == (1, 1) and np.allclose(de, [[[1.0, 1.0]]])
    f, jac = compiled.blocks[0].max_groups[0].pieces(np.array([[1.0, 2.0, 3.0]]))
    assert f[0, 0, 0] == 5.0 and np.allclose(jac[0, 0, 0], [0.0, 1.0, 1.0])
