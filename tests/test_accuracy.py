"""Certified accuracy (issue 14): nonuniform meshes, the pointwise checks of `solved`, the
error estimate against exact solutions, located switch times and `accuracy=`."""

from __future__ import annotations

import numpy as np
import pytest

import qdframe
from qdframe.bench.accuracy import exact_models
from qdframe.errors import InputError
from qdframe.grid import Grid

EXACT = exact_models()  # every registered model with an exact solution, the plugin's too
RESIDUAL_TOL = 1e-8  # solve's default: the pointwise checks of `solved`, relative to max(1, max|x|)
ESTIMATE_FACTOR = 1.3  # the estimate 2.5·max|x_h − x_{h/2}| is 1.25× a first-order error (measured 1.245–1.263)

# Known failures of the promise, with what was measured (`qdframe.solve(name, nodes=N)` /
# `accuracy=1e-6` on the 2-core machine); README.md, "Known failures", lists them too.
KNOWN = {
    ("stick-slip-oscillator", 101): "solved with error estimate 2.81 below its true error 4.51 "
                                    "(implicit Euler damps the 24 reversals); issue 30",
    ("stick-slip-oscillator", 1001): "solved without an error estimate (its solve on the bisected 2001-point grid "
                                     "ends max_iter), true error 2.97; issue 30",
    ("stick-slip-oscillator", "accuracy"): "accuracy=1e-6 ends stationary on 41 points without an estimate, "
                                           "true error 4.69; issue 31",
}


NOT_RUN = {
    # 54–63 s of the suite for a run that makes no claim: not solved (max_iter after 500
    # iterations, true error 1.13; issue 31), so its estimate is None as it must be
    ("stick-slip-oscillator", 10001): "a minute-long solve that ends max_iter",
}


def _cases(settings):
    return [pytest.param(name, setting, marks=pytest.mark.xfail(strict=True, reason=KNOWN[name, setting]))
            if (name, setting) in KNOWN else (name, setting)
            for name in EXACT for setting in settings if (name, setting) not in NOT_RUN]


def _known_switch_times(model) -> np.ndarray:
    """The model's switch times; a model that names none has none (paper-7.1 has no sign
    term, sliding-mode slides from t = 0: tests/bench/test_filippov_reference.py)."""
    return np.asarray(getattr(type(model), "switch_times", ()), dtype=float)


# ----------------------------------------------------------------------- nonuniform meshes
@pytest.mark.parametrize("scheme", ["trapezoid", "implicit-euler", "radau-iia"])
def test_a_nonuniform_mesh_integrates_as_its_rule_says(scheme):
    tau = np.array([0.0, 0.1, 0.15, 0.5, 0.7, 1.3, 2.0])
    grid = Grid.from_mesh(tau, scheme)
    assert grid.nodes == grid.scheme.stages * (tau.size - 1) + 1 and grid.T == 2.0 and not grid.uniform
    assert np.array_equal(grid.t[grid.mesh], tau)
    assert grid.weights.sum() == pytest.approx(2.0 + (grid.weights[0] if scheme != "trapezoid" else 0.0))
    exact_degree = {"trapezoid": 1, "implicit-euler": 0, "radau-iia": 2}[scheme]  # z of this degree integrates exactly
    z = grid.t ** exact_degree
    assert grid.cumulative(z)[grid.mesh] == pytest.approx(tau ** (exact_degree + 1) / (exact_degree + 1), abs=1e-14)
    y = np.random.default_rng(1).normal(size=grid.nodes)
    assert y @ grid.cumulative(z) == pytest.approx(grid.cumulative_adjoint(y) @ z, rel=1e-12)


def test_the_bisected_grid_keeps_every_mesh_point():
    grid = Grid.from_mesh([0.0, 0.3, 1.0], "radau-iia")
    finer = grid.bisected()
    assert np.allclose(finer.mesh_times, [0.0, 0.15, 0.3, 0.65, 1.0]) and finer.nodes == 9


@pytest.mark.parametrize("mesh, field", [([0.0, 0.5, 0.4, 3.0], "mesh"), ([0.1, 3.0], "mesh"), ([0.0, 2.0], "mesh")])
def test_a_bad_mesh_is_named(mesh, field):
    with pytest.raises(InputError, match=field):
        qdframe.solve("block-stop-stick", mesh=mesh)


def test_a_mesh_point_on_the_stop_makes_implicit_euler_exact_in_velocity():
    """block-stop-stick stops at t = 1: with a mesh point there, implicit Euler's velocity is
    exact (v' is constant on each piece) and the located stop is 1."""
    tau = np.concatenate([np.linspace(0, 1, 8), np.linspace(1, 3, 12)[1:]])
    result = qdframe.solve("block-stop-stick", mesh=tau)
    exact = qdframe.load_model("block-stop-stick").exact_solution(result.t)
    assert result.solved and result.nodes == tau.size and result.options["uniform"] is False
    assert np.max(np.abs(result.x[:, 1] - exact[:, 1])) <= 1e-9
    assert result.switch_times == pytest.approx([1.0], abs=1e-9)


