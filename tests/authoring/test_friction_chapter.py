"""Issue 35, item 8: docs/authoring.md's friction chapter — the Coulomb pendulum with Sgn and
sympy's sin, a start from qdframe.simulate — is the code of examples/coulomb_pendulum.py,
and its outcomes are the ones the chapter states; its vector sign (issue 38) is the code of
examples/isotropic_friction.py; a force in time (a clock state) is examples/time_forcing.py."""

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
CLOCK_EXAMPLE = ROOT / "examples" / "time_forcing.py"


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
    38: the puck in the set language, the hand-written BallSwitch) examples/isotropic_friction.py; a force in time (a clock state) is examples/time_forcing.py."""
    blocks = re.findall(r"```python\n(.*?)```", _chapter(), re.S)
    assert len(blocks) == 5
    for block, example in zip(blocks, [EXAMPLE, VECTOR_EXAMPLE, VECTOR_EXAMPLE, EXAMPLE, CLOCK_EXAMPLE]):
        code = example.read_text()
        for line in block.splitlines():
            assert line.strip() in code, f"not in examples/{example.name}: {line!r}"


def test_the_chapter_says_where_the_names_come_from():
    chapter = _chapter()
    for needed in ("from sympy import sin", "`Sgn` is qdframe's (`qdframe.sets.Sgn`)", "`Abs`, `Min`, `Max`",
                   "`initial_guess(t)`", "qdframe.simulate.simulate", "`Simulation`"):
        assert needed in chapter, needed


def test_the_pendulum_sticks_where_the_chapter_says(example):
    """The default call: solved to 1e-6 by replay (the true error of this initial-value
    problem), the reversal and the stop where the chapter says, stuck where friction holds it."""
    result = qdframe.solve(example.CoulombPendulum())
    assert result.solved and result.certificate == "replay" and result.options["start"] == "simulated"
    assert result.error_estimate <= 1e-6 * max(1.0, float(np.max(np.abs(result.x))))
    assert np.allclose(result.switch_times, [1.056, 2.077], atol=1e-3)
    assert result.x[-1, 0] == pytest.approx(0.0997, abs=1e-4) and result.x[-1, 1] == pytest.approx(0.0, abs=1e-9)
    assert abs(9.81 * np.sin(result.x[-1, 0])) <= 2.0  # friction holds it


def test_the_simulated_start_is_what_solves_the_longer_release(example):
    solved = qdframe.solve(example.Released(), accuracy=1e-5)
    assert solved.solved and np.allclose(solved.switch_times, [1.498, 2.625, 3.673, 4.691], atol=1e-3)
    constant = qdframe.solve(example.Released(), nodes=101, max_iter=100, simulate_start=False)
    assert not constant.converged and constant.I > 1e-2 and constant.options["start"] == "model"
    own = qdframe.solve(example.ReleasedFromSimulation(), nodes=101, simulate_start=False)
    assert own.converged and own.status == "uncertified" and own.error_estimate is None
    assert "above the target" in own.message and "(the replay stopped there)" in own.message


def test_numpys_sin_on_a_symbol_is_one_error_naming_sympy():
    class NumpySin(SetModel):
        state_names = "theta omega"
        default_x0 = (1.0, 0.0)

        def sets(self, theta, omega):
            return {theta: omega, omega: -9.81 * np.sin(theta) - 2 * Sgn(omega)}

    with pytest.raises(InputError, match=r"NumpySin.sets\(\): expected formulas of SymPy functions .*from sympy import sin"):
        NumpySin()
