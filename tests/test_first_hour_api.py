"""Issue 17 ("a new user's first hour"), items 4, 10 and 15: a NaN mid-run is one error
naming the returned iterate's node and state, loading paper-7.3 does not simulate, and
the returned x(t_0) is x0 exactly."""

import re

import numpy as np
import pytest

import qdframe
from qdframe import registry
from qdframe.cli import main as cli_main
from qdframe.errors import ModelOutputError
from qdframe.model import InclusionModel, SetBlock


# ---------------------------------------------------------------- item 4: NaN mid-run
class NaNPastThreshold(InclusionModel):
    """pos' = vel, vel' = 1 − pos, pos(0) = 0, pos(1) = 1 (vel(0) free): the solution
    pos = 1 − cos t + cot(1)·sin t rises to 1 at t = 1; vel' is NaN where pos > threshold
    (`gradient`: only its gradient is NaN there), a region the descent reaches mid-run."""

    name = "test-nan-mid-run"
    state_names = ("pos", "vel")
    default_x0 = (0.0, float("nan"))
    end_indices = (0,)
    default_end_values = (1.0,)
    threshold = 0.5
    gradient = False

    def blocks(self):
        threshold, gradient_only = self.threshold, self.gradient

        def position(y):
            grad = np.zeros_like(y)
            grad[:, 1] = 1.0
            return y[:, 1].copy(), grad

        def velocity(y):
            grad = np.zeros_like(y)
            grad[:, 0] = -1.0
            past = y[:, 0] > threshold
            if gradient_only:
                return 1.0 - y[:, 0], np.where(past[:, None], np.nan, grad)
            return np.where(past, np.nan, 1.0 - y[:, 0]), grad

        return (SetBlock.equation(0, position, name="pos'"), SetBlock.equation(1, velocity, name="vel'"))


def nan_model(threshold: float, gradient: bool = False) -> InclusionModel:
    return type("NaNModel", (NaNPastThreshold,), {"threshold": threshold, "gradient": gradient})()


def test_the_model_is_finite_at_the_start_and_on_the_solution():
    result = qdframe.solve(nan_model(np.inf), nodes=21)
    assert result.converged and 0.99 < result.x[:, 0].max() < 1.01


@pytest.mark.parametrize("direction", ["gauss-newton", "native"])
def test_a_nan_trial_point_is_rejected_not_a_failure(direction):
    """γ̄ = 2 overshoots pos to 2 > 1.5 on the first trial (NaN): the line search steps back."""
    result = qdframe.solve(nan_model(1.5), nodes=21, direction=direction, gamma_max=2.0, max_iter=40)
    assert result.status != "failed"
    assert np.all(np.isfinite(result.x)) and result.x[:, 0].max() <= 1.5
    if direction == "gauss-newton":
        assert result.converged


def _located(message: str, model: InclusionModel) -> tuple[int, float, dict[str, float]]:
    """The node, t and the named state values of an iterate's NaN message."""
    match = re.search(r"at node (\d+) \(t = ([0-9.e+-]+)\) of the iterate after \d+ iterations, where \((.*?)\)", message)
    assert match, message
    node, t = int(match.group(1)), float(match.group(2))
    state = dict(pair.split(" = ") for pair in match.group(3).split(", "))
    return node, t, {k: float(v) for k, v in state.items()}


def test_a_nan_that_stops_the_descent_names_the_returned_iterates_node_and_state():
    """pos must rise to 1 but vel' is NaN past 0.5: gauss-newton drives pos to 0.5 at t = 1,
    where every step goes past it. The error names that node and the state there."""
    model = nan_model(0.5)
    with pytest.raises(ModelOutputError) as info:
        qdframe.solve(model, nodes=21)
    message = str(info.value)
    assert "\n" not in message and "'test-nan-mid-run'" in message and "max-group \"vel'\"" in message
    assert "the descent cannot continue" in message
    node, t, state = _located(message, model)
    assert set(state) == {"pos", "vel"}
    assert node == 20 and t == 1.0
    assert state["pos"] <= 0.5 and abs(state["pos"] - 0.5) < 1e-6  # finite at the iterate, NaN just past it
    assert info.value.nonfinite and info.value.node == node


def test_a_nan_gradient_stops_the_descent_the_same_way():
    """Only the gradient is NaN past 0.3: trial points there are rejected all the same."""
    model = nan_model(0.3, gradient=True)
    with pytest.raises(ModelOutputError) as info:
        qdframe.solve(model, nodes=21)
    message = str(info.value)
    assert "max-group \"vel'\" Jacobian is non-finite" in message
    node, t, state = _located(message, model)
    assert abs(state["pos"] - 0.3) < 1e-6 and np.isclose(t, node / 20)


def test_a_nan_when_the_direction_evaluates_the_accepted_iterate_names_its_state():
    """A direction that meets the model's NaN at the accepted iterate itself (here simulated
    after one step, gauss-newton solving paper-7.1 in two): the error gives the state of that
    iterate at the node."""
    from qdframe.directions.gauss_newton import GaussNewton

    class Failing(GaussNewton):
        name = "failing"

        calls = 0  # this descent's calls (start() begins a descent)

        def start(self, functional):
            super().start(functional)
            self.calls = 0

        def compute(self, functional, xi, delta):
            if self.calls == 1:
                self.seen = xi.copy()
                raise ModelOutputError("model 'x': a piece returned a non-finite value at node 3",
                                       label="block vel' max-group \"vel'\"", node=3, nonfinite=True)
            self.calls += 1
            return super().compute(functional, xi, delta)

    model = qdframe.load_model("paper-7.1")
    direction = Failing()
    with pytest.raises(ModelOutputError) as info:
        qdframe.solve(model, nodes=11, direction=direction)
    message = str(info.value)
    node, t, state = _located(message, model)
    assert node == 3 and np.isclose(t, 0.3) and "of the iterate after 1 iterations" in message
    assert np.allclose([state["x1"], state["x2"]], direction.seen[3, :2], rtol=1e-5, atol=1e-12)


