"""ψ* on S_k (qdframe.functional.psi): the chunked, memoized search gives the same ψ*, the same
δ-active pieces and the same solves as the original batched scan, kept here as the reference;
and the same ψ*, bit for bit, as the chunked search before the scan reused the warm check's
samples and the golden searches their known values (`previous_maximize`), with fewer
evaluations of ℓ."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import qdframe
import qdframe.functional.pieces as functional_module  # where ψ* is searched
from qdframe.functional import Functional
from qdframe.functional.assembly import _delta_active
from qdframe.schemes.grid import Grid
from qdframe.models.paper_sets import Paper72Sets
from qdframe.functional.psi import (CHECK_STRIDE, CHUNK, EDGE, _angle, _tangent_basis, maximize_on_sphere,
                                    sphere_samples)
from qdframe.sets import Ball, SetModel, intersection

S2_MODELS = ["paper-7.2", "paper-7.2-sets", "intersecting-balls"]  # intersecting-balls: qdframe-mechanics


def reference_maximize(objective, nodes, k, samples=128, sweeps=None, iterations=40, start=None):
    """The search before chunking and warm starts (`start` ignored): all samples of S_k in one
    call of ℓ, then golden refinement."""
    grid = sphere_samples(k, samples)
    values = objective(np.broadcast_to(grid, (nodes, samples, k)))
    psi = grid[np.argmax(values, axis=1)]
    spacing = 2.0 * np.pi / samples if k == 2 else np.pi / samples ** (1.0 / (k - 1))
    sweeps = (1 if k == 2 else 4) if sweeps is None else sweeps
    for sweep in range(sweeps):
        width = 2.0 * spacing / (4.0**sweep)
        for tangent in _tangent_basis(psi):
            psi = _previous_golden(objective, psi, tangent, width, iterations)
    return psi


def previous_maximize(objective, nodes, k, samples=128, sweeps=None, iterations=40, start=None):
    """The chunked search with warm starts as it was before the cold scan reused the check's
    samples and the golden searches the values known at their start: the oracle, bit for bit."""
    grid = sphere_samples(k, samples)
    spacing = 2.0 * np.pi / samples if k == 2 else np.pi / samples ** (1.0 / (k - 1))
    sweeps = (1 if k == 2 else 4) if sweeps is None else sweeps

    def restricted(at):
        return objective if at is None or at.size == nodes else (lambda p: objective(p, at))

    def refine(psi, at):
        for sweep in range(sweeps):
            for tangent in _tangent_basis(psi):
                psi = _previous_golden(restricted(at), psi, tangent, 2.0 * spacing / (4.0**sweep), iterations)
        return psi

    if start is None or start.shape != (nodes, k):
        return refine(grid[_previous_best(objective, grid, nodes)[0]], None)
    check = grid[::CHECK_STRIDE] if k == 2 else sphere_samples(k, max(8, samples // CHECK_STRIDE))
    index, top = _previous_best(objective, check, nodes)
    psi = np.array(start, dtype=float)
    warm = np.flatnonzero(_angle(check[index], psi) <= CHECK_STRIDE * spacing)
    if warm.size:
        psi[warm] = refine(psi[warm], warm)
        value = restricted(warm)(psi[warm][:, None, :])[:, 0]
        with np.errstate(invalid="ignore"):
            lost = (value < top[warm]) | (_angle(psi[warm], start[warm]) > EDGE * 2.0 * spacing) | ~np.isfinite(value)
        warm = warm[~lost]
    cold = np.setdiff1d(np.arange(nodes), warm)
    if cold.size:
        psi[cold] = refine(grid[_previous_best(restricted(cold), grid, cold.size)[0]], cold)
    return psi


def _previous_best(objective, grid, nodes):
    count, k = grid.shape
    step = max(1, min(count, CHUNK // max(nodes, 1)))
    best, top = np.zeros(nodes, dtype=int), np.full(nodes, -np.inf)
    for start in range(0, count, step):
        values = objective(np.broadcast_to(grid[start : start + step], (nodes, min(step, count - start), k)))
        for column in range(values.shape[1]):
            value = values[:, column]
            better = (value > top) | (np.isnan(value) & ~np.isnan(top))
            best[better], top[better] = start + column, value[better]
    return best, top


def _previous_golden(objective, psi, tangent, width, iterations):
    def point(theta):
        return psi * np.cos(theta)[:, None] + tangent * np.sin(theta)[:, None]

    def value(theta):
        return objective(point(theta)[:, None, :])[:, 0]

    golden = (np.sqrt(5.0) - 1.0) / 2.0
    lo, hi = np.full(psi.shape[0], -width), np.full(psi.shape[0], width)
    a, b = hi - golden * (hi - lo), lo + golden * (hi - lo)
    fa, fb = value(a), value(b)
    for _ in range(iterations):
        left = fa >= fb
        hi, lo = np.where(left, b, hi), np.where(left, lo, a)
        new_a, new_b = np.where(left, hi - golden * (hi - lo), b), np.where(left, a, lo + golden * (hi - lo))
        f_moved = value(np.where(left, new_a, new_b))
        fa, fb = np.where(left, f_moved, fb), np.where(left, fa, f_moved)
        a, b = new_a, new_b
    theta = 0.5 * (lo + hi)
    return point(np.where(value(theta) >= value(np.zeros_like(theta)), theta, 0.0))


class Balls3(SetModel):
    """x' ∈ B_1((0.5, 0, 0)) ∩ B_1((−0.5, 0, 0)) in R^3: an S_3 block (golden sweeps over two tangents)."""

    name = "test-balls-3"
    state_names = "x1 x2 x3"
    default_T = 1.0
    default_x0 = (0.0, 0.0, 0.0)
    default_xT = {"x1": 0.1, "x2": 0.2, "x3": -0.1}

    def sets(self, x1, x2, x3):
        return {(x1, x2, x3): (0.1 * x2, 0, 0) + intersection(Ball((0.5, 0, 0), 1), Ball((-0.5, 0, 0), 1))}


