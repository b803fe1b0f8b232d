"""Held inputs (qdframe.functional.held): a fixed set's choice and the controls are one per
mesh interval of a multi-stage collocation scheme. η's value, gradient and gauss-newton
rows against finite differences; which blocks are held; a held solve's choices; and the
default call on a bounded-input problem judged by an independent replay."""

from __future__ import annotations

import numpy as np
import pytest
import sympy

import qdframe
from qdframe.bench.references import SchemeRule, judge
from qdframe.directions.linearized_system import LinearizedSystem, _held_rows
from qdframe.directions.sparse_rows import RowBlocks
from qdframe.errors import InputError
from qdframe.functional import Functional
from qdframe.functional.held import held_pairs
from qdframe.schemes.grid import Grid, make_scheme
from qdframe.sets import Interval, SetModel, Sgn


class SpringPush(SetModel):
    """p' = v, v' ∈ −p + [−2, 2] − 0.5·Sgn(v): an interval moved by a spring, with friction."""

    name = "spring-push"
    state_names = "p v"
    default_T = 3.0
    default_x0 = (0.0, 0.0)
    default_xT = {"p": 1.0, "v": 0.0}

    def sets(self, p, v):
        return {p: v, v: -p + Interval(-2, 2) - 0.5 * Sgn(v)}


class GrowingFriction(SetModel):
    """p' = v, v' ∈ [−2, 2] − (1 + p²/2)·Sgn(v): a fixed interval, friction growing with p."""

    name = "growing-friction"
    state_names = "p v"
    default_T = 2.0
    default_x0 = (0.0, 0.0)
    default_xT = {"p": 0.5, "v": 0.0}

    def sets(self, p, v):
        return {p: v, v: Interval(-2, 2) - (1 + p**2 / 2) * Sgn(v)}


def _held(name, nodes: int = 9, seed: int = 0) -> tuple[Functional, np.ndarray]:
    """A held functional on radau-iia and a random iterate (selections inside [−1, 1])."""
    model = GrowingFriction() if name == "growing-friction" else qdframe.load_model(name)
    functional = Functional(model, Grid(model.T, nodes, "radau-iia"), inputs="held")
    rng = np.random.default_rng(seed)
    xi = functional.initial_point() + 0.3 * rng.standard_normal((nodes, functional.dim)) * functional.free
    if functional.p:
        xi[:, -functional.p:] = np.clip(xi[:, -functional.p:], -0.9, 0.9)
    return functional, xi


@pytest.mark.parametrize("scheme, nodes, pairs", [
    ("radau-iia", 7, [(1, 2), (3, 4), (5, 6)]),
    ("radau-iia5", 7, [(1, 3), (2, 3), (4, 6), (5, 6)]),
    ("implicit-euler", 5, []),
    ("trapezoid", 5, []),
])
def test_pairs_are_each_intervals_stages_against_its_last(scheme, nodes, pairs):
    """Radau IIA's stages inside each interval are tied to its last; a one-stage rule has
    nothing to hold, and the trapezoid rule's velocity reads the interval's first point."""
    assert [tuple(p) for p in held_pairs(Grid(1.0, nodes, scheme))] == pairs


def test_held_blocks_are_the_fixed_sets():
    """coulomb-rest-to-rest: v' ∈ [−U, U] − F·Sgn(v) is held, p' = v is not; the double
    pendulum's sets [0.5·x, 1.5·x] and the spring's −p + [−2, 2] move with the state, and
    paper-7.3's control u is the user's: nothing of theirs is held."""
    functional, xi = _held("coulomb-rest-to-rest")
    assert functional.held.coords(functional.arguments(xi)) == [1]
    for model in (qdframe.load_model("double-pendulum"), SpringPush(), qdframe.load_model("paper-7.3")):
        assert Functional(model, Grid(model.T, 9, "radau-iia"), inputs="held").held is None
    model = qdframe.load_model("coulomb-rest-to-rest")
    assert Functional(model, Grid(model.T, 9, "radau-iia")).held is None  # inputs free: the default of Functional


