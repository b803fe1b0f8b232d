"""Sign terms, controls, the Filippov simulator and Example 7.3."""

import numpy as np
import pytest

import qdframe
from qdframe import simulate as simulate_module
from qdframe.cli import main
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.ready_pieces import abs_sum
from qdframe.model import InclusionModel, SetBlock, SignTerm, Surface
from qdframe.simulate import simulate


def _linear(coefficients, width):
    gradient = np.zeros(width)
    for index, value in coefficients.items():
        gradient[index] = value
    return lambda y: (y @ gradient, np.broadcast_to(gradient, y.shape).copy())


def _switch(index, width, sign=-1.0):
    gradient = np.zeros(width)
    gradient[index] = sign
    return lambda y: (sign * y[:, index], np.broadcast_to(gradient, y.shape).copy())


class DryFriction(InclusionModel):
    """x' ∈ v·… : x1' = x2, x2' ∈ g − μ·Sgn(x2) (a block pushed by g against friction μ)."""

    name = "test-dry-friction"
    state_names = ("position", "velocity")
    default_x0 = (0.0, 1.0)
    mu, g = 1.0, 0.5

    def blocks(self):
        return (
            SetBlock.equation(0, _linear({1: 1.0}, 2)),
            SetBlock.equation(1, lambda y: (np.full(y.shape[0], self.g), np.zeros_like(y)),
                              signs=(SignTerm(self.mu, _switch(1, 2), 1e-3),)),
        )


def test_simulator_follows_filippov_sticking():
    """v' = g − μ·sign(v) with v(0) = 1: v = 1 − (μ − g)t until t = 2, then v ≡ 0 (stuck, |g| < μ)."""
    run = simulate(DryFriction(), 0.0, 3.0, (0.0, 1.0), dt=1e-3)
    t, v = run.t, run.x[:, 1]
    moving = t <= 1.9
    assert np.allclose(v[moving], 1.0 - 0.5 * t[moving], atol=2e-3)
    assert np.max(np.abs(v[t >= 2.1])) <= 1e-9
    assert run.x[-1, 0] == pytest.approx(1.0, abs=2e-3)  # ∫ v = 1·2 − 0.25·4 = 1


class Sliding(InclusionModel):
    """x' ∈ −Sgn(x) + u with a control: sliding on x = 0 after t = x(0)."""

    name = "test-sliding"
    state_names = ("x",)
    control_names = ("u",)
    default_x0 = (0.7,)

    def blocks(self):
        return (SetBlock.equation(0, _linear({1: 1.0}, 2), signs=(SignTerm(1.0, _switch(0, 2), 1e-3),)),)


def test_simulator_slides_on_the_discontinuity():
    run = simulate(Sliding(), 0.0, 1.5, (0.7,), dt=1e-3)
    assert np.allclose(run.x[run.t <= 0.69, 0], 0.7 - run.t[run.t <= 0.69], atol=2e-3)
    assert np.max(np.abs(run.x[run.t >= 0.71, 0])) <= 1e-9


@pytest.mark.parametrize("name, t_end", [("two-surface-sliding", 2.2), ("stick-slip-oscillator", 7.0)])
def test_simulator_windows_give_the_step_by_step_trajectory(monkeypatch, name, t_end):
    """Newton on a window of steps keeps only steps solved to the step's tolerance: the
    same trajectory as one step at a time, across sliding, sticking and reversals."""
    model = qdframe.load_model(name)
    windowed = simulate(model, 0.0, t_end, model.x0, dt=1e-3)
    monkeypatch.setattr(simulate_module, "WINDOW_MIN", 1)
    monkeypatch.setattr(simulate_module, "WINDOW_MAX", 1)
    stepwise = simulate(model, 0.0, t_end, model.x0, dt=1e-3)
    assert np.max(np.abs(windowed.x - stepwise.x)) <= 1e-9


class ScaledLine(InclusionModel):
    """x1' = x2, x2' ∈ −2·Sgn(k·(x1 + x2)): slide-after-reaching with its switch scaled by k."""

    name = "test-scaled-line"
    state_names = ("x1", "x2")
    default_x0 = (1.0, 0.0)
    k = 1.0

    def blocks(self):
        return (SetBlock.equation(0, _linear({1: 1.0}, 2)),
                SetBlock.equation(1, _linear({}, 2), signs=(SignTerm(2.0, _linear({0: -self.k, 1: -self.k}, 2)),)))