def _model(name):
    unregistered = {"test-balls-3": Balls3, "paper-7.2-sets": Paper72Sets}
    return unregistered[name]() if name in unregistered else qdframe.load_model(name)


def _iterates(functional: Functional, count: int = 4) -> list[np.ndarray]:
    """The start and random points around it: z inside, outside and on the sets."""
    rng = np.random.default_rng(7)
    start = functional.initial_point()
    points = [start]
    for scale in (0.3, 1.0, 3.0)[: count - 1]:
        xi = start + scale * rng.standard_normal(start.shape)
        points.append(functional.pack(*functional.split(xi)))
    return points


def _sphere_states(functional: Functional, xi: np.ndarray):
    y, z = functional.arguments(xi), functional.split(xi)[1]
    return [functional.pieces.state_sphere(block, y, z) for block in functional.blocks if block.size > 1]


@pytest.mark.parametrize("name", S2_MODELS + ["test-balls-3"])
def test_psi_and_active_pieces_match_the_reference_scan(name, monkeypatch):
    model = _model(name)
    functional = Functional(model, Grid(model.T, 301))
    new = [_sphere_states(functional, xi) for xi in _iterates(functional)]
    monkeypatch.setattr(functional_module, "maximize_on_sphere", reference_maximize)
    reference = Functional(model, Grid(model.T, 301))
    old = [_sphere_states(reference, xi) for xi in _iterates(reference)]
    assert new and all(new)
    for sides, ref_sides in zip(new, old):
        for side, ref in zip(sides, ref_sides):
            # each iterate after the first is searched from the last one's ψ* (warm start): the
            # same maximum ℓ to rounding (k = 2) or to the coordinate sweeps' own precision (k = 3,
            # ~1e-7), and ψ* to √ε (ℓ is flat to rounding there) or to that precision
            k = side.psi.shape[1]
            np.testing.assert_allclose(side.ell, ref.ell, rtol=0, atol=1e-14 if k == 2 else 2e-7)
            np.testing.assert_allclose(side.psi, ref.psi, rtol=0, atol=1e-7 if k == 2 else 1e-6)
            positive = side.h > 0
            np.testing.assert_array_equal(positive, ref.h > 0)
            for part, ref_part in zip(side.min_parts + side.max_parts, ref.min_parts + ref.max_parts):
                for delta in (1e-3, 1e-1):
                    np.testing.assert_array_equal(_delta_active(part.values, delta, positive),
                                                  _delta_active(ref_part.values, delta, positive))