# ------------------------------------------------------------------------ certification
def test_solved_reports_every_check_against_a_tolerance_scaled_to_the_states():
    result = qdframe.solve("block-stop-stick", nodes=101)
    assert result.solved
    scale_x = max(1.0, float(np.max(np.abs(result.x))))
    assert set(result.checks) == {"boundary", "inclusion", "selection", "consistency"}
    assert result.checks["consistency"]["tol"] == pytest.approx(1e-8 * scale_x)
    assert result.checks["selection"]["tol"] == 1e-8
    assert all(c["value"] <= c["tol"] for c in result.checks.values())
    worst = max(result.checks, key=lambda k: result.checks[k]["value"] / result.checks[k]["tol"])
    assert result.binding_check == worst
    assert np.array_equal(result.x[0], qdframe.load_model("block-stop-stick").x0)  # x(0) = x0 exactly


def test_the_boundary_error_is_read_from_x_itself():
    result = qdframe.solve("block-stop-stick-bvp", nodes=101)
    assert result.solved
    assert result.boundary_error == pytest.approx(abs(result.x[-1, 0] - 1.0), abs=0.0)


# ---------------------------------------------------------------------- error estimates
def test_the_exact_models_are_all_found():
    """exact_models() finds the built-in ones and the plugin's (a model missing here would
    silently leave every test below)."""
    assert {"block-stop-stick", "block-stop-stick-bvp", "block-breakaway", "slide-on-line", "slide-after-reaching",
            "two-surface-sliding", "stick-slip-oscillator", "paper-7.1", "coulomb-block", "sliding-mode"} <= set(EXACT)


@pytest.mark.parametrize("name, nodes", _cases([101, 1001, 10001]))
def test_a_solved_result_has_its_true_error_within_its_estimate(name, nodes):
    """README: at N = 101, 1001 and 10001 with the default scheme, a `solved` result's true
    error is within its estimate, and the estimate is 1.25 times a first-order error (the
    bound here: 1.3×), or, where the scheme is exact at the points (paper-7.1's trapezoid,
    two-surface-sliding's implicit Euler), within the pointwise tolerance."""
    result = qdframe.solve(name, nodes=nodes)
    assert result.solved, result.message
    assert result.error_estimate is not None, result.message
    assert result.solution_error <= result.error_estimate
    floor = RESIDUAL_TOL * max(1.0, float(np.max(np.abs(result.x))))
    assert result.error_estimate <= ESTIMATE_FACTOR * result.solution_error + floor


def test_no_estimate_when_skipped_or_not_solved():
    assert qdframe.solve("block-stop-stick", nodes=101, estimate=False).error_estimate is None
    unfinished = qdframe.solve("block-stop-stick", nodes=101, max_iter=1)
    assert unfinished.status == "max_iter" and unfinished.error_estimate is None and unfinished.switch_times.size == 0


# ---------------------------------------------------------------- switches and accuracy
@pytest.mark.parametrize("name, setting", _cases(["accuracy"]))
def test_accuracy_locates_the_switches_and_meets_the_target_with_few_nodes(name, setting):
    """README: with accuracy=1e-6 every exact problem ends solved with true error ≤ 1e-6 (and
    within its estimate) on fewer than 200 points, the switch times within 1e-8."""
    model = qdframe.load_model(name)
    result = qdframe.solve(model, accuracy=1e-6)
    assert result.solved, result.message
    assert result.solution_error <= result.error_estimate <= 1e-6
    assert result.nodes < 200
    exact = _known_switch_times(model)
    assert result.switch_times.size == exact.size, result.switch_times
    assert np.max(np.abs(result.switch_times - exact), initial=0.0) <= 1e-8
    assert "error estimate" in result.message and result.options["accuracy"] == 1e-6


def test_an_unmet_accuracy_says_why():
    result = qdframe.solve("slide-on-line", accuracy=1e-12, max_nodes=200, scheme="implicit-euler")
    assert result.status == "stationary"
    assert "accuracy 1.0e-12 not met" in result.message and "max_nodes = 200" in result.message


def test_accuracy_is_never_claimed_without_an_estimate():
    """paper-7.3 at accuracy=1e-6: the companion solve on the bisected mesh does not finish, so
    there is no estimate, and no `solved` (found by bench run's reference: error 3.5e-3)."""
    result = qdframe.solve("paper-7.3", accuracy=1e-6)
    assert result.error_estimate is None
    assert result.status == "stationary" and "no error estimate" in result.message


def test_accuracy_input_is_checked():
    with pytest.raises(InputError, match="accuracy"):
        qdframe.solve("slide-on-line", accuracy=-1.0)
    with pytest.raises(InputError, match="max_nodes"):
        qdframe.solve("slide-on-line", accuracy=1e-3, max_nodes=2)


def test_the_papers_method_runs_on_a_nonuniform_mesh():
    """native and osqp (the same direction QPs) take the same iterates on an uneven mesh of
    paper-7.1 and reach the paper's accuracy; gauss-newton solves it."""
    tau = np.sort(np.concatenate([np.linspace(0, 1, 31), [0.013, 0.52, 0.977]]))
    native, osqp = (qdframe.solve("paper-7.1", mesh=tau, direction=d, continuation="none") for d in ("native", "osqp"))
    assert (native.iterations, native.objective) == (osqp.iterations, osqp.objective)  # identical runs (README)
    assert native.objective <= 1e-3 and native.solution_error <= 1e-3
    newton = qdframe.solve("paper-7.1", mesh=tau)
    assert newton.solved and np.array_equal(newton.t, tau) and newton.solution_error <= 1e-12
