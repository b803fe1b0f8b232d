"""Certified accuracy (issues 14, 30): nonuniform meshes, the pointwise checks, the error
estimate against exact solutions on fixed grids, located switch times and `accuracy=`."""

from __future__ import annotations

import numpy as np
import pytest

import qdframe
from qdframe.bench.accuracy import exact_models
from qdframe.errors import InputError
from qdframe.schemes.grid import Grid
from qdframe.sets import Interval, SetModel, Sgn

EXACT = exact_models()  # every registered model with an exact solution, the plugin's too
RESIDUAL_TOL = 1e-8  # solve's default: the pointwise checks, relative to max(1, max|x|)
ESTIMATE_FACTOR = 1.3  # bisection's 2.5·max|x_h − x_{h/2}| is 1.25× a first-order error (measured 1.245–1.263)
REPLAY_SLACK = 1e-8  # the replay's own integration (rtol 1e-11) and rounding, relative to max(1, max|x|)

# Known failures of the promise, with what was measured on the 2-core machine; README.md,
# "Known failures", lists them too.
_RELAY_PERIOD = ("relay-period on a fixed implicit-Euler grid: x(0) given and x(T) = x(0) in both states are, "
                 "with T, one condition more than the discrete problem can meet (implicit Euler loses the energy "
                 "the orbit keeps): 101 nodes end max_iter (T off by 0.79), 1001 stationary (T off by 0.19); the "
                 "default call solves it (radau-iia, its mesh on the crossings)")
KNOWN: dict = {("relay-period", 101): _RELAY_PERIOD, ("relay-period", 1001): _RELAY_PERIOD}  # (model, setting): why


NOT_RUN: dict = {("relay-period", 10001): "the same failure as at 101 and 1001, 58 s to reach it"}  # why left out

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


def test_a_refined_mesh_keeps_every_point_and_refines_where_the_error_is():
    """adaptive.refine cuts each interval into equal parts: every old point stays (a
    solution carried there keeps its jumps on points), and the interval with the large
    local error gets the most parts."""
    from qdframe.solve.adaptive import refine

    grid = Grid.from_mesh(np.array([0.0, 0.3, 0.5, 1.0]), "radau-iia")
    local = np.array([1e-8, 1e-4, 1e-8])
    finer = refine(grid, local, 1e-6, 1e-4)
    assert np.all(np.isin(grid.mesh_times, finer)) and np.all(np.diff(finer) > 0)
    parts = np.diff(np.searchsorted(finer, grid.mesh_times))
    assert parts[1] == parts.max() > max(parts[0], parts[2]) and finer.size - 1 >= 1.25 * 3


def test_a_refinement_that_gained_less_than_the_order_counts_points_by_the_gain():
    """Where the last refinement cut the estimate as order 0.77 (sliding-mode-terminal's 151 → 265
    points, 7.7e-6 → 5.0e-6), the next mesh's count is what first order asks, not the scheme's
    order 3 (which asked for two more meshes); above first order nothing changes."""
    from qdframe.solve.adaptive import OBSERVED_FLOOR, observed_order, refine

    assert observed_order([7.7e-6], [150]) is None
    assert observed_order([7.7e-6, 5.0e-6], [75, 132]) == pytest.approx(np.log(7.7 / 5.0) / np.log(132 / 75))
    grid = Grid(1.0, 201, "radau-iia")  # 100 intervals, the local error uniform
    local = np.full(100, 1e-8)
    as_promised = refine(grid, local, 1e-6, 4e-6).size - 1
    as_gained = refine(grid, local, 1e-6, 4e-6, observed=0.77).size - 1
    # at most 4× the intervals, as every refinement
    assert as_gained > as_promised and as_gained >= min(400, 100 * (4e-6 / 0.85e-6) ** (1 / max(0.77, OBSERVED_FLOOR)))
    assert refine(grid, local, 1e-6, 4e-6, observed=2.0).size - 1 == as_promised  # above first order: as before


def test_a_free_input_refined_keeps_its_choices_jumps_on_points():
    """coulomb-rest-to-rest (a bounded force, the solutions a set) by the default call:
    with the old points kept, its refinement certifies on at most 400 points (801 when a
    refined mesh moved them, the carried force's jumps then inside intervals)."""
    result = qdframe.solve("coulomb-rest-to-rest")
    assert result.status == "solved", result.message
    assert result.nodes <= 400


