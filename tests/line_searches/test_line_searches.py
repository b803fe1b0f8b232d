"""The line searches (paper (180)) on functions whose minimizer is known."""

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
