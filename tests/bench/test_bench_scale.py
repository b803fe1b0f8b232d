"""`qdframe bench scale`: the harness measures what it says (values, not speed)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from qdframe.bench import scale
from qdframe.cli import main


def cell(path: str, model: str, nodes: int, seconds: float) -> scale.Cell:
    return scale.Cell(path, model, nodes, 3, "max_iter", seconds, seconds / 2, seconds / 4, seconds / 4, 1.0, 1.0)


def test_exponent_is_the_slope_of_the_logs() -> None:
    cells = [cell("p", "a", n, 2e-6 * n**1.5) for n in (1001, 10001, 100001)] + [cell("p", "b", 1001, 1.0)]
    k = scale.exponents(cells)
    assert k[("p", "a")] == pytest.approx(1.5, abs=1e-12)
    assert np.isnan(k[("p", "b")])  # one grid: no slope
    assert cells[0].ratio == pytest.approx(2.0)


def test_a_cell_measures_the_descent_the_floor_and_the_arrays() -> None:
    measured = scale.measure("gauss-newton", "paper-7.3", 201, iterations=2)
    assert measured.iterations == 2 and measured.status == "max_iter"
    assert 0 < measured.factor_s < measured.floor_s and measured.model_s > 0
    assert measured.floor_s == pytest.approx(measured.factor_s + measured.model_s)
    # ξ alone is 201 nodes × (x, z, u) of paper-7.3 in float64; J and the factors come on top
    assert measured.must_exist_mb > 201 * 5 * 8 / 2**20
    assert measured.per_iteration_s > 0 and measured.ratio == measured.per_iteration_s / measured.floor_s
    # every gauss-newton iteration factors its KKT system at least once (one per active-set guess)
    assert measured.factorizations >= 1 and measured.factorizations * measured.iterations == int(
        measured.factorizations * measured.iterations)


def test_cli_writes_the_table_and_json(tmp_path, capsys) -> None:
    out = tmp_path / "scale.json"
    code = main(["bench", "scale", "--paths", "native", "--models", "paper-7.1", "--nodes", "101,201",
                 "--iterations", "1", "--json", str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    assert "| native | paper-7.1 | 201 |" in printed
    assert "KKT/iter" in printed and "| — |" in printed  # native factors no KKT system
    report = json.loads(out.read_text())
    assert report["format"] == "qdframe-bench-scale/1"
    assert [c["nodes"] for c in report["cells"]] == [101, 201]
    assert np.isfinite(report["exponents"][0]["k"])


def test_repeated_measurements_keep_the_least_time_and_floor_and_the_largest_peak() -> None:
    a = scale.Cell("p", "m", 101, 3, "max_iter", 2.0, 0.5, 0.4, 0.1, 30.0, 1.0, 4.0)
    b = scale.Cell("p", "m", 101, 3, "max_iter", 1.5, 0.6, 0.5, 0.1, 20.0, 1.0, 4.0)
    failed = scale.Cell("p", "m", 101, 0, "failed", *([float("nan")] * 6), error="MemoryError: ")
    kept = scale.best([a, failed, b])
    assert (kept.per_iteration_s, kept.floor_s, kept.factor_s, kept.model_s) == (1.5, 0.5, 0.4, 0.1)
    assert kept.peak_mb == 30.0 and kept.repeats == 2 and kept.ratio == 3.0
    assert scale.best([failed]).error  # nothing measured: the failure is the row


def test_cli_repeats_each_cell(tmp_path) -> None:
    out = tmp_path / "scale.json"
    assert main(["bench", "scale", "--paths", "native", "--models", "paper-7.1", "--nodes", "101",
                 "--iterations", "1", "--repeat", "2", "--json", str(out)]) == 0
    (measured,) = json.loads(out.read_text())["cells"]
    assert measured["repeats"] == 2 and measured["per_iteration_s"] > 0
