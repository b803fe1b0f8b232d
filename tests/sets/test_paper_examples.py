"""The paper's Examples 7.1–7.3 in the set language (qdframe/models/paper_sets.py) give the
hand-written models' (qdframe/models/paper.py, paper_73.py) functional, quasidifferential and solves."""

import numpy as np
import pytest

import qdframe
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.models.paper_sets import Paper71Sets, Paper72Sets, Paper73Sets

PAIRS = [(Paper71Sets, "paper-7.1"), (Paper72Sets, "paper-7.2"), (Paper73Sets, "paper-7.3")]


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
    options = dict(nodes=31, scheme="trapezoid", signs="band", estimate=False)  # the descents, compared
    mine, theirs = qdframe.solve(layer(), **options), qdframe.solve(name, **options)
    assert mine.status == theirs.status and mine.converged
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
