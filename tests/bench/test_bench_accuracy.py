"""`qdframe bench accuracy`: uniform grids against accuracy= to a true error (correctness only, never timing)."""

from __future__ import annotations

import pytest

from qdframe.bench.accuracy import AccuracyRow, exact_models, ladder_nodes, run, table
from qdframe.cli import main


def test_the_models_are_those_with_an_exact_solution():
    found = exact_models()
    assert {"block-stop-stick", "block-stop-stick-bvp", "block-breakaway", "slide-on-line", "slide-after-reaching",
            "two-surface-sliding", "paper-7.1"} <= set(found)
    assert not {"paper-7.2", "paper-7.3", "sliding-mode-terminal"} & set(found)


def test_the_ladder_doubles_the_intervals():
    assert ladder_nodes("implicit-euler")[:3] == [21, 41, 81] and ladder_nodes("radau-iia")[:3] == [41, 81, 161]
    assert max(ladder_nodes("implicit-euler")) <= 100_001 and ladder_nodes("radau-iia", max_nodes=200) == [41, 81, 161]


def test_one_model_adaptive_meets_the_target_and_the_uniform_ladders_reach_it():
    [row] = run(["slide-on-line"], [1e-4])
    assert isinstance(row, AccuracyRow) and row.status == "solved"
    assert row.error <= row.target and row.met and row.estimate_holds
    assert [u.scheme for u in row.uniform] == ["radau-iia", "implicit-euler"]
    for u in row.uniform:
        assert u.reached and u.error <= 1e-4 and u.nodes in ladder_nodes(u.scheme) and u.status in ("solved", "uncertified")
    radau = row.uniform[0]
    nodes_ratio, time_ratio = row.ratios()
    assert nodes_ratio == radau.nodes / row.nodes and time_ratio == radau.seconds / row.seconds
    assert row.switch_offset == 0.0 and row.switches == () and row.known_switches == ()  # it slides from the start
    text = table([row])
    assert text.count("\n") == 2 and "| slide-on-line | 1e-04 |" in text


def test_switch_times_are_compared_with_the_known_ones():
    [row] = run(["block-breakaway"], [1e-4], schemes=("radau-iia",))
    assert row.known_switches == (1.0,) and len(row.switches) == 1 and row.switch_offset <= 1e-8


def test_a_target_beyond_the_cap_is_not_reached():
    [row] = run(["slide-on-line"], [1e-4], schemes=("implicit-euler",), max_nodes=81)
    [u] = row.uniform
    assert not u.reached and u.tried == 81 and u.error > 1e-4
    assert row.ratios("implicit-euler") == (None, None)
    assert "not reached (81, " in table([row])


def test_the_command_prints_a_table(capsys):
    assert main(["bench", "accuracy", "--models", "paper-7.1", "--targets", "1e-4"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("| model | target | adaptive N |") and "| paper-7.1 | 1e-04 | " in out


@pytest.mark.parametrize("args, field", [(["--targets", "0,1e-4"], "--targets"), (["--targets", "x"], "--targets"),
                                         (["--models", "paper-7.2"], "--models")])
def test_bad_arguments_end_in_one_line(args, field, capsys):
    assert main(["bench", "accuracy", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and field in err