def test_memo_reuses_psi_only_for_the_same_inputs(monkeypatch):
    model = qdframe.load_model("paper-7.2")
    xi = _iterates(Functional(model, Grid(model.T, 101)), 2)[1]
    moved = []
    for column in (0, 2):  # x1 (y, the ellipse's axis) and z1, at one node, by one ulp or so
        point = xi.copy()
        point[50, column] += 1e-13
        moved.append(point)
    fresh = [_sphere_states(Functional(model, Grid(model.T, 101)), point)[0].psi for point in [xi, *moved]]
    functional = Functional(model, Grid(model.T, 101))
    calls = []
    search = functional_module.maximize_on_sphere
    monkeypatch.setattr(functional_module, "maximize_on_sphere", lambda *a, **k: calls.append(1) or search(*a, **k))
    first = _sphere_states(functional, xi)[0]
    first.psi[:] = 0.0  # a caller changing its ψ* does not change the memo's
    again = _sphere_states(functional, xi.copy())[0]
    assert len(calls) == 1
    np.testing.assert_array_equal(again.psi, fresh[0])
    found = [_sphere_states(functional, point)[0].psi for point in moved]  # warm: the same ψ* to √ε
    for psi, expected in zip(found, fresh[1:]):
        np.testing.assert_allclose(psi, expected, rtol=0, atol=1e-7)
    assert len(calls) == 3
    for point, expected in zip([xi, *moved], [again.psi, *found]):  # all still remembered
        np.testing.assert_array_equal(_sphere_states(functional, point)[0].psi, expected)
    assert len(calls) == 3


@pytest.mark.parametrize("direction", ["gauss-newton", "native"])
def test_solve_paper_72_matches_the_reference_scan(direction, monkeypatch):
    options = dict(nodes=101, direction=direction, max_iter=6, estimate=False)
    result = qdframe.solve("paper-7.2", **options)
    monkeypatch.setattr(functional_module, "maximize_on_sphere", reference_maximize)
    reference = qdframe.solve("paper-7.2", **options)
    assert result.iterations == reference.iterations and result.status == reference.status
    assert result.objective == pytest.approx(reference.objective, rel=1e-9)
    assert result.I == pytest.approx(reference.I, rel=1e-9)
    np.testing.assert_allclose(result.x, reference.x, rtol=0, atol=1e-10)


@pytest.mark.parametrize("name", S2_MODELS)
def test_the_warm_start_scans_half_and_finds_the_cold_maximum(name):
    """A small step from an iterate: ψ* searched from the last one evaluates ℓ at fewer
    node-direction pairs than the cold search and finds the same maximum."""
    model = _model(name)
    grid = Grid(model.T, 301)
    start = _iterates(Functional(model, grid), 2)[1]
    step = 1e-3 * np.random.default_rng(3).standard_normal(start.shape)
    warm, cold = Functional(model, grid), Functional(model, grid)
    _sphere_states(warm, start)  # the last ψ*: the next search's start
    pairs = []
    search = functional_module.maximize_on_sphere

    def counted(objective, *args, **kwargs):
        def ell(psi, at=None):
            pairs[-1] += psi.shape[0] * psi.shape[1]
            return objective(psi, at)
        pairs.append(0)
        return search(ell, *args, **kwargs)

    functional_module.maximize_on_sphere = counted
    try:
        new = _sphere_states(warm, start + step)[0]
        ref = _sphere_states(cold, start + step)[0]
    finally:
        functional_module.maximize_on_sphere = search
    assert pairs[0] < 0.75 * pairs[1]
    np.testing.assert_allclose(new.ell, ref.ell, rtol=0, atol=1e-14)
    np.testing.assert_allclose(new.psi, ref.psi, rtol=0, atol=1e-7)


