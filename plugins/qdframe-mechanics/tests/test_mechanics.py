"""qdframe-mechanics: the six Section 5 models are registered under this distribution,
pass `check-model`, have feasible boundary data and solve with the default method."""

import json

import numpy as np
import pytest

import qdframe
from qdframe.authoring import check_model
from qdframe.cli import main
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.sets import SetModel, Sgn
from qdframe_mechanics.models import CoulombBlock

MODELS = ["coulomb-block", "sliding-mode", "double-pendulum", "velocity-range", "disturbed-control", "intersecting-balls"]


def test_list_json_shows_the_six_models_under_this_distribution(capsys):
    assert main(["list", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    ours = {e["name"] for e in listing["models"] if e["distribution"] == "qdframe-mechanics"}
    assert ours == set(MODELS)
    assert all(e["description"] for e in listing["models"] if e["name"] in MODELS)


@pytest.mark.parametrize("name", MODELS)
def test_check_model_passes(name):
    report = check_model(qdframe.load_model(name), samples=32)
    assert report.ok, report.table()


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("nodes", [11, 101])
def test_default_solve_is_solved(name, nodes):
    result = qdframe.solve(name, nodes=nodes)
    assert result.converged, result.message  # the discrete problem (a grid of 11 is not meant to meet 1e-6)
    assert result.I <= 1e-10 and result.objective <= 1e-10
    # what `solved` certifies: each residual within residual_tol = 1e-8 of the states' scale
    scale_x, scale_z = max(1.0, np.max(np.abs(result.x))), max(1.0, np.max(np.abs(result.z)))
    assert result.boundary_error <= 1e-8 * scale_x and result.consistency_error <= 1e-8 * scale_x
    assert result.inclusion_residual <= 1e-8 * scale_z
    if result.solution_error is not None:  # unique solutions: near the known one, to implicit Euler's O(h)
        assert result.solution_error <= 2 * model_step(name, nodes)
    if result.selections is not None:  # Filippov's inclusion holds strictly: λ ∈ Sgn(s)
        assert result.selection_residual <= 1e-8 and np.all(np.abs(result.selections) <= 1 + 1e-8)


def model_step(name, nodes):
    return qdframe.load_model(name).T / (nodes - 1)


@pytest.mark.parametrize("name", MODELS)
def test_boundary_data_comes_from_a_motion_in_the_inclusion(name):
    """The reference motion starts at x0, ends at the end values and stays in F (to O(h²));
    Filippov's set with the C¹ band contains it (signs="band": no selections to choose)."""
    model = qdframe.load_model(name)
    grid = Grid(model.T, 2001)
    x = model.reference_solution(grid.t)
    assert np.allclose(x[0], model.x0, atol=1e-9)
    assert np.allclose(x[-1, list(model.end_indices)], model.end_values, atol=1e-9)
    z = np.gradient(x, grid.t, axis=0, edge_order=2)
    functional = Functional(model, grid, signs="band")
    xi = functional.pack(x, z, None if not model.n_controls else np.zeros((grid.nodes, model.n_controls)))
    assert functional.residuals(xi).inclusion_residual <= 1e-3


def test_stored_end_values_match_fresh_computations():
    from scipy.linalg import expm

    from qdframe_mechanics.models import _pendulum_run

    pendulum = qdframe.load_model("double-pendulum")
    assert np.allclose(pendulum.end_values, _pendulum_run().y[:2, -1], atol=1e-12)
    disturbed = qdframe.load_model("disturbed-control")
    assert np.allclose(disturbed.end_values, expm(disturbed.closed_loop * disturbed.T) @ disturbed.x0, atol=1e-12)


def test_models_with_a_unique_solution_state_it():
    for name in ("coulomb-block", "sliding-mode"):
        model = qdframe.load_model(name)
        t = np.linspace(0, model.T, 5)
        assert np.allclose(model.exact_solution(t), model.reference_solution(t))
    for name in ("double-pendulum", "velocity-range", "disturbed-control", "intersecting-balls"):
        assert qdframe.load_model(name).exact_solution(np.linspace(0, 1, 5)) is None


def test_coulomb_block_sticks_under_the_simulator():
    """Past T = 2 the block is at rest: the Filippov simulator keeps v = 0 (|g| < μ·F_N)."""
    from qdframe.simulate import simulate

    run = simulate(CoulombBlock(), 0.0, 2.5, (0.0, 3.0), dt=2e-3)
    assert run.x[run.t >= 2.05, 1] == pytest.approx(0.0, abs=1e-9)
    assert run.x[-1, 0] == pytest.approx(3.0, abs=5e-3)


def test_sliding_mode_stays_on_its_surface():
    errors = {}
    for nodes in (101, 1001):
        result = qdframe.solve("sliding-mode", nodes=nodes)
        assert result.converged and result.surface_error <= 1e-8
        errors[nodes] = result.solution_error
    # implicit Euler's O(h) against e^{−2t}: a tenth of the step, a tenth of the error
    assert errors[1001] / errors[101] == pytest.approx(0.1, rel=0.05)


def test_intersecting_balls_start_where_psi_star_is_not_unique():
    model = qdframe.load_model("intersecting-balls")
    functional = Functional(model, Grid(model.T, 11))
    xi = functional.initial_point()
    (side,) = functional.distance_sides(xi)[0].sides
    psi = side[2]
    # z − (−0.5x) = (0, 2) is equidistant from both balls: ℓ(ψ) = 2ψ2 − 1.5 + |ψ1| is largest
    # at both ψ* = (±1, 2)/√5 (Remark 5.1); the search returns one of them at every node
    assert np.allclose(np.abs(psi[:, 0]), 1 / np.sqrt(5), atol=1e-6) and np.allclose(psi[:, 1], 2 / np.sqrt(5), atol=1e-6)
    assert np.allclose(side[0], np.sqrt(5) - 1.5, atol=1e-9)


def test_the_stick_phase_is_solved_strictly():
    """coulomb-block stops at t = 2 and sticks until T = 3: v = 0 to solver precision there,
    the friction selection is g/(μ·F_N) = 0.7 (λ of Sgn(−v) = −Sgn(v): −0.7), and the error
    against the exact motion is first order (implicit Euler)."""
    errors = {}
    for nodes in (101, 1001):
        result = qdframe.solve("coulomb-block", nodes=nodes)
        assert result.converged, result.message
        stuck = result.t > 2.0 + 2 * result.T / (nodes - 1)
        assert np.max(np.abs(result.x[stuck, 1])) <= 1e-8  # residual_tol
        # λ = (z − g)/(μ·F_N) with z = Δv/h: v's 1e-8 becomes ~1e-8/h in λ
        assert result.selections[stuck, 0] == pytest.approx(-0.7, abs=1e-8 * nodes)
        errors[nodes] = result.solution_error
    assert errors[1001] / errors[101] == pytest.approx(0.1, rel=0.1)
