"""The paper's method carried on where it is ε-stationary but not solved: ε and δ shrink
together down to eps_floor on a certified solve, and stay fixed on a fixed grid."""

import pytest

import qdframe
from qdframe.errors import InputError


@pytest.fixture(scope="module")
def fixed():
    """The paper's rule: ε = 1e-2 on a fixed grid of 21 points (continuation 11 → 21)."""
    return qdframe.solve("paper-7.1", nodes=21, direction="native", estimate=False)


@pytest.fixture(scope="module")
def carried():
    """The same grid with ε and δ allowed to shrink."""
    return qdframe.solve("paper-7.1", nodes=21, direction="native", estimate=False, eps_floor=1e-12, max_iter=200)


def test_a_fixed_grid_keeps_the_papers_eps_and_delta(fixed):
    assert fixed.status == "stationary" and "≤ ε at every node" in fixed.message
    assert fixed.options["eps"] == 1e-2 and fixed.options["delta"] == 1e-3
    assert "shrunk" not in fixed.message


def test_shrinking_eps_goes_on_and_lowers_the_true_error(fixed, carried):
    assert carried.iterations > fixed.iterations
    assert carried.options["eps"] < 1e-2 and carried.options["delta"] == pytest.approx(carried.options["eps"] / 10)
    assert "ε and δ shrunk to" in carried.message
    # against the closed form of Example 7.1
    assert carried.solution_error < fixed.solution_error / 100


def test_the_certified_call_shrinks_by_default():
    result = qdframe.solve("paper-7.1", direction="native", max_iter=60)
    assert result.options["eps"] < 1e-2 and "ε and δ shrunk" in result.message
    pinned = qdframe.solve("paper-7.1", direction="native", max_iter=60, eps_floor=1e-2)
    assert pinned.options["eps"] == 1e-2 and "shrunk" not in pinned.message


def test_gauss_newton_is_unaffected():
    result = qdframe.solve("paper-7.1", nodes=41, estimate=False)
    assert result.options["eps"] == 1e-2 and "discrete problem is solved" in result.message


def test_an_eps_floor_above_eps_is_a_one_line_error():
    with pytest.raises(InputError, match="eps_floor.*≤ eps"):
        qdframe.solve("paper-7.1", nodes=11, direction="native", eps_floor=0.1)
