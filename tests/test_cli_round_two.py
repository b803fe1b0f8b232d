"""Issue 35 ("a new user's first hour, round two"), items 1, 3 and 6: one line and exit 2
for every bad input (a plugin's own exceptions, backend options out of range, an output
format no one writes), exit codes a script can trust, and "did you mean" for names."""

from __future__ import annotations

import sys
import textwrap

import numpy as np
import pytest

import qdframe
from qdframe import registry
from qdframe.cli import main
from qdframe.solve import solving  # the module (qdframe.solve, the attribute, is the function)
from qdframe.registry import make_direction
from qdframe.directions.base import with_options
from qdframe.errors import InputError, PluginCodeError, UnknownNameError
from qdframe.status import EXIT_CODES, EXIT_ERROR, EXIT_USAGE, Status

PLUGIN = '''
import numpy as np
from qdframe.sets import Interval, SetModel


class _Base(SetModel):
    state_names = "x"
    default_x0 = (0.0,)
    default_xT = {"x": 1.0}

    def sets(self, x):
        return {x: Interval(0, 2)}


class RaisesInSets(_Base):
    """sets() divides by zero."""
    name = "raises-in-sets"

    def sets(self, x):
        return {x: 1 / 0}


class RaisesInInit(_Base):
    """__init__ needs a file that is not there."""
    name = "raises-in-init"

    def __init__(self, **overrides):
        raise RuntimeError("no config file")


class RaisesInGuess(_Base):
    """initial_guess() raises."""
    name = "raises-in-guess"

    def initial_guess(self, t):
        raise KeyError("start")
'''


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """A distribution `broken-models` with the models above and one entry whose module fails to import."""
    (tmp_path / "broken_models.py").write_text(textwrap.dedent(PLUGIN))
    (tmp_path / "unimportable_models.py").write_text("raise ImportError('no module named scipy_special_thing')\n")
    info = tmp_path / "broken_models-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-models\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[qdframe.models]\n"
        "raises-in-sets = broken_models:RaisesInSets\n"
        "raises-in-init = broken_models:RaisesInInit\n"
        "raises-in-guess = broken_models:RaisesInGuess\n"
        "cannot-load = unimportable_models:Model\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    registry.refresh()
    yield
    monkeypatch.undo()
    for name in ("broken_models", "unimportable_models"):
        sys.modules.pop(name, None)
    registry.refresh()


def _no_solve(monkeypatch):
    """Make any solve an error: the checks under test must come before it."""
    def refuse(*args, **kwargs):
        raise AssertionError("the solve started")

    monkeypatch.setattr(solving, "solve", refuse)


# ---------------------------------------------------------------- item 1: a plugin's exceptions
@pytest.mark.parametrize("command, model, method, raised", [
    ("solve", "raises-in-sets", "sets()", "ZeroDivisionError: division by zero"),
    ("solve", "raises-in-init", "__init__", "RuntimeError: no config file"),
    ("solve", "raises-in-guess", "initial_guess()", "KeyError: 'start'"),
    ("check-model", "raises-in-sets", "sets()", "ZeroDivisionError: division by zero"),
    ("check-model", "raises-in-init", "__init__", "RuntimeError: no config file"),
])
def test_a_plugins_exception_is_one_line_naming_distribution_model_and_method(plugin, capsys, command, model, method,
                                                                                raised):
    assert main([command, model, "--quiet"]) == EXIT_USAGE
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"qdframe: error: model {model!r} (distribution broken-models): {method} raised {raised} at ")
    assert "broken_models.py:" in err  # the file and line that raised


def test_check_model_reports_an_initial_guess_that_raises_as_a_failed_check(plugin, capsys):
    assert main(["check-model", "raises-in-guess"]) == 1  # a model defect found by the check: its exit status
    out, err = capsys.readouterr()
    assert "initial_guess()" in out and "error — KeyError: 'start' at " in out
    assert err.startswith("qdframe: error: model 'raises-in-guess': initial_guess(): error: KeyError") and err.count("\n") == 1


def test_a_plugins_exception_keeps_its_cause_in_python(plugin):
    with pytest.raises(PluginCodeError) as info:
        qdframe.solve("raises-in-guess", nodes=11)
    assert isinstance(info.value.__cause__, KeyError) and info.value.method == "initial_guess()"


