"""A mesh point on a switch takes its interval's selection (the left limit), and the descent
leaves a kink by a watchdog of full Newton steps (issues 30, 31).

At a mesh point pinned on a switch, s = 0 and Sgn(0) leaves the selection free; Radau IIA
and implicit Euler integrate that point's z over the interval before it only, so a
selection from the other side (or between) spoils that interval. The natural map there is
replaced by λ_k = λ_{k−1} for every column that ends the interval off its surface."""

from __future__ import annotations

import numpy as np
import pytest

import qdframe
from qdframe.descent.loop import DescentOptions
from qdframe.descent.steps import watchdog
from qdframe.registry import make_direction
from qdframe.directions.base import Direction, DirectionSolver
from qdframe.directions.linearized_system import LinearizedSystem
from qdframe.functional import Functional
from qdframe.errors import InputError
from qdframe.schemes.grid import Grid
from qdframe.models.exact_friction import stick_slip_oscillator_motion


@pytest.mark.parametrize("scheme, left", [("radau-iia", [4]), ("implicit-euler", [2]), ("trapezoid", [])])
def test_the_mesh_points_on_a_switch_are_left_limits_where_the_rule_ends_an_interval_there(scheme, left):
    tau = np.array([0.0, 0.2, 0.35, 0.7, 1.0])
    grid = Grid.from_mesh(tau, scheme, switches=(0.35, 0.5))  # 0.5 is not a mesh point: no left limit
    assert grid.left_limits.tolist() == left
    assert grid.bisected().t[grid.bisected().left_limits].tolist() == ([0.35] if left else [])
    assert Grid.from_mesh(tau, scheme).left_limits.size == 0


def _two_surfaces_at_a_pinned_point():
    """two-surface-sliding (two sign columns) on a Radau IIA mesh with a point pinned at 0.5."""
    model = qdframe.load_model("two-surface-sliding")
    grid = Grid.from_mesh(np.linspace(0.0, 1.0, 5), "radau-iia", switches=(0.5,))
    functional = Functional(model, grid)
    rng = np.random.default_rng(3)
    x, z = rng.normal(size=(grid.nodes, 2)), rng.normal(size=(grid.nodes, 2))
    lam = rng.uniform(-0.5, 0.5, size=(grid.nodes, 2))
    k = int(grid.left_limits[0])
    lam[k - 1] = [1.0, 0.3]  # the first column ends the interval off its surface, the second on it
    lam[k] = [-0.4, 0.2]
    return functional, functional.pack(x, z, None, lam), k


def test_a_left_limit_selection_is_the_point_befores_where_the_interval_ends_off_the_surface():
    functional, xi, k = _two_surfaces_at_a_pinned_point()
    residual, jacobian = functional.selection_residual(xi)
    y, lam = functional.arguments(xi), functional.selections(xi)
    s = functional.switch_values(y, gradients=False)[0]
    natural = lam - np.clip(lam + s, -1.0, 1.0)
    assert residual[k, 0] == pytest.approx(-0.4 - 1.0)  # λ_k − λ_{k−1}
    assert residual[k, 1] == natural[k, 1]  # on the surface before: the natural map
    others = np.arange(functional.grid.nodes) != k
    assert np.array_equal(residual[others], natural[others])
    assert np.array_equal(jacobian[k, 0, : functional.args], np.zeros(functional.args))
    assert jacobian[k, 0, functional.args] == 1.0
    assert functional.terms(xi).sigma == pytest.approx(0.5 * functional.values.integral(np.sum(residual**2, axis=1)))


def test_gauss_newtons_rows_of_a_left_limit_are_its_linearization():
    """A change of λ_{k−1} alone (off the clip's kinks) moves r_k = λ_k − λ_{k−1} by −dλ: the
    Jacobian's extra column predicts it exactly."""
    functional, xi, k = _two_surfaces_at_a_pinned_point()
    system = LinearizedSystem(functional, xi, 1e-3)
    d = np.zeros((functional.grid.nodes, system.width))
    lam_col = 2 * functional.n + functional.m  # the first selection's column in the extended unknowns
    d[k - 1, lam_col] = 1e-3  # λ_{k−1} = 1 → 1.001: still off the surface, its own row λ − 1, row k linear
    moved = xi.copy()
    moved[k - 1, lam_col] += 1e-3
    after = LinearizedSystem(functional, moved, 1e-3).residual
    assert np.allclose(system.residual + system.jacobian @ d.ravel(), after, atol=1e-12, rtol=0)


class _Fixed(DirectionSolver):
    """A Newton-type solver that proposes `step` everywhere except x(t_0)."""

    name = "fixed"
    full_steps = True

    def __init__(self, step: float) -> None:
        self.step = step

    def compute(self, functional, xi, delta):
        step = np.full_like(xi, self.step)
        step[0, : functional.n] = 0.0
        return Direction(step=step, deviation=np.abs(step).max(axis=1), slope=-1.0, stationary=False)


def test_the_watchdog_keeps_full_steps_only_for_a_real_gain():
    """From a point one Newton step solves, the watchdog returns that step; steps that only
    raise the objective are not kept (the descent then stops where it stalled)."""
    model = qdframe.load_model("block-stop-stick")
    reference = qdframe.solve(model, nodes=41, scheme="radau-iia", estimate=False)
    functional = Functional(model, Grid(model.T, 41, "radau-iia"))
    solved = functional.pack(reference.x, reference.z, None, reference.selections)
    options = DescentOptions()
    off = solved.copy()
    off[1:, 1] += 1e-3  # every velocity moved: its consistency defect is linear, one Newton step
    value = functional.objective(off)
    path = watchdog(functional, make_direction("gauss-newton"), off, value, options, 4)
    assert len(path) == 1 and functional.objective(path[-1][0]) <= options.tol
    assert watchdog(functional, _Fixed(1e-2), off, value, options, 4) == []


@pytest.mark.parametrize("T, points", [(10.0, 3000), (14.0, 4000)])
def test_a_stick_slip_oscillator_over_a_few_reversals_is_certified_by_default(T, points):
    """The spring–friction oscillator over T = 10 (3 reversals at kπ) and 14 (4): every
    reversal is a crossing pinned on a mesh point. The default call is solved, its estimate
    at or above the true error and within 1e-6·max(1, |x|), the reversals located to 1e-8,
    on a mesh where Radau IIA keeps its order 3 at the crossings: measured 1141 and 1769
    points; with the natural map at the pinned points (a selection free in Sgn(0) there)
    19845 and 40173."""
    model = qdframe.load_model("stick-slip-oscillator", T=T)
    result = qdframe.solve(model)
    assert result.solved, result.message
    scale = max(1.0, float(np.max(np.abs(result.x))))
    error = float(np.max(np.abs(result.x - stick_slip_oscillator_motion(result.t))))  # the default motion, cut at T
    assert error <= result.error_estimate <= 1e-6 * scale
    reversals = np.pi * np.arange(1, int(T / np.pi) + 1)
    assert result.switch_times == pytest.approx(reversals, abs=1e-8)
    assert result.nodes <= points


def test_switch_times_that_are_not_finite_numbers_are_refused():
    with pytest.raises(InputError, match="switches: expected finite switch times"):
        Grid.from_mesh([0.0, 0.5, 1.0], "radau-iia", switches=(0.5, float("nan")))
    with pytest.raises(InputError, match="switches"):
        Grid.from_mesh([0.0, 0.5, 1.0], "radau-iia", switches=("half",))
