"""The command line (DESIGN.md §5) and the entry-point registries."""

import json
import warnings

import pytest

from qdframe import registry
from qdframe.cli import main
from qdframe.status import EXIT_CODES
from qdframe.errors import UnknownNameError


def test_list_json_names_distributions(capsys):
    assert main(["list", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert {"paper-7.1", "paper-7.2"} <= {e["name"] for e in data["models"]}
    assert {"native"} <= {e["name"] for e in data["directions"]}
    assert {"golden", "armijo"} <= {e["name"] for e in data["line_searches"]}
    builtin = {"paper-7.1", "paper-7.2", "paper-7.3", "native", "gauss-newton", "golden", "armijo"}
    assert all(e["distribution"] == "qdframe" for kind in data.values() for e in kind if e["name"] in builtin)


def test_solve_writes_json_and_plot(tmp_path, capsys):
    out, fig = tmp_path / "r.json", tmp_path / "r.png"
    code = main(["solve", "paper-7.2", "--direction", "native", "--nodes", "11", "--max-iter", "2", "--json", str(out), "--plot", str(fig)])
    data = json.loads(out.read_text())
    assert data["status"] == "max_iter" and code == EXIT_CODES[data["status"]] == 5  # two iterations: the budget
    assert data["model"] == "paper-7.2" and data["iterations"] == 2
    assert fig.stat().st_size > 1000
    assert "status" in capsys.readouterr().out


@pytest.mark.parametrize("flag, grids", [([], [11, 51]), (["--continuation", "none"], [51]),
                                         (["--continuation", "auto"], [11, 51]), (["--continuation", "21"], [21, 51])])
def test_continuation_flag(flag, grids, tmp_path):
    out = tmp_path / "r.json"
    code = main(["solve", "paper-7.2", "--direction", "native", "--nodes", "51", "--quiet", "--json", str(out)] + flag)
    data = json.loads(out.read_text())
    assert code == EXIT_CODES[data["status"]]  # the paper's method ends stationary (4) on 7.2
    assert data["options"]["grids"] == grids and data["nodes"] == 51
    assert sorted({record["nodes"] for record in data["history"]}) == grids


def test_overrides_reach_the_model(tmp_path):
    out = tmp_path / "r.json"
    assert main(["solve", "paper-7.2", "--nodes", "5", "--max-iter", "0", "--T", "2", "--x0=0.5,-1",
                 "--xT", "1,1", "--json", str(out), "--quiet"]) == EXIT_CODES["max_iter"]
    data = json.loads(out.read_text())
    assert data["T"] == 2.0 and data["x"][0] == [0.5, -1.0] and data["t"][-1] == 2.0


@pytest.mark.parametrize(
    "args, field",
    [
        (["solve", "nomodel"], "model"),
        (["solve", "paper-7.2", "--nodes", "1"], "--nodes"),
        (["solve", "paper-7.2", "--nodes", "2.5"], "--nodes"),
        (["solve", "paper-7.2", "--delta", "0"], "--delta"),
        (["solve", "paper-7.2", "--eps", "-1"], "--eps"),
        (["solve", "paper-7.2", "--gamma-max", "inf"], "--gamma-max"),
        (["solve", "paper-7.2", "--max-iter", "-3"], "--max-iter"),
        (["solve", "paper-7.2", "--T", "-1"], "--T"),
        (["solve", "paper-7.2", "--x0", "1,2,3"], "x0"),
        (["solve", "paper-7.2", "--x0=nan,1"], "--x0"),
        (["solve", "paper-7.2", "--xT", "1"], "xT"),
        (["solve", "paper-7.2", "--direction", "bogus"], "direction"),
        (["solve", "paper-7.2", "--line-search", "bogus"], "line search"),
        (["solve", "paper-7.2", "--json", "/nonexistent-dir/r.json"], "--json"),
        (["solve", "paper-7.2", "--continuation", "fine"], "--continuation"),
        (["solve", "paper-7.2", "--continuation", "101", "--nodes", "51"], "continuation"),
    ],
)
def test_bad_arguments_end_in_one_line_naming_the_field(args, field, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and field in err and "Traceback" not in err


def test_unknown_name_lists_the_available_ones():
    with pytest.raises(UnknownNameError, match="native"):
        registry.lookup("directions", "no-such-direction")


def test_a_broken_plugin_is_a_warning_naming_its_distribution(tmp_path, monkeypatch):
    info = tmp_path / "broken_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[qdframe.models]\nbroken = no_such_module_xyz:Model\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    registry.refresh()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            models = registry.available("models")
        assert "broken" not in models and "paper-7.1" in models
        assert any("broken-plugin" in str(w.message) for w in caught)
    finally:
        monkeypatch.undo()
        registry.refresh()


def test_an_unwritable_plot_path_is_a_usage_error_not_a_traceback(capsys):
    assert main(["solve", "paper-7.2", "--nodes", "5", "--plot", "/proc/qdframe-test.png"]) == 2
    err = capsys.readouterr().err
    assert "--plot" in err and "Traceback" not in err and err.count("\n") == 1


def test_a_broken_plugin_is_one_line_once_in_check_model_and_list(tmp_path, monkeypatch, capsys):
    info = tmp_path / "broken_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[qdframe.models]\nbroken = no_such_module_xyz:Model\npaper-7.1 = no_such_module_xyz:Other\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    registry.refresh()
    try:
        assert main(["list"]) == 0
        assert main(["solve", "paper-7.1", "--nodes", "11", "--quiet"]) == 0
        err = capsys.readouterr().err
        lines = err.splitlines()
        assert all(line.startswith("qdframe: warning: ") for line in lines) and "Traceback" not in err
        loading = [line for line in lines if "could not load" in line]
        assert len(loading) == 1 and "pip uninstall broken-plugin" in loading[0]
        shadowed = [line for line in lines if "is shadowed" in line]
        assert shadowed and all("pip uninstall broken-plugin" in line for line in shadowed)
    finally:
        monkeypatch.undo()
        registry.refresh()
