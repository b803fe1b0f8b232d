"""Issue 35, item 8: the README describes what `simulate` returns (a Simulation, not a tuple)
and `solve --help` the continuation default (auto)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import qdframe
from qdframe.cli import main
from qdframe.simulate import Simulation, simulate

README = (Path(__file__).resolve().parents[1] / "docs" / "guide.md").read_text()  # the Python API's page


def test_the_readme_says_simulate_returns_a_simulation():
    assert "returns the simulated `t, x, z`" not in README
    start = README.index("`qdframe.simulate.simulate(")
    sentence = " ".join(README[start:start + 400].split())
    assert "returns a `Simulation`" in sentence and "`run.x[-1]`" in sentence
    run = simulate(qdframe.load_model("block-stop-stick"), 0.0, 2.0, [0.0, 2.0], dt=1e-3)
    assert isinstance(run, Simulation)
    with pytest.raises(TypeError):
        t, x, z = run  # what the README used to promise
    assert run.x[-1] == pytest.approx([1.0, 0.0], abs=2e-3) and run.t.shape == (run.x.shape[0],)


def test_solve_help_gives_the_continuation_default(capsys):
    with pytest.raises(SystemExit):
        main(["solve", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "none for gauss-newton" not in text
    assert "(default: auto)" in text and "gauss-newton 101, 301, 1001, 3001" in text


def test_the_default_continuation_is_auto_for_both_directions():
    for direction in ("gauss-newton", "native"):
        assert qdframe.registry.make_direction(direction).default_continuation == "auto"
    result = qdframe.solve("paper-7.1", nodes=1001, max_iter=3)
    assert result.options["grids"][0] == 101  # gauss-newton's ladder: 101, 301, then 1001
    assert np.all(np.diff(result.options["grids"]) > 0)
