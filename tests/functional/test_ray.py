"""Functional.ray: the objective along ξ + γG as the line searches evaluate it (χ + υ in
closed form, the set pieces per trial) against the direct objective(ξ + γG)."""

from __future__ import annotations

import numpy as np
import pytest

import qdframe
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.models.paper_sets import Paper71Sets, Paper72Sets, Paper73Sets
from qdframe.sets import Interval, SetModel, Sgn


class Relaxing(SetModel):
    """x' ∈ −x + [−1, 1], b' ∈ 1 − 3·Sgn(b), x(0) free and x(T) = x(0)."""

    state_names = "a b"
    default_T = 2.0
    default_x0 = (float("nan"), 0.5)
    periodic = (0,)

    def sets(self, a, b):
        return {a: -a + Interval(-1, 1), b: 1 - 3 * Sgn(b)}


MODELS = {
    "paper-7.1": lambda: qdframe.load_model("paper-7.1"),
    "paper-7.2": lambda: qdframe.load_model("paper-7.2"),
    "paper-7.3": lambda: qdframe.load_model("paper-7.3"),
    "paper-7.3-reduced": lambda: qdframe.load_model("paper-7.3-reduced"),
    "paper-7.1-sets": Paper71Sets,
    "paper-7.2-sets": Paper72Sets,
    "paper-7.3-sets": Paper73Sets,
    "relaxing-periodic": Relaxing,
}


def _ray_and_direct(functional: Functional, seed: int) -> tuple[np.ndarray, list[float], list[float]]:
    rng = np.random.default_rng(seed)
    xi = functional.initial_point() + 0.5 * rng.standard_normal(functional.free.shape) * functional.free
    step = rng.standard_normal(xi.shape) * functional.free
    gammas = np.concatenate([[0.0, 1e-9, 1e-4, 1.0], rng.uniform(0.0, 2.0, 6)])
    ray = functional.ray(xi, step)
    return gammas, [ray(g) for g in gammas], [functional.objective(xi + g * step) for g in gammas]


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("signs", ["exact", "band"])
def test_ray_is_the_objective_along_the_direction(name, signs):
    model = MODELS[name]()
    functional = Functional(model, Grid(model.T, 41, model.default_scheme), signs=signs)
    gammas, along, direct = _ray_and_direct(functional, seed=7)
    np.testing.assert_allclose(along, direct, rtol=1e-12, atol=0.0, err_msg=f"γ = {gammas}")


@pytest.mark.parametrize("scheme", ["trapezoid", "implicit-euler", "radau-iia"])
def test_ray_on_every_scheme(scheme):
    model = Relaxing()
    functional = Functional(model, Grid(model.T, 21, scheme))
    _, along, direct = _ray_and_direct(functional, seed=3)
    np.testing.assert_allclose(along, direct, rtol=1e-12, atol=0.0)


def test_ray_is_accurate_where_it_passes_through_a_solution():
    """ξ + γ0·G is paper-7.1's exact solution: the ray's value there is rounding-small
    (χ + υ in vertex form; a·γ² + b·γ + c leaves ~1e-16 of I(ξ) ~ 10 there, here
    −1.4e-17 at γ0 = 0.37 and 5.6e-16 at γ0 = 1.3)."""
    model = qdframe.load_model("paper-7.1")
    functional = Functional(model, Grid(model.T, 101, model.default_scheme))
    t = functional.grid.t
    solution = functional.pack(np.stack([0 * t, t], axis=1), np.stack([0 * t, 1 + 0 * t], axis=1))
    rng = np.random.default_rng(5)
    step = rng.standard_normal(solution.shape) * functional.free
    step[:, 0] = 0.0  # keep x1 = 0 exact, so the cost ∫|x1| is 0 there, not rounding
    for gamma in (0.37, 1.3):
        xi = solution - gamma * step
        ray = functional.ray(xi, step)
        assert ray(0.0) > 1.0
        assert ray(gamma) <= 1e-24 and functional.objective(xi + gamma * step) <= 1e-24


@pytest.mark.parametrize("name", ["paper-7.1", "paper-7.3", "paper-7.3-sets", "relaxing-periodic"])
@pytest.mark.parametrize("signs", ["exact", "band"])
def test_values_only_distances_equal_the_sides(name, signs):
    """φ's h of a one-coordinate block from values alone is :meth:`Pieces.state_1d`'s h, bit for bit."""
    model = MODELS[name]()
    functional = Functional(model, Grid(model.T, 41, model.default_scheme), signs=signs)
    rng = np.random.default_rng(11)
    xi = functional.initial_point() + 0.5 * rng.standard_normal(functional.free.shape) * functional.free
    y, z, lam = functional.arguments(xi), functional.split(xi)[1], functional.selections(xi)
    for b, block in enumerate(functional.blocks):
        selections = functional.block_selections(b, lam)
        side = functional.pieces.state_1d(block, y, z, selections)
        np.testing.assert_array_equal(functional.pieces.interval_distance(block, y, z, selections), side.h)
