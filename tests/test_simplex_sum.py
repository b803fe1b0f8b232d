"""SimplexSum.compact: the same polytopes per node, in fewer and narrower groups."""

import numpy as np
import pytest

from qdframe.functional.quasidifferential import SimplexSum


@pytest.mark.parametrize("seed", range(6))
def test_compact_keeps_every_polytope(seed):
    """Support functions in random directions equal before and after, one-generator groups
    are folded into the center, and every kept group lists its active generators first."""
    rng = np.random.default_rng(seed)
    n, groups, width, d = 9, 5, 3, 4
    generators = rng.normal(size=(n, groups, width, d))
    mask = rng.random((n, groups, width)) < 0.6
    mask[:, :, 0] |= ~mask.any(axis=2)  # every group has an active generator
    mask[:, 1] = False  # group 1 has one active generator at every node, in varying slots
    mask[np.arange(n), 1, rng.integers(0, width, size=n)] = True
    mask[:, 3] = False
    mask[:, 3, 2] = True  # group 3: one, always in the last slot
    polytopes = SimplexSum(rng.normal(size=(n, d)), generators, mask)
    compact = polytopes.compact()
    single = (mask.sum(axis=2) <= 1).all(axis=0)
    assert single[1] and single[3] and compact.generators.shape[1] == groups - single.sum()
    for direction in rng.normal(size=(20, n, d)):
        assert np.allclose(compact.support(direction), polytopes.support(direction), rtol=0, atol=1e-12)
        assert np.allclose(compact.lower_support(direction), polytopes.lower_support(direction), rtol=0, atol=1e-12)
    counts = compact.mask.sum(axis=2)
    assert np.array_equal(compact.mask, np.arange(compact.mask.shape[2])[None, None, :] < counts[..., None])


def test_compact_with_only_single_groups_leaves_a_point():
    rng = np.random.default_rng(0)
    generators = rng.normal(size=(4, 2, 3, 2))
    mask = np.zeros((4, 2, 3), dtype=bool)
    mask[:, 0, 1] = mask[:, 1, 2] = True
    compact = SimplexSum(np.zeros((4, 2)), generators, mask).compact()
    assert compact.generators.shape == (4, 0, 1, 2)
    assert np.array_equal(compact.center, generators[:, 0, 1] + generators[:, 1, 2])
