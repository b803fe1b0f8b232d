"""The replay reference (qdframe.certificates.projection_replay): the nearest velocity against brute
force, and replays of exact, solved and perturbed trajectories."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

import qdframe
from qdframe.certificates.projection_replay import nearest_velocity, replay
from qdframe.errors import InputError
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.registry import lookup


def _model(name: str, **overrides):
    return lookup("models", name).obj(**overrides)


def _functional(model, nodes: int) -> Functional:
    return Functional(model, Grid(model.T, nodes), signs="band", psi_samples=32)


# ------------------------------------------------------------------ nearest velocity
def test_nearest_velocity_interval_blocks_are_clips():
    """velocity-range: x1' ∈ co{x1, x2, x3} (an interval), x2' = x3, x3' = −x2 (equations)."""
    rng = np.random.default_rng(3)
    model = _model("velocity-range")
    x, z = rng.normal(size=(500, 3)), 2 * rng.normal(size=(500, 3))
    P = nearest_velocity(_functional(model, 500), np.concatenate([x, z], axis=1))
    expected = np.stack([np.clip(z[:, 0], x.min(axis=1), x.max(axis=1)), x[:, 2], -x[:, 1]], axis=1)
    np.testing.assert_allclose(P, expected, atol=1e-14)
    assert np.any(P[:, 0] != z[:, 0]) and np.any(P[:, 0] == z[:, 0])  # both cases occur


def test_nearest_velocity_sum_of_intersection_and_ball():
    """disturbed-control's x2 block: a21·x1 + a22·x2 + [−1, 1] ∩ [−2x1 − 0.5, −2x1 + 0.5] + 0.1|x|·[−1, 1]."""
    rng = np.random.default_rng(4)
    model = _model("disturbed-control")
    x, z = rng.normal(size=(500, 2)), 3 * rng.normal(size=(500, 2))
    P = nearest_velocity(_functional(model, 500), np.concatenate([x, z], axis=1))
    base = -x[:, 0] - 0.5 * x[:, 1]
    spread = 0.1 * np.abs(x).sum(axis=1)
    lo = base + np.maximum(-1, -2 * x[:, 0] - 0.5) - spread
    hi = base + np.minimum(1, -2 * x[:, 0] + 0.5) + spread
    expected = np.where(lo <= hi, np.clip(z[:, 1], lo, hi), 0.5 * (lo + hi))  # empty: the middle
    np.testing.assert_allclose(P[:, 0], x[:, 1], atol=1e-14)
    np.testing.assert_allclose(P[:, 1], expected, atol=1e-13)


def _lens_constraints(name: str, x: np.ndarray):
    """The two convex sets of the block as inequality constraints g(v) ≥ 0."""
    if name == "paper-7.2":
        a = x[0] ** 2 + 3.0
        return [lambda v: 1.0 - v @ v, lambda v: 1.0 - (v[0] - 2.0) ** 2 / a - v[1] ** 2]
    offset = -0.5 * x
    return [lambda v: 2.25 - np.sum((v - offset - [-1.0, 0.0]) ** 2),
            lambda v: 2.25 - np.sum((v - offset - [1.0, 0.0]) ** 2)]


def _brute_projection(z: np.ndarray, constraints) -> np.ndarray:
    cons = [{"type": "ineq", "fun": g} for g in constraints]
    best = None
    for start in (np.zeros(2), 0.5 * z, np.array([0.3, 0.0])):
        result = minimize(lambda v: np.sum((v - z) ** 2), start, jac=lambda v: 2 * (v - z), constraints=cons,
                          method="SLSQP", options={"ftol": 1e-16, "maxiter": 500})
        if min(g(result.x) for g in constraints) > -1e-10 and (best is None or result.fun < best.fun):
            best = result
    return best.x


@pytest.mark.parametrize("name", ["paper-7.2", "intersecting-balls"])
def test_nearest_velocity_on_intersections_against_brute_force(name):
    """The nearest point of the lens (disc ∩ ellipse of 7.2, the plugin's two balls) by
    SLSQP. Away from the lens' corners the formula z − h·ψ* is the nearest point; in a
    corner's normal cone (c̃ = min gives max(dist A, dist B) < dist(A ∩ B)) the repeated
    step gives a point of the lens within 3·dist(z, F) of z, not the nearest one."""
    rng = np.random.default_rng(5)
    model = _model(name)
    count = 150
    x = rng.uniform(-1.2, 1.2, size=(count, 2))
    z = rng.uniform(-2.0, 2.5, size=(count, 2))
    z[:50] = 0.5 * z[:50]  # many inside or near
    P = nearest_velocity(_functional(model, count), np.concatenate([x, z], axis=1))
    exact, corner = 0, 0
    for k in range(count):
        constraints = _lens_constraints(name, x[k])
        best = _brute_projection(z[k], constraints)
        assert min(g(P[k]) for g in constraints) > -1e-9, f"node {k}: the projection is outside F"
        if np.max(np.abs(P[k] - best)) <= 1e-7:
            exact += 1
            continue
        corner += 1
        assert all(abs(g(best)) < 1e-7 for g in constraints), f"node {k}: off by {P[k] - best} away from a corner"
        assert np.linalg.norm(P[k] - z[k]) <= 3.0 * np.linalg.norm(best - z[k]) + 1e-12
    print(f"\n{name}: {exact} of {count} nearest points exact (1e-7), {corner} in a corner's normal cone")
    assert exact >= 0.6 * count and np.any(np.linalg.norm(P - z, axis=1) > 0.1)


