"""`qdframe bench run --suite ocp`: the replay that judges every run (against closed forms), the
reading of qdframe's and nosnoc's controls, and the suite on one small problem (the docs' small
command, run by tests/test_docs_commands.py, runs the CLI end to end)."""

from __future__ import annotations

import numpy as np
import pytest

from qdframe.bench import nosnoc_ocp, ocp
from qdframe.bench.nosnoc_peer import nosnoc_available
from qdframe.bench.ocp_problems import PROBLEMS
from qdframe.bench.two_modes import contact, integrate
from qdframe.cli import main
from qdframe.models import optimal_references as references


def _replayed(problem, control, breaks=()):
    return integrate(contact(problem.numeric_field, problem.friction), problem.x0, problem.T, control, breaks,
                     lambda x, u: float(problem.running(x, u)), problem.terminal)


@pytest.mark.parametrize("name, reference", [
    ("least-effort-block", references.least_effort(1.0, 2.0, 0.5)),
    ("least-effort-bounded", references.least_effort_bounded(1.0, 2.0, 0.5, 1.5)),
    ("lq-terminal", references.lq_terminal(1.0, 50.0, (2.0, 0.0))),
])
def test_the_exact_optimal_control_replays_to_its_exact_cost_and_end(name, reference):
    problem = PROBLEMS[name]
    motion = _replayed(problem, lambda t: np.array([float(reference.control(np.array([t]))[0])]),
                       tuple(getattr(reference, "switch_times", ()) or ()))
    assert motion.cost == pytest.approx(problem.best, abs=1e-11)
    assert np.allclose(motion.x_end, reference.states(np.array([problem.T]))[0], atol=1e-11)


def test_a_push_below_the_friction_bound_leaves_the_block_stuck_and_a_stronger_one_stops_it_later():
    """p' = v, v' ∈ u − 0.5·Sgn(v) from rest: u = 0.4 moves nothing; u = 1 until t = 1 then 0 slides
    with v' = 0.5 to v = 0.5, then v' = −0.5 stops it at t = 2 at p = 0.5 and it sticks (u = 0)."""
    problem = PROBLEMS["least-effort-block"]
    still = _replayed(problem, lambda t: np.array([0.4]))
    assert np.array_equal(still.x_end, [0.0, 0.0]) and still.cost == pytest.approx(0.16 * 2.0)
    push = _replayed(problem, lambda t: np.array([1.0 if t < 1.0 else 0.0]), (1.0,))
    assert push.x_end == pytest.approx([0.5, 0.0], abs=1e-10) and push.events == 1  # the stop located to ~1e-11
    assert push.cost == pytest.approx(1.0)


def test_qdframes_control_is_its_schemes_polynomial_between_its_points():
    """Radau IIA: on each mesh interval the line through u at its two stages, u(t0) unread."""
    import qdframe

    result = qdframe.solve("least-effort-bounded", nodes=21, scheme="radau-iia")
    control, breaks, samples = ocp.scheme_control(result)
    t, u = np.asarray(result.t), np.asarray(result.u)
    assert np.allclose(breaks, t[2:-1:2])
    for k in range(1, t.size):
        assert control(t[k] - 1e-12 if k % 2 == 0 else t[k])[0] == pytest.approx(u[k, 0], abs=1e-9)
    middle = 0.5 * (t[1] + t[2])
    assert control(middle)[0] == pytest.approx(0.5 * (u[1, 0] + u[2, 0]))
    assert samples.shape == (2 * 10 + 10, 1)


def test_the_suite_judges_qdframe_and_nosnoc_by_the_replayed_cost(tmp_path):
    """lq-terminal (no end values, a terminal cost): qdframe's default call within 1e-6 of J*;
    nosnoc's 5 stages of constant control above J* by the replay, its own cost equal to it."""
    pytest.importorskip("nosnoc")
    assert nosnoc_available() is None, nosnoc_available()
    rows = ocp.run(["lq-terminal"], accuracy=(), stages=(5,))
    mine, theirs = rows
    assert (mine.solver, mine.status, theirs.solver, theirs.status) == ("qdframe", "solved", "nosnoc", "solved")
    assert mine.cost_error <= 1e-6 * PROBLEMS["lq-terminal"].best and mine.violation == 0.0
    # qdframe's own estimate bounds its own cost's distance to J*; nosnoc gives none
    assert abs(mine.own_cost - PROBLEMS["lq-terminal"].best) <= mine.own_estimate and theirs.own_estimate is None
    assert theirs.cost > PROBLEMS["lq-terminal"].best + 1e-3
    assert theirs.cost == pytest.approx(theirs.own_cost, rel=1e-9)
    paths = ocp.write_report(rows, tmp_path, "qdframe bench run --suite ocp", 1.0)
    assert ocp.read_rows(paths["results"]) == rows
    text = paths["report"].read_text()
    assert "| lq-terminal | 36.95652174 | qdframe |" in text and "nosnoc 0.2" in text


def test_the_best_known_cost_is_the_least_of_the_runs_that_met_the_conditions():
    row = ocp.Row("nosnoc-motor", "nosnoc", "s", "solved", 0.9, 0.9, float("nan"), 1e-9, 1.0, 20)
    missed = ocp.Row("nosnoc-motor", "nosnoc", "s", "solved", 0.5, 0.5, float("nan"), 1e-2, 1.0, 20)
    judged = ocp.with_best([row, missed])
    assert ocp.best(judged, "nosnoc-motor") == 0.9
    assert judged[0].cost_error == 0.0 and judged[1].cost_error == pytest.approx(0.4)
    assert "| nosnoc-motor | 0.9 | nosnoc | 1.00 | 1.00 | 1.00 |" in ocp.work_precision(judged)


def test_nosnocs_statement_has_the_problems_bounds_and_modes():
    pytest.importorskip("nosnoc")
    import casadi as ca
    import nosnoc

    model, problem = nosnoc_ocp.statement(PROBLEMS["least-effort-bounded"], ca, nosnoc)
    assert list(problem.lbu) == [-1.5] and list(problem.ubu) == [1.5]
    f = ca.Function("f", [model.x, model.u], [model.F[0]])
    assert np.allclose(np.array(f([0.0, 1.0], [0.7])), [[1.0, 1.0], [0.2, 1.2]])


@pytest.mark.parametrize("extra, field", [
    (["--directions", "native"], "--directions"), (["--nodes", "11"], "--nodes"),
    (["--models", "paper-7.1"], "--models"), (["--executor", "dask"], "--executor"),
])
def test_the_ocp_suite_refuses_the_other_suites_options(extra, field, capsys, tmp_path):
    code = main(["bench", "run", "--suite", "ocp", "--out", str(tmp_path / "o"), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2 and field in err and len(err.splitlines()) == 1
