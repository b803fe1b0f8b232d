"""The command line as a new user meets it: global options where the README shows them,
direction options, only backends that work, honest summaries."""

from __future__ import annotations

import json

import pytest

import qdframe
from qdframe.cli import main
from qdframe.directions.gauss_newton import GaussNewton
from qdframe.registry import make_direction
from qdframe.directions.base import with_options
from qdframe.errors import InputError
from qdframe.result import _grids


def test_debug_is_accepted_after_the_subcommand(capsys):
    assert main(["solve", "no-such-model"]) == 2  # one line
    assert "no-such-model" in capsys.readouterr().err
    for argv in (["solve", "no-such-model", "--debug"], ["--debug", "solve", "no-such-model"]):
        assert main(argv) == 2  # --debug: the traceback, wherever the flag stands, and the same exit status
        err = capsys.readouterr().err
        assert "Traceback" in err and "UnknownNameError" in err


def test_option_sets_a_direction_field():
    solver = with_options(make_direction("gauss-newton"), {"mu": "1e-6", "mu_max": "10"})
    assert solver.mu == 1e-6 and solver.mu_max == 10.0 and isinstance(solver.mu_max, float)
    assert make_direction("gauss-newton").mu != 1e-6  # a copy: the registry's class is untouched


@pytest.mark.parametrize("options, expected", [
    ({"nope": "1"}, "KEY one of: mu, mu_min, mu_max"),
    ({"mu": "abc"}, "mu=<a number>"),
])
def test_option_errors_name_the_field_and_the_form(options, expected):
    with pytest.raises(InputError, match="--option") as info:
        with_options(make_direction("gauss-newton"), options)
    assert expected in str(info.value)


def test_option_on_the_command_line(tmp_path, capsys):
    """`--option mu=1` reaches the solver: the run's iterates are those of the direction built
    by hand with mu = 1 (heavy Levenberg–Marquardt damping: shorter first steps), not the
    default's."""
    out = tmp_path / "damped.json"
    assert main(["solve", "paper-7.1", "--nodes", "11", "--option", "mu=1", "--json", str(out), "--quiet"]) == 0
    damped = json.loads(out.read_text())
    by_hand = qdframe.solve("paper-7.1", nodes=11, direction=GaussNewton(mu=1.0))
    default = qdframe.solve("paper-7.1", nodes=11)
    assert damped["direction"] == "gauss-newton"
    assert [h["objective"] for h in damped["history"]] == [h.objective for h in by_hand.history]
    assert damped["iterations"] == by_hand.iterations
    assert [h["objective"] for h in damped["history"]] != [h.objective for h in default.history]  # not the default's
    assert main(["solve", "paper-7.1", "--option", "mu"]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err
    assert main(["solve", "paper-7.1", "--option", "bad=1"]) == 2


def test_a_qpsolvers_solver_that_fails_is_not_offered(capsys):
    qpsolvers = pytest.importorskip("qpsolvers")
    from qdframe.directions.qpsolvers_backend import NOT_OFFERED, offered_solvers

    assert "highs" not in offered_solvers(qpsolvers) and "highs" in NOT_OFFERED
    assert main(["solve", "paper-7.1", "--direction", "qpsolvers:highs"]) == 2
    err = capsys.readouterr().err
    assert "highs is not offered" in err and "daqp" in err


def test_the_summary_says_when_a_solve_ended_on_a_coarser_grid():
    assert _grids([11, 101], 11) == "  (ended on this grid; 101 requested)"
    assert _grids([11, 101], 101) == "  (continued from 11)"
    assert _grids([101], 101) == ""


def test_json_to_stdout_keeps_stdout_clean(capsys):
    assert main(["solve", "paper-7.2", "--nodes", "11", "--json", "-"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["model"] == "paper-7.2"  # stdout is the JSON alone
    assert "status" in err  # the summary went to stderr


def test_a_reader_that_stops_early_is_no_error():
    """`qdframe solve … | head -1` (here `| true`, which reads nothing: the pipe is closed before
    the summary is written): the closed pipe is not reported as an unexpected error."""
    import subprocess
    import sys

    done = subprocess.run(f"{sys.executable} -m qdframe.cli solve block-stop-stick --nodes 101 | true",
                          shell=True, capture_output=True, text=True)
    assert done.returncode == 0 and done.stderr == ""
