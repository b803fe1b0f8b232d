"""The gauss-newton direction: against a dense Levenberg–Marquardt step, and on the paper's examples."""

import numpy as np
import pytest

import qdframe
from qdframe.directions.gauss_newton import GaussNewton, Step
from qdframe.directions.linearized_system import LinearizedSystem
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid


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
    system = LinearizedSystem(functional, xi, delta=1e-3)
    step_ext, predicted, slope, _ = Step(system).solve(mu)
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
def test_paper_examples_to_1e_10(name, nodes, certified):
    result = qdframe.solve(name, nodes=nodes, direction="gauss-newton", tol=1e-10, max_iter=10)
    certified(result)  # within 10 iterations: every residual within 1e-8 of the states' scale
    assert result.I <= 1e-10 and result.objective <= 1e-10
    if name == "paper-7.1":  # x1 = 0, x2 = t: the trapezoid rule is exact on it (measured 3.4e-13)
        assert result.solution_error <= 1e-8


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


def _three_pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """max(x1, −x1, x2 − 1/2): a max-group whose three pieces can tie two or three at a node."""
    grads = np.zeros((y.shape[0], 3, y.shape[1]))
    grads[:, 0, 0], grads[:, 1, 0], grads[:, 2, 1] = 1.0, -1.0, 1.0
    return np.stack([y[:, 0], -y[:, 0], y[:, 1] - 0.5], axis=1), grads


def _models_with_a_cost():
    from qdframe.model import Cost
    from qdframe.models.paper import Paper71

    class ThreePieces(Paper71):
        def cost(self):
            return Cost(max_groups=(_three_pieces,), weight=self.penalty)

    return [qdframe.load_model("paper-7.1"), ThreePieces()]


@pytest.mark.parametrize("model_index", [0, 1])
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("exact", [True, False])
def test_the_active_set_step_minimizes_the_step_qp(model_index, seed, exact, monkeypatch):
    """With a nonsmooth cost, the step the active-set iteration settles on minimizes the same
    model as the Clarabel QP (a second method): ½dᵀHd + gᵀd + the cost's max-pieces + the
    hinges, whose value at the QP's step is the optimum. Made exact (ACTIVE_SET_TOL = 0) it
    reaches the optimum and the QP's step; by default (violations left out that change the
    model by ≤ 1e-3 of the decrease) within 1 % of it. Started again from the set it settled
    on, it takes one KKT solve and gives the same step."""
    import qdframe.directions.gauss_newton as gn

    if exact:
        monkeypatch.setattr(gn, "ACTIVE_SET_TOL", 0.0)
    model = _models_with_a_cost()[model_index]
    functional = Functional(model, Grid(1.0, 21))
    rng = np.random.default_rng(seed)
    x = np.stack([0.2 * rng.normal(size=21), np.linspace(0, 1, 21) + 0.2 * rng.normal(size=21)], axis=1)
    z = np.stack([0.5 * rng.normal(size=21), 1.0 + 0.5 * rng.normal(size=21)], axis=1)
    x[0] = model.x0
    xi = functional.pack(x, z)
    mu = 1e-4
    system = LinearizedSystem(functional, xi, delta=1e-3)
    step = Step(system)
    d, predicted, _, settled = step.solve(mu)
    assert settled is not None, "the active-set iteration fell back to the QP"
    # the guesses change the tied pieces, not the pattern of the constraint rows: one analysis
    assert step.kkt.analyses == 1
    J, lam, damping = system.jacobian, system.penalty, mu * system.damping()
    hessian = (lam * (J.T @ J) + gn.sp.diags(damping)).tocsc()
    clarabel = gn.make_step_qp("clarabel")  # the raw QP step (no polish by the active-set iteration)
    d_qp, predicted_qp, *_ = step.qp.solve(lambda reduced: hessian, lam * (J.T @ system.residual), clarabel,
                                           polish=False, previous=None)

    def model_value(step, decrease):  # the QP's objective, up to the constant I(ξ)
        return -decrease + 0.5 * float(damping @ step**2)

    optimum, found = model_value(d_qp, predicted_qp), model_value(d, predicted)
    assert optimum < 0 and optimum - 1e-8 * abs(optimum) <= found <= optimum + (1e-8 if exact else 1e-2) * abs(optimum)
    if exact:
        assert np.abs(d - d_qp).max() <= 1e-5 * np.abs(d_qp).max()
    solves = []
    real = gn.solve_kkt
    monkeypatch.setattr(gn, "solve_kkt", lambda *args, **kwargs: solves.append(1) or real(*args, **kwargs))
    again = Step(LinearizedSystem(functional, xi, delta=1e-3))
    d_warm, predicted_warm, *_ = again.solve(mu, warm=settled)
    # the same step, to the rounding of another pivot order (a fresh KKTSolver's own analysis)
    assert len(solves) == 1 and np.allclose(d_warm, d, rtol=0, atol=1e-9 * np.abs(d).max())
    assert np.isclose(predicted_warm, predicted, rtol=1e-12)


def test_the_active_set_iteration_stops_at_a_guess_it_has_solved(monkeypatch):
    """The next guess is a function of the last, so a guess that comes back starts a cycle
    that never settles: the iteration hands the step to the QP there, not after MAX_GUESSES
    solves. block-time-optimal on 21 nodes cycles through 2–15 guesses in many steps; no
    guess is solved twice, and the shortest time is still found."""
    import qdframe.directions.gauss_newton as gn

    runs, current = [], []
    guess_step, solve = gn.ActiveSetIteration._guess_step, gn.ActiveSetIteration.solve

    def counted_guess(self, hessian, gradient, active, ties):
        current.append((active.tobytes(), *(tie.tobytes() for tie in ties)))
        try:
            return guess_step(self, hessian, gradient, active, ties)
        except gn.BackendError:
            current.append("singular")
            raise

    def counted_solve(self, *args):
        current.clear()
        found = solve(self, *args)
        runs.append((list(current), found))
        return found

    monkeypatch.setattr(gn.ActiveSetIteration, "_guess_step", counted_guess)
    monkeypatch.setattr(gn.ActiveSetIteration, "solve", counted_solve)
    result = qdframe.solve("block-time-optimal", nodes=21, estimate=False)
    assert abs(result.T - 4 / 3 * np.sqrt(1.5)) <= 1e-6
    assert all(len(set(guesses)) == len(guesses) for guesses, _ in runs)  # none solved twice
    cut = [guesses for guesses, found in runs if found is None and "singular" not in guesses
           and len(guesses) < gn.MAX_GUESSES]
    assert cut  # steps handed over at a repeated guess
