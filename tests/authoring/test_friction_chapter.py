"""Issue 35, item 8: docs/authoring.md's friction chapter — the Coulomb pendulum with Sgn and
sympy's sin, a start from qdframe.simulate — is the code of examples/coulomb_pendulum.py,
and its outcomes are the ones the chapter states; its vector sign (issue 38) is the code of
examples/isotropic_friction.py."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

import qdframe
from qdframe.errors import InputError
from qdframe.sets import SetModel, Sgn

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "authoring.md"
EXAMPLE = ROOT / "examples" / "coulomb_pendulum.py"
VECTOR_EXAMPLE = ROOT / "examples" / "isotropic_friction.py"


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("coulomb_pendulum", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _chapter() -> str:
    text = GUIDE.read_text()
    return text[text.index("## 2. Friction"):text.index("## 3. Register it")]


def test_the_chapters_code_is_the_examples():
    """The pendulum's two blocks are examples/coulomb_pendulum.py; the vector sign's two (issue
    38: the puck in the set language, the hand-written BallSwitch) examples/isotropic_friction.py."""
    blocks = re.findall(r"```python\n(.*?)```", _chapter(), re.S)
    assert len(blocks) == 4
    for block, example in zip(blocks, [EXAMPLE, VECTOR_EXAMPLE, VECTOR_EXAMPLE, EXAMPLE]):
        code = example.read_text()
        for line in block.splitlines():
            assert line.strip() in code, f"not in examples/{example.name}: {line!r}"


def test_the_chapter_says_where_the_names_come_from():
    chapter = _chapter()
    for needed in ("from sympy import sin", "`Sgn` is qdframe's (`qdframe.sets.Sgn`)", "`Abs`, `Min`, `Max`",
                   "`initial_guess(t)`", "qdframe.simulate.simulate", "`Simulation`"):
        assert needed in chapter, needed


def test_the_pendulum_sticks_where_the_chapter_says(example):
    result = qdframe.solve(example.CoulombPendulum(), nodes=1001)
    assert result.status == "solved" and result.iterations == 32
    assert np.allclose(result.switch_times, [0.0, 1.056, 2.076], atol=1e-3)
    assert result.x[-1, 0] == pytest.approx(0.086, abs=1e-3) and result.x[-1, 1] == pytest.approx(0.0, abs=1e-9)
    assert abs(9.81 * np.sin(result.x[-1, 0])) <= 2.0  # friction holds it


def test_the_default_start_fails_and_the_simulated_one_solves(example):
    failed = qdframe.solve(example.Released(), nodes=101, max_iter=100)
    assert failed.status == "max_iter" and failed.I == pytest.approx(6.9e-2, rel=0.01)
    simulated = qdframe.solve(example.ReleasedFromSimulation(), nodes=101)
    assert simulated.status == "solved" and simulated.iterations == 17
    assert np.allclose(simulated.switch_times, [0.0, 1.438, 2.517, 3.550], atol=1e-3)


def test_numpys_sin_on_a_symbol_is_one_error_naming_sympy():
    class NumpySin(SetModel):
        state_names = "theta omega"
        default_x0 = (1.0, 0.0)

        def sets(self, theta, omega):
            return {theta: omega, omega: -9.81 * np.sin(theta) - 2 * Sgn(omega)}

    with pytest.raises(InputError, match=r"NumpySin.sets\(\): expected formulas of SymPy functions .*from sympy import sin"):
        NumpySin()