@pytest.mark.parametrize("name", ["coulomb-rest-to-rest", "sliding-mode-terminal", "growing-friction"])
def test_eta_gradient_and_rows_match_finite_differences(name):
    """∂η/∂ξ (the paper's direction) and the gauss-newton rows' J·d against central
    differences, and η = ½‖rows‖² (the rows are √w-weighted); growing-friction's amplitude
    a(p) = 1 + p²/2 puts λ·∇a in the choice's gradient."""
    functional, xi = _held(name)
    held, step = functional.held, 1e-6
    fd = np.zeros_like(xi)
    for i, j in np.argwhere(functional.free):
        up, down = xi.copy(), xi.copy()
        up[i, j] += step
        down[i, j] -= step
        fd[i, j] = (held.eta(up) - held.eta(down)) / (2 * step)
    gradient = held.gradient(xi) * functional.free
    assert np.max(np.abs(gradient - fd)) <= 1e-7 * max(1.0, np.max(np.abs(fd)))
    system = LinearizedSystem(functional, xi, 1e-3)
    root_w = np.sqrt(functional.weights)
    residual, cols, vals = _held_rows(functional, xi, system.y_cols(), system.z_cols(), root_w)
    assert 0.5 * np.sum(residual**2) == pytest.approx(held.eta(xi), rel=1e-12)
    rows = RowBlocks(system.size)
    rows.add(cols, vals)
    d = np.random.default_rng(1).standard_normal(xi.shape) * functional.free
    extended = np.zeros((xi.shape[0], system.width))
    extended[:, : functional.dim] = d
    moved = _held_rows(functional, xi + step * d, system.y_cols(), system.z_cols(), root_w)[0]
    assert np.max(np.abs((moved - residual) / step - rows.matrix() @ extended.ravel())) <= 1e-6


def _choices(result, inputs: str) -> np.ndarray:
    model = qdframe.load_model("coulomb-rest-to-rest")
    functional = Functional(model, Grid(model.T, result.nodes, "radau-iia"), inputs="held")
    return functional.held.residual(functional.pack(result.x, result.z, result.u, result.selections))


def test_a_held_solve_chooses_once_per_interval():
    """On a fixed grid, the held solve's force is the same at both stages of every interval;
    the free solve's is not."""
    held = qdframe.solve("coulomb-rest-to-rest", nodes=21, scheme="radau-iia", estimate=False)
    free = qdframe.solve("coulomb-rest-to-rest", nodes=21, scheme="radau-iia", estimate=False, inputs="free")
    assert held.status == free.status == "uncertified"  # the discrete problem solved, no estimate asked for
    assert held.options["inputs"] == "held" and free.options["inputs"] == "free"
    assert np.max(np.abs(_choices(held, "held"))) <= 1e-6
    assert np.max(np.abs(_choices(free, "free"))) >= 1e-3


def test_default_call_on_a_bounded_input_meets_its_target_on_few_points():
    """The default call certifies coulomb-rest-to-rest on few points; the true motion its input
    drives (the benchmark's events replay, DOP853 at 1e-12 with event location, the
    scheme's own continuation) is within 1e-6 of x and meets the end conditions."""
    result = qdframe.solve("coulomb-rest-to-rest")
    assert result.status == "solved" and result.nodes <= 101
    model = qdframe.load_model("coulomb-rest-to-rest")
    t = np.asarray(result.t)
    rule = SchemeRule(make_scheme("radau-iia"), t, np.arange(0, t.size, 2))
    verdict = judge(model, t, np.asarray(result.x), np.asarray(result.z), None, result.switch_times,
                    velocity=rule, selections=np.asarray(result.selections))
    assert verdict.error <= result.error_estimate <= 1e-6  # the estimate bounds the error: no factor on it


def test_inputs_must_be_held_or_free():
    with pytest.raises(InputError, match="inputs"):
        qdframe.solve("coulomb-rest-to-rest", nodes=21, inputs="constant")


class Track(SetModel):
    """A clock c' = 1 and x' ∈ [−2, 2] kept on the surface x = sin(c): the choice must follow cos."""

    name = "track"
    state_names = "c x"
    default_T = 3.0
    default_x0 = (0.0, 0.0)

    def sets(self, c, x):
        return {c: 1, x: Interval(-2, 2)}

    def surface_equations(self, c, x):
        return [x - sympy.sin(c)]


def test_where_a_held_choice_cannot_meet_the_problem_the_solve_chooses_freely():
    """The surface moves x within every interval: no held choice keeps it there, the held solve
    ends stationary, and the default call solves with each point's own choice, saying so."""
    result = qdframe.solve(Track())
    assert result.status == "solved"
    assert result.options["inputs"] == "free"
    assert "with the inputs held the solve ended stationary" in result.message
    t = np.asarray(result.t)
    assert np.max(np.abs(np.asarray(result.x)[:, 1] - np.sin(t))) <= 1e-6
