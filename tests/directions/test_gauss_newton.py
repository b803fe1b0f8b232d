"""The gauss-newton direction: against a dense Levenberg–Marquardt step, and on the paper's examples."""

import numpy as np
import pytest

import qdframe
from qdframe.directions.gauss_newton import GaussNewton, _System
from qdframe.functional import Functional
from qdframe.grid import Grid


def dense_cumulative(nodes: int, h: float) -> np.ndarray:
    C = np.zeros((nodes, nodes))
    for k in range(1, nodes):
        C[k] = C[k - 1]
        C[k, k - 1] += h / 2
        C[k, k] += h / 2
    return C


def dense_residuals(functional: Functional, xi: np.ndarray) -> np.ndarray:
    """r(ξ) with x(t0) fixed, written with a dense cumulative matrix; I = ½‖r‖²."""
    x, z = functional.split(xi)
    w = functional.weights
    C = dense_cumulative(functional.grid.nodes, functional.grid.step)
    h = np.stack([side.h for side in functional.distance_sides(xi)], axis=1)
    parts = [(np.sqrt(w)[:, None] * h).ravel(), (np.sqrt(w)[:, None] * (x - functional.model.x0 - C @ z)).ravel()]
    model = functional.model
    if model.end_indices:
        parts.append(model.x0[list(model.end_indices)] + (w @ z)[list(model.end_indices)] - model.end_values)
    return np.concatenate(parts)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_step_equals_a_dense_levenberg_marquardt_step(seed):
    """Without a cost, and with every z far outside its set (every hinge stays active), the step
    solves (JᵀJ + μW) d = −Jᵀr on the free unknowns, J by finite differences."""
    model = qdframe.load_model("paper-7.2")
    functional = Functional(model, Grid(1.0, 6))
    rng = np.random.default_rng(seed)
    xi = functional.pack(rng.normal(size=(6, 2)) * 0.3, rng.normal(size=(6, 2)) * 0.3 + 3.0)  # z far outside the sets
    free = functional.free.ravel()
    r0 = dense_residuals(functional, xi)
    J = np.zeros((r0.size, free.sum()))
    for column, index in enumerate(np.flatnonzero(free)):
        e = np.zeros(xi.size)
        e[index] = 1e-7
        J[:, column] = (dense_residuals(functional, xi + e.reshape(xi.shape)) -
                        dense_residuals(functional, xi - e.reshape(xi.shape))) / 2e-7
    mu = 0.3
    W = np.repeat(functional.weights, xi.shape[1]).reshape(xi.shape).ravel()[free]
    expected = np.linalg.solve(J.T @ J + mu * np.diag(W), -J.T @ r0)
    system = _System(functional, xi, delta=1e-3)
    step_ext, predicted, slope = system.solve(mu)
    step = system.unknowns_step(step_ext).ravel()
    assert np.allclose(step[free], expected, rtol=1e-5, atol=1e-7)
    assert np.all(step[~free] == 0)
    assert np.isclose(slope, (J.T @ r0) @ expected, rtol=1e-5)
    assert np.isclose(predicted, -(r0 @ J @ expected + 0.5 * np.sum((J @ expected) ** 2)), rtol=1e-5)


@pytest.mark.parametrize("name", ["paper-7.1", "paper-7.2"])
def test_slope_matches_the_directional_derivative(name):
    model = qdframe.load_model(name)
    functional = Functional(model, Grid(1.0, 21))
    xi = functional.initial_point()
    direction = GaussNewton().compute(functional, xi, 1e-3)
    assert direction.slope < 0
    alpha = 1e-7
    fd = (functional.objective(xi + alpha * direction.step) - functional.objective(xi)) / alpha
    assert fd == pytest.approx(direction.slope, rel=1e-3)


@pytest.mark.parametrize("nodes", [11, 101])
@pytest.mark.parametrize("name", ["paper-7.1", "paper-7.2"])
def test_paper_examples_to_1e_10(name, nodes):
    result = qdframe.solve(name, nodes=nodes, direction="gauss-newton", tol=1e-10, max_iter=10)
    assert result.status == "solved"
    assert result.I <= 1e-10 and result.iterations <= 10
    assert result.boundary_error <= 1e-5
    assert result.inclusion_residual <= 2e-4
    if name == "paper-7.1":
        assert result.objective <= 1e-4
        assert result.solution_error <= 1e-3  # x1 = 0, x2 = t


def test_unreachable_end_point_ends_stationary_not_solved():
    model = qdframe.load_model("paper-7.2", end_values=[5.0, 5.0])
    result = qdframe.solve(model, nodes=21, direction="gauss-newton", max_iter=60)
    assert result.status in {"stationary", "max_iter"}
    assert result.I > 1.0


def test_a_fresh_solve_restarts_the_damping():
    solver = GaussNewton()
    first = qdframe.solve("paper-7.2", nodes=11, direction=solver, tol=1e-10)
    second = qdframe.solve("paper-7.2", nodes=11, direction=solver, tol=1e-10)
    assert first.iterations == second.iterations and first.I == second.I