@pytest.mark.parametrize("k", [1e-3, 1e6])
def test_simulator_does_not_depend_on_the_switch_scale(k):
    """The natural map's c is 1/|∂s/∂λ| through the step: the same motion for s and k·s."""
    scaled = ScaledLine()
    scaled.k = k
    reference = simulate(ScaledLine(), 0.0, 2.0, (1.0, 0.0), dt=1e-3)
    run = simulate(scaled, 0.0, 2.0, (1.0, 0.0), dt=1e-3)
    assert np.max(np.abs(run.x - reference.x)) <= 1e-9
    assert np.max(np.abs(run.x[run.t >= 0.42].sum(axis=1))) <= 1e-12  # sliding on x1 + x2 = 0


def test_simulator_follows_resolved_states():
    """paper-7.3-reduced has no block for x1..x3 (z_i ≡ x_{i+3}): the same motion as paper-7.3."""
    start = (-1.0, 1.0, -1.0, -1.0, 1.0, 1.0)
    full = simulate(qdframe.load_model("paper-7.3", x0=start), -0.2, 0.0, start, dt=1e-3)
    reduced = simulate(qdframe.load_model("paper-7.3-reduced", x0=start), -0.2, 0.0, start, dt=1e-3)
    assert np.max(np.abs(full.x - reduced.x)) <= 1e-12


class Mixed(InclusionModel):
    """A model with controls, an l1-amplitude sign term, a constant sign term, and a surface."""

    name = "test-mixed"
    state_names = ("a", "b", "c")
    control_names = ("u",)
    default_x0 = (0.3, -0.2, 0.5)
    end_indices = (0,)
    default_end_values = (0.1,)

    def blocks(self):
        return (
            SetBlock.equation(0, _linear({1: 1.0, 3: 0.5}, 4),
                              signs=(SignTerm(abs_sum(range(3), 0.7, 4), _switch(2, 4), 0.05),)),
            SetBlock.equation(1, _linear({0: -1.0, 2: 0.3}, 4), signs=(SignTerm(0.4, _switch(1, 4), 0.05),)),
            SetBlock.equation(2, _linear({0: 0.2, 3: -1.0}, 4)),
        )

    def surface(self):
        def e(x):
            jac = np.zeros((x.shape[0], 1, 3))
            jac[:, 0, 0], jac[:, 0, 2] = 1.0, 2.0
            return (x[:, 0] + 2 * x[:, 2])[:, None] - 1.3, jac

        return Surface(e)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_directional_derivative_with_controls_signs_and_surface(seed):
    """(11.10) built from (A_k, B_k) against one-sided finite differences along random directions."""
    model = Mixed()
    functional = Functional(model, Grid(1.0, 9))
    rng = np.random.default_rng(seed)
    xi = functional.pack(rng.normal(size=(9, 3)) * 0.1, rng.normal(size=(9, 3)), rng.normal(size=(9, 1)))
    qd = functional.quasidifferential(xi, 1e-12)
    for _ in range(5):
        g = rng.normal(size=xi.shape) * functional.free
        alpha = 1e-7
        fd = (functional.objective(xi + alpha * g) - functional.objective(xi)) / alpha
        assert qd.directional_derivative(g, functional.weights) == pytest.approx(fd, rel=1e-4, abs=1e-6)


def test_set_bounds_of_a_sign_term_contain_filippovs_set():
    """With the band: far from s = 0 the set is a·sign(s) exactly; at s = 0 the whole a·[−1, 1].
    With selections the set is the point a·λ, and the default λ is the band's."""
    model = Sliding()
    band = Functional(model, Grid(1.0, 3), signs="band")
    xi = band.pack(np.array([[0.7], [0.0], [-0.5]]), np.zeros((3, 1)), np.zeros((3, 1)))
    lower, upper = band.set_bounds(xi)[0]
    assert np.allclose(lower, [-1.0, -1.0, 1.0]) and np.allclose(upper, [-1.0, 1.0, 1.0])
    exact = Functional(model, Grid(1.0, 3))
    xi = exact.pack(np.array([[0.7], [0.0], [-0.5]]), np.zeros((3, 1)), np.zeros((3, 1)), np.array([[-1.0], [0.25], [1.0]]))
    lower, upper = exact.set_bounds(xi)[0]
    assert np.allclose(lower, [-1.0, 0.25, 1.0]) and np.allclose(upper, lower)
    assert np.allclose(exact.pack(xi[:, :1], xi[:, 1:2], xi[:, 2:3])[:, 3], [-1.0, 0.0, 1.0])


