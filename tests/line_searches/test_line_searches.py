"""The line searches (paper (180)) on functions whose minimizer is known."""

import numpy as np
import pytest

from qdframe.line_searches.armijo import Armijo
from qdframe.line_searches.golden import GoldenSection


def test_golden_finds_the_minimum_of_a_unimodal_function():
    gamma, value = GoldenSection().search(lambda g: (g - 0.3) ** 2, 0.09, -0.6, 1.0)
    assert gamma == pytest.approx(0.3, abs=1e-5) and value == pytest.approx(0.0, abs=1e-10)


def test_golden_finds_a_decrease_its_bracket_stepped_over():
    """I falls only on [0, 0.01] and is above I(ξ) but decreasing beyond: the golden
    bracket moves right, away from the decrease; halving from γ̄ finds it and the search
    repeats there (the earlier fallback took the end 1e-3 of [0, 1e-3])."""

    def along(g: float) -> float:
        return 1.0 - g if g <= 0.01 else 1.5 - 0.1 * g

    gamma, value = GoldenSection().search(along, 1.0, -1.0, 1.0)
    assert gamma == pytest.approx(0.01, rel=1e-4) and value < 1.0


def test_golden_reports_no_decrease_as_zero():
    assert GoldenSection().search(lambda g: 1.0 + g, 1.0, 1.0, 1.0) == (0.0, 1.0)


def test_armijo_accepts_sufficient_decrease():
    gamma, value = Armijo().search(lambda g: (g - 0.3) ** 2, 0.09, -0.6, 1.0)
    assert 0 < gamma <= 1.0 and value <= 0.09 + 1e-4 * gamma * -0.6


def test_armijo_stops_where_the_decrease_it_asks_for_is_below_the_objectives_rounding():
    """A stalled search (every trial above the value: a kink, or rounding) used to evaluate the
    objective 60 times; it stops once γ·|slope| < 4ε·|value|, at the first γ = 2^-j below it."""
    calls = []

    def along(gamma: float) -> float:
        calls.append(gamma)
        return 2.0 + gamma  # no decrease anywhere
    assert Armijo().search(along, 2.0, -1e-6, 1.0) == (0.0, 2.0)
    smallest = calls[-1]
    assert smallest * 1e-6 >= 4 * np.finfo(float).eps * 2.0 > smallest * 0.5 * 1e-6
    assert len(calls) < 60


def test_armijo_still_finds_a_decrease_the_rounding_floor_leaves_visible():
    """The floor only cuts trials whose whole first-order decrease is below the rounding: a
    decrease at γ = 2^-20 along a slope of −1 is found as before."""
    def along(gamma: float) -> float:
        return 1.0 - gamma if gamma <= 2.0**-20 else 1.0 + gamma
    assert Armijo().search(along, 1.0, -1.0, 1.0) == (2.0**-20, 1.0 - 2.0**-20)


def test_armijo_without_a_descent_slope_keeps_halving_for_any_decrease():
    """slope ≥ 0 (a nonsmooth model's derivative): no floor, any decrease is taken."""
    def along(gamma: float) -> float:
        return 1.0 - 1e-3 if gamma <= 2.0**-30 else 1.5
    gamma, value = Armijo().search(along, 1.0, 0.0, 1.0)
    assert gamma == 2.0**-30 and value == 1.0 - 1e-3
