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


def test_a_cell_measures_the_descent_the_floor_and_the_arrays(monkeypatch) -> None:
    """Each number of a cell against what the module docstring says it is, from values the
    test sets or counts itself: s/iter the MEDIAN of the iterations' times (a history whose
    times the test writes), the floor the FASTEST of the three factorizations plus the model's
    evaluation (clock readings the test scripts), KKT/iter the factorizations gauss-newton
    made (calls the test counts), must-exist ξ + J + the SMALLER factors (sizes the test takes
    from the model's dimensions and from what each factorization returned)."""
    import dataclasses

    import qdframe
    import qdframe.descent.loop as loop
    import qdframe.directions.kkt as kkt
    from qdframe.directions.linearized_system import LinearizedSystem
    from qdframe.functional import Functional
    from qdframe.schemes.grid import Grid

    times = [0.0, 0.5, 0.7, 0.8]  # the iterations take 0.5, 0.2, 0.1 s: median 0.2 (mean 0.27, last 0.1)
    real_descend = loop.descend

    def descend(*args, **kwargs):
        result = real_descend(*args, **kwargs)
        assert len(result.history) == len(times)
        result.history = [dataclasses.replace(r, time_s=t) for r, t in zip(result.history, times)]
        return result

    clock = iter([0.03, 0.02, 0.04, 0.005])  # SuperLU's default panel, its one-column panel, qdldl's LDLᵀ, the model
    returned = []

    def median_time(fn):
        out = fn()
        returned.append(out)
        return next(clock), out

    factored = []
    real_factor = kkt._factor

    def factor(*args, **kwargs):
        factored.append(1)
        return real_factor(*args, **kwargs)

    monkeypatch.setattr(loop, "descend", descend)
    monkeypatch.setattr(scale, "_median_time", median_time)
    monkeypatch.setattr(kkt, "_factor", factor)
    measured = scale.measure("gauss-newton", "paper-7.3", 201, iterations=3)
    assert measured.iterations == 3 and measured.status == "max_iter"
    assert measured.per_iteration_s == pytest.approx(0.2, abs=1e-12)
    assert (measured.factor_s, measured.model_s) == (0.02, 0.005) and measured.floor_s == pytest.approx(0.025)
    assert measured.ratio == pytest.approx(8.0)
    assert measured.factorizations == len(factored) / 3 and len(factored) >= 3  # one or more per iteration
    # the arrays: ξ = (x, z, u, λ) on 201 nodes in float64, paper-7.3's 6 states, 1 control and 3
    # selections (Sgn(x4), Sgn(x5), Sgn(x6): qdframe/models/paper_73.py); J as the test builds it at
    # the model's start; the factors' bytes as their factorizations returned them
    model = qdframe.load_model("paper-7.3")
    xi_bytes = 201 * (6 + 6 + 1 + 3) * 8
    assert (model.n_states, len(model.control_names)) == (6, 1)
    functional = Functional(model, Grid(model.T, 201, model.default_scheme))
    J = LinearizedSystem(functional, functional.initial_point(), 1e-3).jacobian
    j_bytes = J.data.nbytes + J.indices.nbytes + J.indptr.nbytes
    factor_bytes = returned[:3]
    assert min(factor_bytes) < max(factor_bytes)  # different sizes: which one is kept matters
    assert measured.must_exist_mb * 2**20 == pytest.approx(xi_bytes + j_bytes + min(factor_bytes), rel=1e-12)


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