def test_paper_73_starts_where_the_reaching_phase_ends():
    """x(0) is the model's data REACHING_END: the reaching phase simulated again ends there."""
    from qdframe.models import paper_73 as masses
    from qdframe.simulate import simulate

    model = qdframe.load_model("paper-7.3", x0=masses.REACHING_START)
    run = simulate(model, -masses.REACHING_TIME, 0.0, masses.REACHING_START, dt=2e-4)
    assert np.allclose(run.x[-1], masses.REACHING_END, rtol=0.0, atol=1e-12)
    x0 = qdframe.load_model("paper-7.3").x0
    assert np.array_equal(x0, masses.REACHING_END) and np.array_equal(qdframe.load_model("paper-7.3-reduced").x0, x0)
    # the paper's own rounded values (Section 7.3: x1 ≈ −1.053, x2 ≈ 1.099, x3 ≈ −0.787, x4 = 0,
    # x5 ≈ 0.026, x6 ≈ 1.119), to one unit of their last digit: x1 and x6 differ by 5.8e-4 and
    # 5.5e-4, more than the paper's rounding (5e-4) — its reaching phase was integrated otherwise
    assert np.allclose(x0, [-1.053, 1.099, -0.787, 0.0, 0.026, 1.119], rtol=0.0, atol=1e-3)


@pytest.mark.parametrize("nodes, scheme, signs", [(101, None, "exact"), (11, "trapezoid", "band"), (101, "trapezoid", "band")])
def test_paper_73_with_gauss_newton(nodes, scheme, signs, certified):
    """Exact selections on implicit Euler (the default), and the paper's trapezoid rule with the band."""
    result = qdframe.solve("paper-7.3", nodes=nodes, direction="gauss-newton", tol=1e-10, scheme=scheme, signs=signs)
    certified(result)  # boundary, surface, consistency, inclusion (and selections) within 1e-8 of the scale
    assert result.I <= 1e-10
    assert (result.selections is not None) == (signs == "exact")
    if signs == "exact":
        assert result.selections.shape == (nodes, 3)
    assert result.u is not None and result.u.shape == (nodes, 1)
    assert np.allclose(result.x[:, 0], result.x[0, 0], atol=5e-3)  # x1 flat near −1.0525 on the surface


def test_simulate_command(tmp_path, capsys):
    out = tmp_path / "sim.json"
    assert main(["simulate", "test-sliding-unregistered", "--from", "0", "--to", "1", "--x0", "1"]) == 2
    assert main(["simulate", "paper-7.1", "--from", "0", "--to", "0.1", "--x0", "0,0", "--dt", "0.01",
                 "--json", str(out)]) == 0
    assert '"x_end"' in out.read_text()
    assert main(["simulate", "paper-7.1", "--from", "1", "--to", "0", "--x0", "0,0"]) == 2
    assert main(["simulate", "paper-7.2", "--from", "0", "--to", "1", "--x0", "0,0"]) == 2
    err = capsys.readouterr().err
    assert "--to" in err and "S_k" in err


@pytest.mark.parametrize("seed", [0, 1])
def test_resolved_states_tie_z_to_x(seed):
    """paper-7.3-reduced: z_i ≡ x_j, and (11.10) still matches finite differences."""
    model = qdframe.load_model("paper-7.3-reduced", x0=[-1.05, 1.1, -0.79, 0.0, 0.03, 1.12])
    functional = Functional(model, Grid(1.0, 7))
    rng = np.random.default_rng(seed)
    xi = functional.pack(rng.normal(size=(7, 6)), rng.normal(size=(7, 6)), rng.normal(size=(7, 1)))
    x, z = functional.split(xi)
    assert np.array_equal(z[:, :3], x[:, 3:])
    qd = functional.quasidifferential(xi, 1e-12)
    for _ in range(4):
        g = rng.normal(size=xi.shape) * functional.free
        assert np.all(g[:, 6:9] == 0)  # z1..z3 are not unknowns
        alpha = 1e-7
        fd = (functional.objective(xi + alpha * g) - functional.objective(xi)) / alpha
        assert qd.directional_derivative(g, functional.weights) == pytest.approx(fd, rel=1e-4, abs=1e-6)


def test_reduced_and_full_73_solve_to_the_same_accuracy(certified):
    full = qdframe.solve("paper-7.3", nodes=101)
    reduced = qdframe.solve("paper-7.3-reduced", nodes=101)
    for result in (full, reduced):
        certified(result)
    assert np.array_equal(reduced.z[:, :3], reduced.x[:, 3:])