# ------------------------------------------------------------------ replays
def _lens_boundary_trajectory(T: float = 1.0, nodes: int = 101):
    """intersecting-balls with x' = −0.5x + w, w on the left ball's boundary inside the
    right ball (outward normal n): the exact x = 2w(1 − e^{−t/2}), and n."""
    n = np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)])
    w = np.array([-1.0, 0.0]) + 1.5 * n
    t = np.linspace(0.0, T, nodes)
    x = 2 * w * (1 - np.exp(-0.5 * t))[:, None]
    z = -0.5 * x + w
    return t, x, z, n


def test_replay_of_an_exact_solution_and_of_pushed_velocities():
    """Unperturbed: the replay is the trajectory itself up to the linear interpolation of
    z (the exact z is exponential in t: |z − z_lin| ≤ h²/8·max|z''|, z'' = z/4 here, so the
    replay is second order in h). Velocities pushed outward by δ (x moved with them,
    x + δ·n·t): the replay is the unpushed motion, error = δ·T·max|n_i|."""
    previous = None
    for nodes in (101, 1001):
        t, x, z, n = _lens_boundary_trajectory(nodes=nodes)
        model = _model("intersecting-balls", end_values=x[-1])
        exact = replay(model, t, x, z)
        print(f"\nexact lens-boundary trajectory, N = {nodes}: {exact}")
        h = t[1] - t[0]
        interpolation = t[-1] * h**2 / 8 * np.max(np.abs(z)) / 4
        assert exact.error <= interpolation and exact.end_miss <= interpolation and exact.uncertainty <= 1e-10
        if previous is not None:
            assert 80 <= previous / exact.error <= 120  # (1001 − 1)/(101 − 1) = 10: second order
        previous = exact.error
    errors = []
    for delta in (1e-4, 1e-3, 1e-2, 1e-1):
        pushed = replay(model, t, x + delta * n * t[:, None], z + delta * n)
        print(f"δ = {delta:g}: {pushed}")
        assert abs(pushed.error - delta * t[-1] * np.max(np.abs(n))) <= exact.error + 1e-10
        assert pushed.end_miss <= exact.end_miss + 1e-10  # a genuine solution, with the unpushed end
        errors.append(pushed.error)
    assert np.all(np.diff(errors) > 0)


def test_replay_of_paper71_exact_solution():
    """paper-7.1's known solution x1 = 0, x2 = t (z1 = 0 on the interval's end)."""
    model = _model("paper-7.1")
    for nodes in (11, 1001):
        t = np.linspace(0.0, 1.0, nodes)
        x = model.exact_solution(t)
        z = np.tile([0.0, 1.0], (nodes, 1))
        result = replay(model, t, x, z)
        print(f"\npaper-7.1 exact, N = {nodes}: {result}")
        assert result.error <= 1e-8 and result.end_miss <= 1e-8 and result.uncertainty <= 1e-8


def test_replay_of_a_pushed_solution_of_paper72():
    """qdframe's converged solve of paper-7.2: error at its discretization level; its
    velocities pushed by δ out of the unit disc (radially, x with them): error ~ δ·t,
    growing with δ (the pushed velocity's projection is the radial one, so the replay
    does not return to the solve's own trajectory)."""
    solved = qdframe.solve("paper-7.2", nodes=1001)
    assert solved.solved
    base = replay("paper-7.2", solved.t, solved.x, solved.z)
    print(f"\npaper-7.2, N = 1001: {base}")
    assert base.error <= 1e-7 and base.end_miss <= 1e-7 and base.uncertainty <= 1e-9
    # put the velocity on the unit circle (in the ellipse there), then push it out by δ; on
    # 201 points (at 1001 the pushed replays take 2 minutes: every sub-step projects)
    coarse = qdframe.solve("paper-7.2", nodes=201)
    direction = coarse.z / np.linalg.norm(coarse.z, axis=1, keepdims=True)
    t = coarse.t
    errors = []
    for delta in (1e-3, 1e-2, 1e-1):
        z = (1.0 + delta) * direction
        x = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (z[1:] + z[:-1]) * np.diff(t)[:, None], axis=0)])
        pushed = replay("paper-7.2", t, x, z)
        print(f"δ = {delta:g}: {pushed}")
        bound = delta * t[-1] * np.max(np.abs(direction))
        assert 0.5 * bound <= pushed.error <= 1.01 * bound
        errors.append(pushed.error)
    assert np.all(np.diff(errors) > 0)


def test_replay_error_of_an_implicit_euler_solve_is_first_order():
    """velocity-range (implicit Euler): the replay's error halves with the step."""
    errors = []
    for nodes in (101, 201, 401):
        solved = qdframe.solve("velocity-range", nodes=nodes, continuation="none")
        result = replay("velocity-range", solved.t, solved.x, solved.z)
        print(f"\nvelocity-range N = {nodes}: {result}")
        assert result.uncertainty <= 1e-8
        errors.append(result.error)
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((ratios > 1.6) & (ratios < 2.5)), ratios


def test_replay_shape_errors_name_the_argument():
    t = np.linspace(0, 1, 11)
    with pytest.raises(InputError, match=r"^x: expected shape \(11, 2\)"):
        replay("paper-7.2", t, np.zeros((11, 3)), np.zeros((11, 2)))
    with pytest.raises(InputError, match=r"^z: expected shape \(11, 2\)"):
        replay("paper-7.2", t, np.zeros((11, 2)), np.zeros((10, 2)))
    with pytest.raises(InputError, match=r"^t: expected increasing"):
        replay("paper-7.2", t[::-1], np.zeros((11, 2)), np.zeros((11, 2)))
    with pytest.raises(InputError, match=r"^u: expected None"):
        replay("paper-7.2", t, np.zeros((11, 2)), np.zeros((11, 2)), np.zeros((11, 1)))