def test_a_nan_at_the_start_names_the_start_state():
    model = nan_model(0.5)
    model.x0 = np.array([0.7, np.nan])
    with pytest.raises(ModelOutputError, match=r"at node 0 \(t = 0\) of the start, where \(pos = 0\.7, vel = 0\)"):
        qdframe.solve(model, nodes=11)


def test_the_command_line_prints_one_error_line_and_exits_1(monkeypatch, capsys):
    real = registry.lookup

    def lookup(kind, name):
        if kind == "models" and name == "test-nan-mid-run":
            return registry.Entry("models", name, "test", "test:NaNPastThreshold", NaNPastThreshold)
        return real(kind, name)

    monkeypatch.setattr("qdframe.registry.lookup", lookup)
    assert cli_main(["solve", "test-nan-mid-run", "--nodes", "21"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""  # no summary
    assert captured.err.count("\n") == 1
    assert captured.err.startswith("qdframe: error: model 'test-nan-mid-run': block vel' max-group")
    assert "at node 20 (t = 1) of the iterate" in captured.err and "pos = 0.5" in captured.err


# ---------------------------------------------------------------- item 15: x(t_0) = x0 exactly
@pytest.mark.parametrize("name", ["paper-7.1", "paper-7.2", "paper-7.3-reduced"])
@pytest.mark.parametrize("direction", ["gauss-newton", "native"])
def test_the_returned_x_at_t0_is_x0_exactly(name, direction):
    """paper-7.1 with gauss-newton (its step QP, Clarabel) moved x(t_0) by ~1e-15 before."""
    model = qdframe.load_model(name)
    result = qdframe.solve(model, nodes=21, direction=direction, max_iter=15)
    given = np.isfinite(model.x0)
    assert given.any()
    assert np.array_equal(result.x[0, given], model.x0[given])


def test_a_free_start_coordinate_is_solved_for():
    """x1(0) = 0 given, x2(0) free, x2(1) = 1: the cost ∫|x1| is least at x1 ≡ 0, where
    x1' = 0 ∈ [0, x2] ∩ [x2 − 1, x2 + 1] holds for |x2| ≤ 1, so x2' = x1 + 1 = 1 and
    x2(0) = x2(1) − 1 = 0 (the paper's solution x2 = t, found from a free start)."""
    model = qdframe.load_model("paper-7.1", x0=[0.0, float("nan")])
    result = qdframe.solve(model, nodes=21)
    assert result.converged, result.message
    assert result.x[0, 0] == 0.0
    assert abs(result.x[0, 1]) <= 1e-8  # the value solved for, not only some finite number
    assert np.max(np.abs(result.x[:, 0])) <= 1e-8 and np.max(np.abs(result.x[:, 1] - result.t)) <= 1e-8


def test_a_direction_that_moves_x0_beyond_rounding_is_an_error():
    from qdframe.directions.gauss_newton import GaussNewton

    class Drifting(GaussNewton):
        name = "drifting"

        def compute(self, functional, xi, delta):
            direction = super().compute(functional, xi, delta)
            direction.step[0, 0] += 1e-3
            return direction

    result = qdframe.solve("paper-7.1", nodes=21, direction=Drifting())
    assert result.status == "failed" and "moved the given x(t_0) by 1.00e-03" in result.message
    assert result.x[0, 0] == 0.0


@pytest.mark.parametrize("nodes", [9, 11, 13, 17, 19])
def test_gauss_newton_solves_paper_71_whatever_the_rounding_of_its_last_qp(nodes):
    """Near the solution (objective ~1e-15) the step QP at Clarabel's 1e-12 could end
    InsufficientProgress, and the solve `stationary` at I ~ 4e-16, on 4 of these grids
    (which ones depended on x(t_0)'s 1e-15 drift): the QP is retried at 1e-10."""
    result = qdframe.solve("paper-7.1", nodes=nodes, direction="gauss-newton", tol=1e-10, max_iter=10)
    assert result.solved and result.iterations <= 4


def test_the_optimal_control_hooks_are_honoured():
    """Issue 53: a terminal cost and a control bound written on a model were silently dropped (the
    terminal cost ignored gave `solved` with J = 0); now they are solved: J* = 850/23 = 36.96 for
    ∫u² + 50·((p(1) − 2)² + v(1)²) from rest, and |u| ≤ 8 binds at both ends (unbounded,
    u* = 18.48·(1 − t) − 9.06)."""
    from qdframe.sets import SetModel

    class Effort(SetModel):
        state_names = "p v"
        control_names = "u"
        default_x0 = (0.0, 0.0)

        def sets(self, p, v, u):
            return {p: v, v: u}

        def running_cost(self, p, v, u):
            return u**2

        def terminal_cost(self, p, v):
            return 50 * ((p - 2) ** 2 + v**2)

    free = qdframe.solve(Effort())
    assert free.solved and free.cost == pytest.approx(850 / 23, rel=1e-6)
    Effort.control_bounds = {"u": (-8.0, 8.0)}
    bounded = qdframe.solve(Effort())
    u = np.asarray(bounded.u)[1:, 0]
    assert bounded.solved and float(np.max(np.abs(u))) - 8.0 <= bounded.checks["bounds"]["tol"]
    assert u[0] == pytest.approx(8.0)
    assert bounded.cost > free.cost + 0.05
