"""Tests of qdframe.directions.minnorm.min_norm_point against an independent brute force."""

from __future__ import annotations

import itertools
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.configuration import set_hypothesis_home_dir
from hypothesis.extra.numpy import arrays

# the same examples on every run and every machine (a seed from each test's own code), and no
# example database or constants cache written into the repository (Hypothesis' home is a temp dir)
set_hypothesis_home_dir(str(Path(tempfile.gettempdir()) / "qdframe-hypothesis"))
PROPERTY = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True, database=None)

from qdframe.directions import minnorm
from qdframe.directions.minnorm import min_norm_point

# ------------------------------------------------------------------------ reference


def reference_row(center: np.ndarray, generators: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Brute force for one row: every combination of nonempty subsets of the active
    entries of every group, each solved as a least-squares problem with np.linalg.lstsq
    after eliminating the constraints Σ_p λ_gp = 1 (λ_base = 1 − Σ others); keeps the
    feasible candidate (λ ≥ −1e-12) of least norm. Returns (point, weights)."""
    groups, width, _ = generators.shape
    subsets = []
    for g in range(groups):
        entries = [p for p in range(width) if mask[g, p]]
        subsets.append([s for r in range(1, len(entries) + 1) for s in itertools.combinations(entries, r)])
    best_value, best = np.inf, None
    for pattern in itertools.product(*subsets):
        base_point = center + sum((generators[g, s[0]] for g, s in enumerate(pattern)), np.zeros_like(center))
        free = [(g, p) for g, s in enumerate(pattern) for p in s[1:]]
        weights = np.zeros((groups, width))
        for g, s in enumerate(pattern):
            weights[g, s[0]] = 1.0
        if free:
            columns = np.array([generators[g, p] - generators[g, pattern[g][0]] for g, p in free]).T
            mu = np.linalg.lstsq(columns, -base_point, rcond=None)[0]
            for (g, p), value in zip(free, mu):
                weights[g, p] += value
                weights[g, pattern[g][0]] -= value
        if weights.min(initial=0.0) < -1e-12:
            continue
        point = center + np.einsum("gp,gpd->d", weights, generators)
        if point @ point < best_value:
            best_value, best = point @ point, (point, weights)
    return best


def row_scale(center: np.ndarray, generators: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Largest absolute entry of each row's data (center and active generators)."""
    active = np.where(mask[..., None], np.abs(generators), 0.0).reshape(len(center), -1)
    return np.maximum(np.abs(center).max(axis=1), active.max(axis=1, initial=0.0))


def assert_matches_reference(center, generators, mask, points, rows=None) -> None:
    scale = row_scale(center, generators, mask)
    for b in range(len(center)) if rows is None else rows:
        expected, _ = reference_row(center[b], generators[b], mask[b])
        got = np.linalg.norm(points[b])
        assert got == pytest.approx(np.linalg.norm(expected), rel=1e-9, abs=1e-12 * scale[b]), f"row {b}"
        assert np.linalg.norm(points[b] - expected) <= 1e-8 * scale[b], f"row {b}"


def assert_kkt(center, generators, mask, points, weights, tol: float = 1e-9) -> None:
    """Feasibility, consistency and the optimality condition of every row."""
    rows, groups, width, dim = generators.shape
    assert points.shape == (rows, dim) and weights.shape == (rows, groups, width)
    scale = row_scale(center, generators, mask)
    assert np.all(weights >= -1e-12)
    assert np.all(weights[~mask] == 0.0)
    if groups:
        np.testing.assert_allclose(weights.sum(axis=2), 1.0, rtol=0, atol=1e-12)
    safe = np.where(mask[..., None], generators, 0.0)
    recomputed = center + np.einsum("bgp,bgpd->bd", weights, safe)
    assert np.all(np.abs(points - recomputed) <= 1e-12 * (scale[:, None] + np.abs(points)) * (groups + 1))
    values = np.einsum("bgpd,bd->bgp", safe, points)  # <a_gp, y>
    lowest = np.where(mask, values, np.inf).min(axis=2, initial=np.inf)
    used = weights > 1e-9
    excess = np.where(used, values - lowest[..., None], -np.inf)
    limit = tol * scale[:, None, None] ** 2
    assert np.all(excess <= limit), f"KKT violated by {np.max(excess - limit)}"


def random_instance(rng, rows, groups, width, dim, density=1.0):
    center = rng.normal(size=(rows, dim))
    generators = rng.normal(size=(rows, groups, width, dim))
    mask = rng.random((rows, groups, width)) < density
    mask[np.arange(rows)[:, None], np.arange(groups), rng.integers(0, width, (rows, groups))] = True
    return center, generators, mask


def solve_and_check(center, generators, mask, reference_rows=None):
    points, weights = min_norm_point(center, generators, mask)
    assert_kkt(center, generators, mask, points, weights)
    assert_matches_reference(center, generators, mask, points, reference_rows)
    return points, weights


# ------------------------------------------------------------------- known answers


def test_answer_at_a_vertex():
    generators = np.array([[[[1.0, 1.0], [2.0, 1.0], [1.0, 3.0]]]])
    points, weights = min_norm_point(np.zeros((1, 2)), generators, np.ones((1, 1, 3), bool))
    np.testing.assert_allclose(points, [[1.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(weights, [[[1.0, 0.0, 0.0]]], atol=1e-15)


def test_answer_on_an_edge():
    generators = np.array([[[[1.0, -1.0], [1.0, 1.0], [3.0, 0.0]]]])
    points, weights = min_norm_point(np.zeros((1, 2)), generators, np.ones((1, 1, 3), bool))
    np.testing.assert_allclose(points, [[1.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(weights, [[[0.5, 0.5, 0.0]]], atol=1e-15)


def test_answer_in_the_interior():
    generators = np.array([[[[2.0, 0.0], [-1.0, 1.0], [-1.0, -1.0]]]])
    center = np.array([[0.0, 0.0]])
    points, weights = min_norm_point(center, generators, np.ones((1, 1, 3), bool))
    np.testing.assert_allclose(points, 0.0, atol=1e-15)
    np.testing.assert_allclose(weights, [[[1 / 3, 1 / 3, 1 / 3]]], atol=1e-15)


def test_answer_in_a_minkowski_sum_of_segments():
    # center + [-1, 1] × [-1, 1] = [2, 4] × [-0.5, 1.5]: nearest point (2, 0).
    center = np.array([[3.0, 0.5]])
    generators = np.array([[[[-1.0, 0.0], [1.0, 0.0]], [[0.0, -1.0], [0.0, 1.0]]]])
    points, weights = min_norm_point(center, generators, np.ones((1, 2, 2), bool))
    np.testing.assert_allclose(points, [[2.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(weights, [[[1.0, 0.0], [0.75, 0.25]]], atol=1e-15)


def test_no_groups_returns_the_center():
    center = np.random.default_rng(0).normal(size=(5, 3))
    points, weights = min_norm_point(center, np.zeros((5, 0, 2, 3)), np.zeros((5, 0, 2), bool))
    np.testing.assert_array_equal(points, center)
    assert weights.shape == (5, 0, 2)


def test_single_active_groups_fold_into_the_center():
    rng = np.random.default_rng(1)
    center, generators, _ = random_instance(rng, 50, 3, 3, 4)
    mask = np.zeros((50, 3, 3), bool)
    mask[np.arange(50)[:, None], np.arange(3), rng.integers(0, 3, (50, 3))] = True
    points, weights = min_norm_point(center, generators, mask)
    np.testing.assert_array_equal(weights, mask.astype(float))
    np.testing.assert_allclose(points, center + np.einsum("bgp,bgpd->bd", mask, generators), rtol=1e-14)


# --------------------------------------------------------------------- random data


@pytest.mark.parametrize(
    "rows, groups, width, dim, density",
    [
        (300, 1, 2, 4, 1.0),
        (300, 1, 4, 3, 1.0),
        (100, 2, 3, 8, 1.0),
        (60, 3, 3, 2, 0.7),
        (100, 2, 4, 3, 0.6),
        (80, 4, 2, 5, 1.0),
        (100, 3, 2, 1, 1.0),
        (100, 2, 3, 20, 0.8),
    ],
)
def test_random_instances_match_the_reference(rows, groups, width, dim, density):
    rng = np.random.default_rng(rows * 1000 + groups * 100 + width * 10 + dim)
    solve_and_check(*random_instance(rng, rows, groups, width, dim, density))


def test_mixed_masks_with_single_and_full_groups():
    rng = np.random.default_rng(7)
    center, generators, mask = random_instance(rng, 200, 3, 3, 3, density=0.5)
    mask[:, 0] = False
    mask[:, 0, 1] = True  # group 0 is a single point everywhere (folded)
    mask[::2, 2] = True  # group 2 full on even rows
    solve_and_check(center, generators, mask)


def test_masked_entries_are_ignored():
    rng = np.random.default_rng(8)
    center, generators, mask = random_instance(rng, 100, 2, 3, 3, density=0.6)
    points, weights = min_norm_point(center, generators, mask)
    garbage = generators.copy()
    garbage[~mask] = np.nan
    garbage_points, garbage_weights = min_norm_point(center, garbage, mask)
    np.testing.assert_array_equal(points, garbage_points)
    np.testing.assert_array_equal(weights, garbage_weights)


def test_large_batch_against_a_subsample():
    rng = np.random.default_rng(9)
    center, generators, mask = random_instance(rng, 20000, 2, 3, 5, density=0.8)
    points, weights = min_norm_point(center, generators, mask)
    assert_kkt(center, generators, mask, points, weights)
    assert_matches_reference(center, generators, mask, points, rng.choice(20000, 100, replace=False))


@pytest.mark.parametrize("scale", [1e-8, 1e8])
def test_scale_invariance(scale):
    rng = np.random.default_rng(10)
    center, generators, mask = random_instance(rng, 200, 2, 3, 4, density=0.8)
    points, weights = min_norm_point(center, generators, mask)
    scaled_points, scaled_weights = solve_and_check(center * scale, generators * scale, mask)
    np.testing.assert_allclose(scaled_points / scale, points, rtol=0, atol=1e-12)
    np.testing.assert_allclose(scaled_weights, weights, rtol=0, atol=1e-9)


def test_rows_of_very_different_scales_in_one_batch():
    rng = np.random.default_rng(11)
    center, generators, mask = random_instance(rng, 90, 2, 3, 3)
    factors = 10.0 ** rng.integers(-9, 9, 90)
    solve_and_check(center * factors[:, None], generators * factors[:, None, None, None], mask)


# ----------------------------------------------------------------- degenerate data


def test_duplicate_generators():
    rng = np.random.default_rng(12)
    center, generators, mask = random_instance(rng, 30, 2, 4, 3)
    generators[:, 0, 1] = generators[:, 0, 0]
    generators[:, 1, 3] = generators[:, 1, 0]
    generators[:, 1, 2] = generators[:, 0, 2]  # duplicated across groups too
    solve_and_check(center, generators, mask)


def test_whole_group_identical():
    rng = np.random.default_rng(13)
    center, generators, mask = random_instance(rng, 100, 2, 3, 3)
    generators[:, 1] = generators[:, 1, :1]
    solve_and_check(center, generators, mask)


def test_collinear_generators():
    rng = np.random.default_rng(14)
    center, generators, mask = random_instance(rng, 30, 2, 4, 3)
    start, step = rng.normal(size=(30, 1, 3)), rng.normal(size=(30, 1, 3))
    generators[:, 0] = start + np.array([0.0, 1.0, 2.5, -0.7])[:, None] * step
    generators[:, 1, :3] = generators[:, 1, :1] + np.array([0.0, 1.0, -2.0])[:, None] * step
    solve_and_check(center, generators, mask)


def test_collinear_points_through_the_origin():
    # The segment passes through the origin: the answer is 0 with non-unique weights.
    direction = np.array([1.0, 2.0, -1.0])
    generators = np.array([[[-1.0 * direction, 0.5 * direction, 2.0 * direction]]])
    points, weights = solve_and_check(np.zeros((1, 3)), generators, np.ones((1, 1, 3), bool))
    np.testing.assert_allclose(points, 0.0, atol=1e-15)


def test_origin_as_a_generator():
    rng = np.random.default_rng(15)
    center, generators, mask = random_instance(rng, 60, 2, 3, 3)
    generators[:, 0, 1] = 0.0
    generators[::2, 1, 2] = 0.0
    solve_and_check(center, generators, mask)
    points, _ = solve_and_check(np.zeros_like(center), generators, mask)
    # With center 0, the origin is in the set when both zero generators are active.
    contains_origin = mask[:, 0, 1] & mask[:, 1, 2] & (np.arange(60) % 2 == 0)
    assert contains_origin.sum() > 5
    assert np.all(np.abs(points[contains_origin]) <= 1e-15)


def test_lower_dimensional_sets_in_high_dimension():
    # All generators in a 2-plane of R^6: every pattern with 3+ directions is singular.
    rng = np.random.default_rng(16)
    basis = rng.normal(size=(6, 2))
    center = rng.normal(size=(20, 6))
    generators = rng.normal(size=(20, 3, 3, 2)) @ basis.T
    solve_and_check(center, generators, np.ones((20, 3, 3), bool))


def test_all_zero_data():
    points, weights = min_norm_point(np.zeros((3, 2)), np.zeros((3, 2, 2, 2)), np.ones((3, 2, 2), bool))
    np.testing.assert_array_equal(points, 0.0)
    np.testing.assert_allclose(weights.sum(axis=2), 1.0)


def test_answer_exactly_at_a_vertex_in_a_degenerate_sum():
    # Minkowski sum of two identical triangles: the answer is twice the nearest vertex.
    triangle = np.array([[1.0, 1.0], [2.0, 1.0], [1.0, 3.0]])
    generators = np.stack([triangle, triangle])[None]
    points, weights = min_norm_point(np.zeros((1, 2)), generators, np.ones((1, 2, 3), bool))
    np.testing.assert_allclose(points, [[2.0, 2.0]], atol=1e-15)
    np.testing.assert_allclose(weights, [[[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]], atol=1e-15)


def tiny_edge_instance():
    """Rows whose answer (r, 0, 0) lies on an edge of length ε = 2^-k ≪ r (nearly
    equal generators); all data are exactly representable. Returns the data, the
    answers and ε per row.

    A vertex of the edge is only ~ε from the answer and its norm differs from the
    optimum by ~ε², below rounding for ε < 1e-8: comparing norms alone cannot find
    the answer, the solver needs the optimality condition.
    """
    rows, edges = [], []
    for k, split, r in itertools.product(range(12, 42, 2), (0.125, 0.5, 0.875), (0.75, 1.0, 3.0)):
        eps = 2.0**-k
        rows.append([[r, -split * eps, 0.0], [r, (1 - split) * eps, 0.0], [r + 1.0, 0.3, 0.2]])
        edges.append(eps)
    generators = np.array(rows)[:, None]
    expected = np.zeros((len(rows), 3))
    expected[:, 0] = generators[:, 0, 0, 0]
    return np.zeros((len(rows), 3)), generators, np.ones((len(rows), 1, 3), bool), expected, np.array(edges)


@pytest.mark.parametrize("cap", [minnorm.PATTERN_CAP, 0])
def test_answer_on_a_tiny_edge(monkeypatch, cap):
    monkeypatch.setattr(minnorm, "PATTERN_CAP", cap)
    center, generators, mask, expected, edge = tiny_edge_instance()
    points, weights = min_norm_point(center, generators, mask)
    assert_kkt(center, generators, mask, points, weights)
    error = np.linalg.norm(points - expected, axis=1)
    assert np.all(error[edge >= 2.0**-26] <= 1e-13)
    assert np.all(error <= 1e-11)  # ~ the optimality tolerance (1e-12 of the scale) as ε → 0


# ------------------------------------------------------ many patterns: active-set path
# PATTERN_CAP = 0 forces the gradient warm start + active-set method with no
# enumeration at all, so these tests check that path on its own.


@pytest.mark.parametrize("degenerate", [False, True])
def test_active_set_path_matches_the_reference(monkeypatch, degenerate):
    monkeypatch.setattr(minnorm, "PATTERN_CAP", 0)
    rng = np.random.default_rng(17)
    center, generators, mask = random_instance(rng, 40, 3, 3, 3, density=0.8)
    if degenerate:
        generators[:, 0, 1] = generators[:, 0, 0]
        generators[:, 1, 2] = 0.0
    solve_and_check(center, generators, mask)


def test_active_set_path_when_the_origin_is_inside():
    # Low dimension, many generators: y = 0 with very non-unique weights.
    rng = np.random.default_rng(22)
    center, generators, mask = random_instance(rng, 300, 6, 4, 2)
    assert minnorm._support_patterns(mask.any(axis=0), 2, minnorm.PATTERN_CAP) is None
    points, weights = min_norm_point(center, generators, mask)
    assert_kkt(center, generators, mask, points, weights)
    assert np.mean(np.linalg.norm(points, axis=1) < 1e-14) > 0.5


def test_too_many_patterns_stay_optimal():
    rng = np.random.default_rng(18)
    center, generators, mask = random_instance(rng, 40, 6, 4, 20)
    assert minnorm._support_patterns(mask.any(axis=0), 20, minnorm.PATTERN_CAP) is None
    points, weights = min_norm_point(center, generators, mask)
    assert_kkt(center, generators, mask, points, weights)


def test_rows_stopped_by_the_step_cap_are_solved_by_enumeration(monkeypatch):
    monkeypatch.setattr(minnorm, "_DIRECT_PATTERNS", 0)
    monkeypatch.setattr(minnorm, "_POLISH_STEPS", 1)
    rng = np.random.default_rng(23)
    solve_and_check(*random_instance(rng, 60, 2, 3, 3, density=0.8))


def test_without_enumeration_the_step_cap_leaves_feasible_but_not_optimal_rows(monkeypatch):
    # Also shows that the KKT checker of these tests does catch wrong answers.
    monkeypatch.setattr(minnorm, "PATTERN_CAP", 0)
    monkeypatch.setattr(minnorm, "_WARM_START_ITERATIONS", 0)
    monkeypatch.setattr(minnorm, "_POLISH_STEPS", 1)
    rng = np.random.default_rng(24)
    center, generators, mask = random_instance(rng, 60, 2, 3, 3, density=0.8)
    points, weights = min_norm_point(center, generators, mask)
    assert np.all(weights >= 0.0) and np.all(weights[~mask] == 0.0)
    np.testing.assert_allclose(weights.sum(axis=2), 1.0, atol=1e-12)
    with pytest.raises(AssertionError, match="KKT"):
        assert_kkt(center, generators, mask, points, weights)


# ----------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    "change, name",
    [
        (lambda c, a, m: (c[0], a, m), "center"),
        (lambda c, a, m: (c, a[:, :, :, :1], m), "generators"),
        (lambda c, a, m: (c, a[:1], m), "generators"),
        (lambda c, a, m: (c, a, m[:, :, :1]), "mask"),
        (lambda c, a, m: (c, a, m.astype(int)), "mask"),
        (lambda c, a, m: (c, a, np.zeros_like(m)), "mask"),
        (lambda c, a, m: (np.where(c > 0, np.inf, c), a, m), "center"),
        (lambda c, a, m: (c, np.where(a > 0, np.nan, a), m), "generators"),
        (lambda c, a, m: (c.astype(complex), a, m), "center"),
    ],
)
def test_bad_input_raises_value_error_naming_the_argument(change, name):
    rng = np.random.default_rng(19)
    center, generators, mask = random_instance(rng, 4, 2, 3, 2)
    with pytest.raises(ValueError, match=name):
        min_norm_point(*change(center, generators, mask))


def test_one_empty_group_is_rejected():
    center, generators, mask = random_instance(np.random.default_rng(20), 4, 2, 3, 2)
    mask[2, 1] = False
    with pytest.raises(ValueError, match="mask"):
        min_norm_point(center, generators, mask)


@pytest.mark.parametrize("dim", [1, 3])
def test_inputs_are_not_modified(dim):
    center, generators, mask = random_instance(np.random.default_rng(21), 30, 2, 3, dim, density=0.7)
    center, generators = center * 5.0, generators * 5.0  # not a power of two: scaling would show
    copies = center.copy(), generators.copy(), mask.copy()
    min_norm_point(center, generators, mask)
    for before, after in zip(copies, (center, generators, mask)):
        np.testing.assert_array_equal(before, after)


# ----------------------------------------------------------------------- properties


@st.composite
def instances(draw, max_rows=3):
    """Small instances on an integer grid (many ties, duplicates and degeneracies)."""
    rows = draw(st.integers(1, max_rows))
    groups = draw(st.integers(0, 3))
    width = draw(st.integers(1, 3))
    dim = draw(st.integers(1, 4))
    values = st.integers(-3, 3).map(float)
    center = draw(arrays(float, (rows, dim), elements=values))
    generators = draw(arrays(float, (rows, groups, width, dim), elements=values))
    mask = draw(arrays(bool, (rows, groups, width)))
    mask[..., 0] |= ~mask.any(axis=2)
    scale = draw(st.sampled_from([1.0, 1e-8, 1e8, 0.37]))
    return center * scale, generators * scale, mask


def vertices(center, generators, mask):
    """Every center + Σ_g a_{g, p_g} over active choices, for one row."""
    groups, width, _ = generators.shape
    for choice in itertools.product(range(width), repeat=groups):
        if all(mask[g, p] for g, p in enumerate(choice)):
            yield center + sum((generators[g, p] for g, p in enumerate(choice)), np.zeros_like(center))


@settings(max_examples=150, **PROPERTY)
@given(instances())
def test_property_feasible_optimal_and_no_longer_than_any_vertex(instance):
    center, generators, mask = instance
    points, weights = min_norm_point(center, generators, mask)
    assert_kkt(center, generators, mask, points, weights)
    scale = row_scale(center, generators, mask)
    for b in range(len(center)):
        shortest = min(np.linalg.norm(v) for v in vertices(center[b], generators[b], mask[b]))
        assert np.linalg.norm(points[b]) <= shortest + 1e-12 * scale[b]


@settings(max_examples=100, **PROPERTY)
@given(instances(max_rows=2))
def test_property_matches_the_reference(instance):
    center, generators, mask = instance
    points, _ = min_norm_point(center, generators, mask)
    assert_matches_reference(center, generators, mask, points)


@settings(max_examples=60, **PROPERTY)
@given(instances(max_rows=2))
def test_property_fallback_is_optimal_too(instance):
    center, generators, mask = instance
    original = minnorm.PATTERN_CAP
    minnorm.PATTERN_CAP = 0
    try:
        points, weights = min_norm_point(center, generators, mask)
    finally:
        minnorm.PATTERN_CAP = original
    assert_kkt(center, generators, mask, points, weights)
    assert_matches_reference(center, generators, mask, points)


def test_groups_of_one_repeated_point_above_the_enumeration_limit():
    """Every group's active entries are one point repeated, with > 64 support patterns: the
    iterative path must stay finite and exact (it divided by zero when a whole group blocked)."""
    rng = np.random.default_rng(0)
    center = rng.normal(size=(1000, 2))
    generators = rng.normal(size=(1000, 4, 1, 2)).repeat(3, axis=2)
    mask = np.ones((1000, 4, 3), dtype=bool)
    points, weights = min_norm_point(center, generators, mask)
    assert np.all(np.isfinite(points)) and np.all(np.isfinite(weights))
    expected = center + generators[:, :, 0, :].sum(axis=1)  # each group is a single point
    np.testing.assert_allclose(points, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(weights.sum(axis=2), 1.0, atol=1e-12)


def test_a_direction_entry_at_rounding_on_a_kink_is_zero_and_the_direction_descends():
    """Paper-7.1 near its solution (ε = 1e-8): x1 ≈ 5e-10 at a node, so both pieces of |x1| are
    δ-active, and the min-norm point's x1 entry is 0 up to rounding. Kept, that rounding
    (3e-17) times the kink's generators (±1) outweighed ‖G‖² ≈ 2e-18 and the direction ascended."""
    import numpy as np

    from qdframe.registry import make_direction
    from qdframe.functional.quasidifferential import Quasidifferential, SimplexSum

    center = np.array([[1.77761619e-08, 4.32537339e-11, -3.08350642e-11, -1.39695075e-09]])
    generators = np.array([[[[1.0, 0.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0]]]])
    sub = SimplexSum(center, generators, np.ones((1, 1, 2), dtype=bool))
    sup = SimplexSum(np.array([[6.70075107e-10, 0.0, 0.0, 0.0]]), np.zeros((1, 0, 1, 4)), np.zeros((1, 0, 1), dtype=bool))
    direction = make_direction("native").from_quasidifferential(Quasidifferential(sub, sup), np.array([0.05]))
    assert direction.step[0, 0] == 0.0
    assert np.allclose(direction.step[0, 1:], -center[0, 1:], rtol=1e-12, atol=0)
    assert direction.slope < 0 and direction.slope == pytest.approx(-0.05 * np.sum(direction.step**2), rel=1e-9)


def test_the_property_tests_are_derandomized_and_write_nothing():
    """Issue 56: an unseeded run drew other examples on every machine and wrote `.hypothesis/`
    into the repository root."""
    tests = [value for value in globals().values() if hasattr(value, "hypothesis")]
    assert len(tests) == 3
    for test in tests:
        chosen = test._hypothesis_internal_use_settings
        assert chosen.derandomize and chosen.database is None, test.__name__
    from hypothesis.configuration import storage_directory

    root = Path(__file__).resolve().parents[2]
    assert root not in Path(storage_directory("constants").path).resolve().parents