def _counted(objective, pairs):
    """objective, adding the samples it evaluates at each node to pairs (nodes,)."""
    def ell(psi, at=None):
        np.add.at(pairs, slice(None) if at is None else at, psi.shape[1])
        return objective(psi, at)
    return ell


def _ell_at(functional, xi):
    """The objective ℓ of the (first) S_k block's search at ξ, as Pieces.state_sphere builds it."""
    found = []
    original = functional_module.maximize_on_sphere
    functional_module.maximize_on_sphere = lambda objective, *a, **k: found.append(objective) or original(objective, *a, **k)
    try:
        _sphere_states(functional, xi)
    finally:
        functional_module.maximize_on_sphere = original
    return found[0]


def _same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


@pytest.mark.parametrize("name", ["paper-7.2", "intersecting-balls", "test-balls-3"])
def test_the_search_matches_the_previous_one_bit_for_bit_with_fewer_evaluations(name):
    """Cold, and warm from a ψ* that stands at some nodes and not at the others (z moved far
    at every third node): the same ψ* bit for bit as `previous_maximize`, with fewer node-sample
    pairs: a cold search saves ℓ at θ = 0 per node; a warm one also the check's samples at the
    nodes where the start does not stand and ℓ at the refined point where it does."""
    model = _model(name)
    nodes = 301
    functional = Functional(model, Grid(model.T, nodes))
    xi = _iterates(functional, 2)[1]
    n = functional.n
    moved = xi.copy()
    moved[::3, n : 2 * n] += 3.0 * np.random.default_rng(5).standard_normal((moved[::3].shape[0], n))
    k = next(block.size for block in functional.blocks if block.size > 1)
    start = maximize_on_sphere(_ell_at(functional, xi), nodes, k)
    objective = _ell_at(Functional(model, Grid(model.T, nodes)), moved)
    for begin in (None, start):
        new_pairs, old_pairs = np.zeros(nodes, dtype=int), np.zeros(nodes, dtype=int)
        new = maximize_on_sphere(_counted(objective, new_pairs), nodes, k, start=begin)
        old = previous_maximize(_counted(objective, old_pairs), nodes, k, start=begin)
        assert _same_bits(new, old)
        assert new_pairs.sum() < old_pairs.sum()
    scanned = old_pairs > old_pairs.min()  # the nodes where the start did not stand: the check, then the full scan
    assert 0 < scanned[::3].sum() and 0 < scanned.sum() < nodes // 2
    assert np.all(old_pairs[scanned] - new_pairs[scanned] > 128 // CHECK_STRIDE)  # the check's samples, and more
    assert np.all(new_pairs[~scanned] < old_pairs[~scanned])


def test_the_merged_scan_keeps_the_first_best_sample_with_ties_nan_and_inf():
    """An ℓ of plateaus (values rounded: ties between samples), NaN at some nodes on arcs of
    one to several samples (first in the check's samples or in the others) and −inf at all
    samples of other nodes, from a start that fails at every node: the scan of the samples the
    check did not evaluate, merged with the check's best, picks the sample of the full scan,
    and the golden searches on plateaus the same points."""
    nodes, rng = 60, np.random.default_rng(11)
    w = rng.standard_normal((nodes, 2))
    nan_above = np.where(rng.random(nodes) < 0.6, rng.uniform(0.95, 1.0, nodes), np.inf)  # NaN where ψ2 > this
    inf_nodes = rng.random(nodes) < 0.1

    def objective(psi, at=None):
        rows = slice(None) if at is None else at
        value = np.round(np.einsum("nk,nmk->nm", w[rows], psi), 1)
        value[psi[..., 1] > nan_above[rows][:, None]] = np.nan
        value[inf_nodes[rows]] = -np.inf
        return value

    for samples in (128, 37):
        far = -maximize_on_sphere(objective, nodes, 2, samples=samples)  # the antipode: the check fails
        for begin in (None, far):
            new = maximize_on_sphere(objective, nodes, 2, samples=samples, start=begin)
            assert _same_bits(new, previous_maximize(objective, nodes, 2, samples=samples, start=begin))


class _WithoutValues:
    """A model whose min-groups lose their values-only function: ψ* from `pieces` alone."""

    def __init__(self, model):
        self._model = model

    def __getattr__(self, name):
        return getattr(self._model, name)

    def blocks(self):
        return tuple(replace(block, min_groups=tuple(replace(g, values=None) for g in block.min_groups))
                     for block in self._model.blocks())


@pytest.mark.parametrize("name", S2_MODELS + ["test-balls-3"])
def test_values_only_pieces_give_the_same_psi_bit_for_bit(name):
    """The search evaluates a min-group's `values` where the model gives one (paper-7.2 and the
    set language do) instead of its pieces' values: the same ψ*, ℓ and h at every iterate."""
    model = _model(name)
    assert any(g.values is not None for block in model.blocks() for g in block.min_groups)
    with_values = Functional(model, Grid(model.T, 301))
    without = Functional(_WithoutValues(model), Grid(model.T, 301))
    assert not any(g.values is not None for block in without.blocks for g in block.min_groups)
    for xi in _iterates(with_values):
        for side, ref in zip(_sphere_states(with_values, xi), _sphere_states(without, xi)):
            np.testing.assert_array_equal(side.psi, ref.psi)
            np.testing.assert_array_equal(side.ell, ref.ell)
            np.testing.assert_array_equal(side.h, ref.h)


class _WrongValues:
    """paper-7.2 whose `values` triples the ellipse's piece, or (`left`) adds 0.1 to it
    only where ψ1 < 0."""

    def __init__(self, left=False):
        self._model = qdframe.load_model("paper-7.2")
        self.left = left

    def __getattr__(self, name):
        return getattr(self._model, name)

    def blocks(self):
        (block,) = self._model.blocks()
        (group,) = block.min_groups

        def values(x, psi):
            if self.left:
                return group.values(x, psi) + np.where(psi[:, :1] < 0, [[0.0, 0.1]], 0.0)
            return group.values(x, psi) * np.array([1.0, 3.0])

        return (replace(block, min_groups=(replace(group, values=values),)),)


def test_values_that_disagree_with_the_pieces_stop_the_solve_with_the_group_and_node_named():
    """A wrong `values` would send the search to a wrong ψ* and shrink h (a false `solved`):
    the first search of a functional compares it with the pieces' values."""
    with pytest.raises(qdframe.ModelOutputError, match=r"min-group 'B2 ∩ E2\(x\)': values\(x, ψ\) gives .* "
                                                      r"for piece 2, pieces\(x, ψ\) .* at node \d+") as raised:
        qdframe.solve(_WrongValues(), nodes=101)
    assert raised.value.label.endswith("values") and raised.value.node is not None


def test_values_wrong_only_in_some_directions_are_found_on_a_large_grid():
    """The comparison samples directions of S_k at nodes spread over the grid, whatever N
    (the scan's first chunk holds a single direction per node at N = 1e5)."""
    model = _WrongValues(left=True)
    functional = Functional(model, Grid(model.T, 100001))
    with pytest.raises(qdframe.ModelOutputError, match=r"for piece 2, .* ψ = \(-"):
        functional.objective(functional.initial_point())


def test_values_are_compared_with_the_pieces_once_per_functional(monkeypatch):
    model = qdframe.load_model("paper-7.2")
    functional = Functional(model, Grid(model.T, 101))
    (group,) = functional.blocks[0].min_groups
    calls = []
    original = group.pieces
    monkeypatch.setattr(functional, "blocks", (replace(functional.blocks[0], min_groups=(
        replace(group, pieces=lambda x, psi: calls.append(x.shape[0]) or original(x, psi)),)),))
    for xi in _iterates(functional, 3):
        _sphere_states(functional, xi)
    searched = [rows for rows in calls if rows != 101]  # the pieces at ψ*, one row per node, are the sides'
    assert len(searched) == 1