@pytest.mark.parametrize("mesh, field, got", [
    ([0.0, 0.5, 0.4, 3.0], "mesh[2]: expected a time > mesh[1] = 0.5", "0.4"),
    ([0.1, 3.0], "mesh[0]: expected 0", "0.1"),
    ([0.0, 2.0], "mesh[1]: expected T = 3", "2.0"),
    ([0.0, float("nan"), 3.0], "mesh[1]: expected a finite mesh time (not NaN or inf)", "nan"),  # not its shape
    ([0.0, 1.0, float("nan")], "mesh[2]: expected a finite mesh time (not NaN or inf)", "nan"),
    (np.array([0.0, np.inf, 3.0]), "mesh[1]: expected a finite mesh time (not NaN or inf)", "inf"),
    ([[0.0, 3.0]], "mesh: expected a list of at least two increasing mesh times from 0 to T = 3", "'shape (1, 2)'"),
    (["a", 3.0], "mesh: expected a list of at least two increasing mesh times from 0 to T = 3", "['a', 3.0]"),
])
def test_a_bad_mesh_is_named(mesh, field, got):
    """One line that names the mesh time at fault (its index), what was expected and what it is."""
    with pytest.raises(InputError) as info:
        qdframe.solve("block-stop-stick", mesh=mesh)
    message = str(info.value)
    assert "\n" not in message and message.startswith(field) and message.endswith(f", got {got}"), message


def test_a_grid_given_a_nan_mesh_time_names_the_nan():
    """Grid's own check (a mesh made by code, not through solve): the NaN, not the shape."""
    with pytest.raises(InputError, match=r"^mesh\[1\]: expected a finite mesh time \(not NaN or inf\), got nan$"):
        Grid.from_mesh(np.array([0.0, np.nan, 1.0]), "trapezoid")


def test_a_mesh_point_on_the_stop_makes_implicit_euler_exact_in_velocity():
    """block-stop-stick stops at t = 1: with a mesh point there, implicit Euler's velocity is
    exact (v' is constant on each piece) and the located stop is 1."""
    tau = np.concatenate([np.linspace(0, 1, 8), np.linspace(1, 3, 12)[1:]])
    result = qdframe.solve("block-stop-stick", mesh=tau)
    exact = qdframe.load_model("block-stop-stick").exact_solution(result.t)
    assert result.converged and result.nodes == tau.size and result.options["uniform"] is False
    assert np.max(np.abs(result.x[:, 1] - exact[:, 1])) <= 1e-9
    assert result.switch_times == pytest.approx([1.0], abs=1e-9)


# ------------------------------------------------------------------------ certification
def test_solved_reports_every_check_against_a_tolerance_scaled_to_the_states():
    result = qdframe.solve("block-stop-stick", nodes=101)
    assert result.converged
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
    assert result.converged
    assert result.boundary_error == pytest.approx(abs(result.x[-1, 0] - 1.0), abs=0.0)


# ---------------------------------------------------------------------- error estimates
def test_the_exact_models_are_all_found():
    """exact_models() finds the built-in ones and the plugin's (a model missing here would
    silently leave every test below)."""
    assert {"block-stop-stick", "block-stop-stick-bvp", "block-breakaway", "slide-on-line", "slide-after-reaching",
            "two-surface-sliding", "stick-slip-oscillator", "paper-7.1", "coulomb-block", "sliding-mode"} <= set(EXACT)