def test_debug_shows_the_plugins_traceback_and_keeps_exit_2(plugin, capsys):
    assert main(["solve", "raises-in-sets", "--debug"]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert "Traceback" in err and "1 / 0" in err and err.rstrip().splitlines()[-1].startswith("qdframe: error: model")


def test_a_plugin_that_failed_to_load_is_named_as_such_not_as_a_typo(plugin, capsys):
    assert main(["solve", "cannot-load"]) == EXIT_USAGE
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and err[0].startswith("qdframe: warning: could not load model 'cannot-load' from distribution "
                                               "broken-models")
    assert "registered by distribution broken-models, which could not be loaded" in err[1]
    assert "did you mean" not in err[1] and "block-breakaway" not in err[1]  # not the list of every model


# ---------------------------------------------------------------- item 1: backend options, ranges
@pytest.mark.parametrize("direction, option, expected", [
    ("gauss-newton", "mu=-1", "mu=<a number > 0"),
    ("gauss-newton", "mu=nan", "mu=<a number > 0"),
    ("gauss-newton", "mu=inf", "mu=<a number > 0"),
    ("gauss-newton", "mu_max=1e-13", "mu_max=<a number ≥ mu_min = 1e-12>"),
    ("gauss-newton", "mu=1e9", "mu=<a number in [mu_min, mu_max]"),
    ("osqp", "max_iter=-5", "max_iter=<an integer ≥ 1 and ≤ 2147483647 (OSQP's limit)>"),
    ("osqp", "max_iter=0", "max_iter=<an integer ≥ 1"),
    ("osqp", "eps_abs=-1", "eps_abs=<a number ≥ 0 (OSQP's limit)>"),
    ("osqp", "polish_refine_iter=-1", "polish_refine_iter=<an integer ≥ 0"),
    ("clarabel", "max_iter=-5", "max_iter=<an integer ≥ 1 and ≤ 4294967295 (Clarabel's limit)>"),
    ("clarabel", "max_iter=4294967296", "max_iter=<an integer ≥ 1 and ≤ 4294967295"),
    ("clarabel", "tol_feas=0", "tol_feas=<a number > 0"),
    ("native", "mu=1", "no options (direction 'native' has none)"),
])
def test_a_backend_option_out_of_range_is_refused_before_the_solve(monkeypatch, capsys, direction, option, expected):
    if direction == "osqp":  # optional; clarabel is a base dependency and never skipped
        pytest.importorskip("osqp")
    _no_solve(monkeypatch)
    assert main(["solve", "paper-7.1", "--direction", direction, "--option", option]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("qdframe: error: --option: expected ") and expected in err
    assert f"got '{option}'" in err or direction == "gauss-newton"


def test_an_option_out_of_range_is_refused_from_python_too():
    from qdframe.directions.gauss_newton import GaussNewton

    with pytest.raises(InputError, match=r"GaussNewton.mu: expected a number > 0"):
        GaussNewton(mu=float("nan"))
    osqp_backend = pytest.importorskip("qdframe.directions.osqp_backend")
    pytest.importorskip("osqp")
    with pytest.raises(InputError, match=r"OsqpDirection.max_iter"):
        osqp_backend.OsqpDirection(max_iter=0)


def test_options_in_range_are_taken():
    solver = with_options(make_direction("gauss-newton"), {"mu": "1e-3", "mu_max": "1e4"})
    assert solver.mu == 1e-3 and solver.mu_max == 1e4


# ---------------------------------------------------------------- issue 56, item 9: bad values of the options
SIMULATE = ["simulate", "paper-7.1", "--from", "0", "--to", "1", "--x0", "0,0"]


@pytest.mark.parametrize("argv, field, said", [
    (["solve", "paper-7.1", "--accuracy", "0"], "argument --accuracy", "expected a positive finite number, got '0'"),
    (["solve", "paper-7.1", "--accuracy", "nan"], "argument --accuracy", "expected a positive finite number, got 'nan'"),
    (["solve", "paper-7.1", "--accuracy", "1e-6x"], "argument --accuracy", "expected a positive finite number"),
    (["solve", "paper-7.1", "--tol", "0"], "argument --tol", "expected a positive finite number, got '0'"),
    (["solve", "paper-7.1", "--tol", "nan"], "argument --tol", "expected a positive finite number, got 'nan'"),
    (["solve", "paper-7.1", "--tol=-1e-10"], "argument --tol", "expected a positive finite number"),
    (["solve", "paper-7.1", "--max-nodes", "2"], "argument --max-nodes", "expected an integer ≥ 3, got '2'"),
    (["solve", "paper-7.1", "--max-nodes", "1e5"], "argument --max-nodes", "expected an integer ≥ 3, got '1e5'"),
    (["solve", "paper-7.1", "--max-nodes", "100.5"], "argument --max-nodes", "expected an integer ≥ 3"),
    (["solve", "paper-7.1", "--max-nodes", "many"], "argument --max-nodes", "expected an integer ≥ 3"),
    (["solve", "paper-7.1", "--selection-scale", "0"], "argument --selection-scale", "expected a positive finite number"),
    (["solve", "paper-7.1", "--residual-tol", "nan"], "argument --residual-tol", "expected a positive finite number"),
    (["solve", "paper-7.1", "--eps-floor", "0"], "argument --eps-floor", "expected a positive finite number"),
    (["solve", "paper-7.1", "--eps-floor", "1"], "eps_floor", "expected a number ≤ eps = 0.01"),  # the plan's check
    (["solve", "paper-7.1", "--signs", "nan"], "argument --signs", "invalid choice: 'nan' (choose from "),
    (["solve", "block-friction-coefficient", "--parameter", "mu=abc"], "argument --parameter",
     "expected NAME=GUESS with a finite number as the guess, got 'mu=abc'"),
    (["solve", "block-friction-coefficient", "--parameter", "mu=nan"], "argument --parameter",
     "expected NAME=GUESS with a finite number as the guess"),
    (["solve", "block-friction-coefficient", "--parameter", "nu=0.3"], "parameters",
     "expected names among the model's parameters (mu), got 'nu'"),
    (["solve", "paper-7.1", "--parameter", "mu=0.3"], "parameters", "expected names among the model's parameters (none)"),
    ([*SIMULATE, "--dt", "0"], "argument --dt", "expected a positive finite number, got '0'"),
    ([*SIMULATE, "--dt", "nan"], "argument --dt", "expected a positive finite number, got 'nan'"),
    ([*SIMULATE, "--dt=-1e-3"], "argument --dt", "expected a positive finite number"),
    (["bench", "run", "--nodes", "0"], "argument --nodes", "expected node counts ≥ 2, got '0'"),
    (["bench", "run", "--nodes", "11,1"], "argument --nodes", "expected node counts ≥ 2, got '11,1'"),
    (["bench", "run", "--nodes", "11.5"], "argument --nodes", "expected comma-separated node counts like 11,101"),
    (["bench", "run", "--nodes", "11,"], "argument --nodes", "expected comma-separated node counts like 11,101"),
    (["bench", "run", "--workers", "0"], "argument --workers", "expected an integer ≥ 1, got '0'"),
    (["bench", "run", "--workers", "1.5"], "argument --workers", "expected an integer ≥ 1, got '1.5'"),
    (["bench", "run", "--workers", "all"], "argument --workers", "expected an integer ≥ 1, got 'all'"),
    (["bench", "directions", "--nodes", "1"], "argument --nodes", "expected an integer ≥ 2, got '1'"),
    (["bench", "scale", "--nodes", "nan"], "argument --nodes", "expected comma-separated node counts like 11,101"),
])
def test_a_bad_option_value_is_one_line_naming_the_field_exit_2(monkeypatch, capsys, argv, field, said):
    """Issue 56, item 9: each refused before any work, with one line that names the field and
    the expected form (argparse's "invalid choice … (choose from …)" for a choice), and exit status 2."""
    import qdframe.cli

    _no_solve(monkeypatch)
    for name in ("_simulate", "main_bench"):  # nor a simulation or a benchmark started
        monkeypatch.setattr(qdframe.cli, name, lambda *args, **kwargs: pytest.fail("the command ran"))
    assert main(argv) == EXIT_USAGE
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("qdframe") and f"error: {field}: {said}" in err, err


# ---------------------------------------------------------------- item 1: outputs checked before the solve
@pytest.mark.parametrize("path", ["out.xyz", "out"])
def test_a_plot_format_no_one_writes_is_refused_before_the_solve(monkeypatch, capsys, tmp_path, path):
    _no_solve(monkeypatch)
    assert main(["solve", "paper-7.1", "--plot", str(tmp_path / path)]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--plot: expected a file name ending in a figure format" in err and ".png" in err


# ---------------------------------------------------------------- item 3: exit codes
def test_the_exit_codes_are_one_per_status_and_documented(capsys):
    codes = {status: EXIT_CODES[status] for status in Status}
    assert codes[Status.SOLVED] == 0 and len(set(codes.values())) == len(codes)
    assert not {EXIT_ERROR, EXIT_USAGE} & set(codes.values())
    with pytest.raises(SystemExit):
        main(["solve", "--help"])
    text = capsys.readouterr().out
    readme = (qdframe_root() / "README.md").read_text()
    for status, code in codes.items():
        assert f"  {code}  {status.value}:" in text
        assert f"| {code} | `{status.value}` |" in readme


def qdframe_root():
    from pathlib import Path

    return Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("argv, status", [
    (["solve", "paper-7.1", "--nodes", "11"], "solved"),
    (["solve", "paper-7.1", "--nodes", "11", "--max-iter", "1"], "max_iter"),
    (["solve", "paper-7.2", "--nodes", "11", "--xT=3,0"], "stationary"),
])
def test_solve_exits_with_its_statuss_code(tmp_path, argv, status):
    import json

    out = tmp_path / "r.json"
    code = main(argv + ["--quiet", "--json", str(out)])
    assert json.loads(out.read_text())["status"] == status and code == EXIT_CODES[status]


@pytest.mark.parametrize("status", ["uncertified", "failed"])
def test_uncertified_and_failed_have_their_codes(monkeypatch, status):
    real = solving.solve

    def ends(*args, **kwargs):
        result = real(*args, **kwargs)
        result.status = status
        return result

    monkeypatch.setattr(solving, "solve", ends)
    assert main(["solve", "paper-7.1", "--nodes", "11", "--quiet"]) == EXIT_CODES[status] != 0


def test_debug_keeps_the_exit_code_of_a_usage_error(capsys):
    assert main(["solve", "paper-7.1", "--nodes", "1", "--debug"]) == EXIT_USAGE
    assert main(["--debug", "solve", "paper-7.1", "--option", "mu=-1"]) == EXIT_USAGE
    assert "Traceback" in capsys.readouterr().err


def test_an_unexpected_exception_is_one_line_exit_1(monkeypatch, capsys):
    def broken(*args, **kwargs):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(solving, "solve", broken)
    assert main(["solve", "paper-7.1"]) == EXIT_ERROR
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unexpected ZeroDivisionError: float division by zero" in err and "--debug" in err


# ---------------------------------------------------------------- item 6: did you mean
@pytest.mark.parametrize("argv, field, suggestion", [
    (["solve", "paper-71"], "model", "'paper-7.1'"),
    (["solve", "paper-7.1", "--direction", "nativ"], "direction", "'native'"),
    (["solve", "paper-7.1", "--direction", "qpsolver:daqp"], "direction", "'qpsolvers:daqp'"),
    (["solve", "paper-7.1", "--line-search", "armjio"], "line search", "'armijo'"),
    (["solve", "paper-7.1", "--scheme", "radau"], "scheme", "'radau-iia'"),
    (["check-model", "paper71"], "model", "'paper-7.1'"),
])
def test_a_misspelled_name_gets_did_you_mean(monkeypatch, capsys, argv, field, suggestion):
    _no_solve(monkeypatch)
    assert main(argv) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{field}: unknown name" in err and f"did you mean {suggestion}" in err
    assert len(err) < 200  # not the list of every name


def test_a_misspelled_option_gets_did_you_mean(capsys):
    assert main(["solve", "paper-7.1", "--option", "mu_mx=1"]) == EXIT_USAGE
    assert "(did you mean mu_max?)" in capsys.readouterr().err


def test_a_name_with_nothing_close_lists_the_names():
    with pytest.raises(UnknownNameError) as info:
        registry.lookup("line_searches", "zzz")
    assert "one of: armijo, golden" in str(info.value) and info.value.suggestions == []
