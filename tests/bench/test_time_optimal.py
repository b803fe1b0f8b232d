"""`qdframe bench time-optimal`: nosnoc's time-optimal statement of block-time-optimal, and the
command's table and report (qdframe's 5–9 s solve replaced by a canned row here; the docs' small
`qdframe bench time-optimal …` command, run by tests/test_docs_commands.py, runs the real one)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from qdframe.bench import nosnoc_time_optimal, time_optimal
from qdframe.bench.nosnoc_peer import nosnoc_available
from qdframe.cli import main
from qdframe.models.identification import BlockTimeOptimal
from qdframe.status import Status

T_STAR = BlockTimeOptimal.exact_T


def _needs_nosnoc() -> None:
    pytest.importorskip("nosnoc")  # not installed: a skip (in CI, where it is, a failure)
    # installed but unusable (a broken CasADi binary, nosnoc failing on import) is a failure, not a skip
    assert nosnoc_available() is None, nosnoc_available()


@pytest.mark.parametrize("formulation, stages", [("global", 4), ("local", 2)])
def test_nosnoc_time_optimal_statement_finds_T(formulation, stages):
    """A small grid: 4 equal stages put a boundary on the switch at 0.75·T*; 2 free stages place it."""
    _needs_nosnoc()
    run = nosnoc_time_optimal.run(formulation, stages, 1)
    assert run.status == Status.SOLVED, run.message
    assert abs(run.T - T_STAR) < 1e-2
    assert run.t[0] == 0.0 and run.t[-1] == pytest.approx(run.T) and run.x.shape == (run.t.size, 2)
    assert time_optimal.trajectory_error(run.t, run.x, run.T) < 1e-2


def test_the_statement_rejects_an_unknown_formulation():
    with pytest.raises(ValueError, match="global, local"):
        nosnoc_time_optimal.statement(BlockTimeOptimal(), "piecewise", None, None)


def test_trajectory_error_is_on_the_normalized_time():
    """The exact motion stretched to T = 2 has no error on the normalized time; at T* itself neither."""
    exact = BlockTimeOptimal()
    t = np.linspace(0.0, 2.0, 9)
    assert time_optimal.trajectory_error(t, exact.motion(t * T_STAR / 2.0), 2.0) == pytest.approx(0.0, abs=1e-15)
    t = np.linspace(0.0, T_STAR, 9)
    assert time_optimal.trajectory_error(t, exact.motion(t) + 1e-3, T_STAR) == pytest.approx(1e-3)


def test_grids_split_the_elements_over_the_stages():
    assert time_optimal.grids((10, 20), (10, 20, 40)) == [(10, 1), (10, 2), (10, 4), (20, 1), (20, 2)]
    assert time_optimal.grids((3,), (10,)) == []


def _canned(accuracy=None):
    t = np.linspace(0.0, T_STAR, 5)
    setting = "default call" if accuracy is None else f"accuracy={accuracy:g}"
    return time_optimal.judged("qdframe", setting, Status.SOLVED, 1.5, T_STAR, t, BlockTimeOptimal().motion(t), "canned")


def test_command_prints_the_table_and_writes_the_report(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(time_optimal, "run_qdframe", _canned)
    out = tmp_path / "time-optimal"
    argv = ["bench", "time-optimal", "--stages", "4", "--elements", "4", "--formulations", "global", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "| qdframe | default call | solved | 1.50 | 1.6329931619 |" in printed
    assert "| qdframe | accuracy=0.001 | solved |" in printed
    report = (out / "report.md").read_text()
    assert report.startswith("# Time-optimal: block-time-optimal, qdframe against nosnoc")
    assert "`qdframe bench time-optimal --stages 4 --elements 4 --formulations global --out " in report
    rows = time_optimal.read_rows(out / "results.csv")
    assert rows[0].solver == "qdframe" and rows[0].trajectory_error == pytest.approx(0.0, abs=1e-15)
    assert time_optimal.table(rows) in printed  # the file holds the printed figures
    if nosnoc_available() is None:
        assert [row.setting for row in rows[2:]] == ["global s, 4 stages × 1 FE"]
        assert "| nosnoc | global s, 4 stages × 1 FE | solved |" in printed and abs(rows[2].T_error) < 1e-2


def test_command_refuses_an_unknown_formulation(tmp_path, capsys):
    assert main(["bench", "time-optimal", "--formulations", "piecewise", "--out", str(tmp_path)]) == 2
    assert "--formulations" in capsys.readouterr().err


def test_the_docs_table_is_the_committed_report():
    """docs/benchmarks.md quotes the table of docs/bench/time-optimal (results.csv, report.md) as made."""
    root = Path(__file__).resolve().parents[2]
    committed = time_optimal.table(time_optimal.read_rows(root / "docs" / "bench" / "time-optimal" / "results.csv"))
    assert committed in (root / "docs" / "bench" / "time-optimal" / "report.md").read_text()
    assert committed in (root / "docs" / "benchmarks.md").read_text()