@pytest.mark.parametrize("name, nodes", _cases([101, 1001, 10001]))
def test_a_fixed_grid_has_its_true_error_within_its_estimate(name, nodes):
    """README: on a fixed grid (nodes=N, the default scheme) the discrete problem is solved,
    its estimate is at or above the true error, and it is `solved` exactly where the estimate
    meets the default target 1e-6·max(1, max|x|). The replay of an initial-value problem is
    its true error (to its integration); bisection is 1.25 times a first-order error (the
    bound here: 1.3×), or, where the scheme is exact at the points, within the tolerance. A
    replay that passes the target stops there, with no estimate: what it saw is a lower
    bound of the true error (its motion is the solution)."""
    result = qdframe.solve(name, nodes=nodes)
    assert result.converged, result.message
    scale = max(1.0, float(np.max(np.abs(result.x))))
    if result.error_estimate is None:  # a replay stopped where its difference passed the target
        assert "(the replay stopped there)" in result.message and not result.solved, result.message
        seen = float(result.message.split(" from it by t = ")[0].rsplit(" ", 1)[1])
        # what it saw, to the message's 3 digits: a lower bound of the true error (its motion is the solution)
        assert 1e-6 * scale < seen <= (1 + 5e-3) * result.solution_error + REPLAY_SLACK * scale
        return
    assert result.solution_error <= result.error_estimate
    if result.certificate == "replay":
        assert result.error_estimate <= result.solution_error + REPLAY_SLACK * scale
    else:
        assert result.error_estimate <= ESTIMATE_FACTOR * result.solution_error + RESIDUAL_TOL * scale
    assert result.solved == (result.error_estimate <= 1e-6 * scale)


def test_no_estimate_when_skipped_or_not_solved():
    assert qdframe.solve("block-stop-stick", nodes=101, estimate=False).error_estimate is None
    unfinished = qdframe.solve("block-stop-stick", nodes=101, max_iter=1, simulate_start=False)
    assert unfinished.status == "max_iter" and unfinished.error_estimate is None and unfinished.switch_times.size == 0


# ---------------------------------------------------------------- switches and accuracy
@pytest.mark.parametrize("name, setting", _cases(["accuracy"]))
def test_accuracy_locates_the_switches_and_meets_the_target(name, setting):
    """README: with accuracy=1e-6 every exact problem ends solved with true error within its
    estimate ≤ 1e-6·max(1, max|x|), the switch times it declares within 1e-8."""
    model = qdframe.load_model(name)
    result = qdframe.solve(model, accuracy=1e-6)
    assert result.solved, result.message
    assert result.solution_error <= result.error_estimate <= 1e-6 * max(1.0, float(np.max(np.abs(result.x))))
    exact = _known_switch_times(model)
    if "switch_times" in vars(type(model)) or exact.size:
        assert result.switch_times.size == exact.size, result.switch_times
        assert np.max(np.abs(result.switch_times - exact), initial=0.0) <= 1e-8
    assert "error estimate" in result.message and result.options["accuracy"] == 1e-6


def test_an_unmet_accuracy_says_why():
    result = qdframe.solve("slide-on-line", accuracy=1e-12, max_nodes=200, scheme="implicit-euler")
    assert result.status == "uncertified" and result.error_estimate > 1e-12
    assert "max_nodes = 200" in result.message and "exceeds the target" in result.message


def test_paper_73_is_certified_by_default():
    from qdframe.bench.references import judge

    model = qdframe.load_model("paper-7.3")
    result = qdframe.solve(model)
    assert result.solved and result.certificate == "replay"
    assert judge(model, result.t, result.x, result.z, result.u).error <= result.error_estimate


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


class _LateBreakaway(SetModel):
    """A spring block held by friction 1.5 − 0.5·c above the force bound 1 until c = t = 1:
    p' = v, v' ∈ −p + [−1, 1] − (1.5 − 0.5·c)·Sgn(v), c' = 1; from rest at 0 to rest at 0.3, T = 4.
    Its discrete solutions ride the break-away threshold, where the replayed motion does not
    follow them: the estimate stays near 0.09 however fine the mesh (a new-user trial's problem)."""

    name = "late-breakaway"
    state_names = "p v c"
    default_T = 4.0
    default_x0 = (0.0, 0.0, 0.0)
    default_xT = {"p": 0.3, "v": 0.0}

    def sets(self, p, v, c):
        return {p: v, v: -p + Interval(-1, 1) - (1.5 - 0.5 * c) * Sgn(v), c: 1}


def test_an_estimate_that_stalls_under_refinement_stops_the_refinement():
    """Where two refinements do not halve the estimate, more points will not certify: the call
    ends `uncertified` after three estimates and says why, instead of refining to max_nodes
    (84841 points before this rule)."""
    result = qdframe.solve(_LateBreakaway())
    assert result.status == "uncertified"
    assert "the estimate stalls near" in result.message
    assert result.nodes < 1000 and result.options["grids"][-1] < 1000
