"""The hard-case suite (also `qdframe bench hard`): every case must pass."""

import pytest

from qdframe.bench import hard


@pytest.mark.parametrize("case", hard.CASES, ids=lambda case: case.__name__)
def test_hard_case(case):
    result = case()
    assert result.passed, f"{result.name}: {result.measured}"


def test_table_lists_every_case():
    results = [hard.HardCase("a", "x", True, 0.1), hard.HardCase("b", "y", False, 0.2)]
    text = hard.table(results)
    assert "pass" in text and "FAIL" in text and text.count("\n") == 2
