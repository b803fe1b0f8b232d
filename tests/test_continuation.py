"""Honest continuation: every grid iterates within its share of the budget, the message
says how many iterations each grid took, and a coarse stage never replaces a better start."""

import numpy as np
import pytest

import qdframe
from qdframe import InclusionModel, SetBlock
from qdframe.solve.continuation import interpolate, iterate_view
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid


def steps_per_grid(result):
    """The accepted steps of the history on each grid of `options["grids"]`."""
    return [sum(1 for r in result.history if r.nodes == grid and r.step > 0) for grid in result.options["grids"]]


def test_a_tiny_budget_gives_every_grid_an_iteration():
    result = qdframe.solve("paper-7.1", nodes=1001, direction="native", max_iter=3)
    assert result.options["grids"] == [11, 101, 1001]
    assert result.options["iterations_per_grid"] == [1, 1, 1] == steps_per_grid(result)
    assert result.status == "max_iter" and result.nodes == 1001 and result.iterations == 3
    last = [r for r in result.history if r.nodes == 1001]
    assert [r.iteration for r in last] == [2, 3] and last[-1].step > 0  # its start, then a step there
    assert result.history[-1].objective == pytest.approx(result.objective)


def test_a_budget_smaller_than_the_grids_skips_the_coarsest():
    """One iteration is kept for each later grid: with 2 over three grids, 11 nodes get none
    (and leave no record), 101 and 1001 one each."""
    result = qdframe.solve("paper-7.1", nodes=1001, direction="native", max_iter=2)
    assert result.options["iterations_per_grid"] == [0, 1, 1] == steps_per_grid(result)
    assert {r.nodes for r in result.history} == {101, 1001}
    one = qdframe.solve("paper-7.1", nodes=1001, direction="native", max_iter=1)
    assert one.options["iterations_per_grid"] == [0, 0, 1] and {r.nodes for r in one.history} == {1001}


def test_a_coarse_grid_spends_at_most_its_share():
    """7.3 with the paper's method does not stop on 11 nodes (before, it spent the whole
    budget there): the coarse grid, band start included, takes at most max_iter // (2·2)
    and the requested grid the rest."""
    result = qdframe.solve("paper-7.3", nodes=101, direction="native", max_iter=30, simulate_start=False)
    coarse, fine = result.options["iterations_per_grid"]
    assert result.options["grids"] == [11, 101] and 1 <= coarse <= 30 // 4 and coarse + fine == 30
    assert [coarse, fine] == steps_per_grid(result)
    assert result.status == "max_iter" and result.nodes == 101


def test_the_message_lists_the_iterations_of_each_grid():
    spent = qdframe.solve("paper-7.1", nodes=101, direction="native", max_iter=10)
    assert spent.status == "max_iter" and spent.options["iterations_per_grid"] == [2, 8]  # 11 nodes: 10 // (2·2)
    assert spent.message.startswith("10 iterations spent: 11 nodes 2, 101 nodes 8; ")  # then the unmet conditions
    stopped = qdframe.solve("paper-7.1", nodes=1001, direction="native")
    counts = stopped.options["iterations_per_grid"]
    assert stopped.status == "stationary" and sum(counts) == stopped.iterations and counts[-1] >= 1
    assert stopped.message.endswith(f"; {stopped.iterations} iterations: 11 nodes {counts[0]}, "
                                    f"101 nodes {counts[1]}, 1001 nodes {counts[2]}")
    alone = qdframe.solve("paper-7.1", nodes=101, direction="native", continuation="none")
    assert alone.options["iterations_per_grid"] == [alone.iterations] and "nodes" not in alone.message


def _growth_pieces(y):
    return y[:, 0], np.ones_like(y)


class Growth(InclusionModel):
    """x' = x from x(0) = 1 to x(1) = e, started from the exact solution e^t."""

    name = "growth"
    state_names = ("x",)
    default_x0 = (1.0,)
    end_indices = (0,)
    default_end_values = (np.e,)
    default_scheme = "trapezoid"

    def blocks(self):
        return (SetBlock.equation(0, _growth_pieces),)

    def initial_guess(self, t):
        return np.exp(t)[:, None], np.exp(t)[:, None]


@pytest.mark.parametrize("direction", ["native", "gauss-newton"])
def test_a_coarse_result_worse_on_the_fine_grid_keeps_the_models_start(direction):
    """The 11-node iterate is a coarse discrete solution; interpolated to 101 nodes it is
    worse there than the model's start (e^t, accurate to the fine grid's error)."""
    model = Growth()
    # the model's own start alone (no simulated motion: it would start the fine grid better still)
    result = qdframe.solve(model, nodes=101, direction=direction, continuation=(11,), max_iter=50, eps=1e-7,
                           simulate_start=False)
    coarse_steps = result.options["iterations_per_grid"][0]
    assert coarse_steps >= 1  # the coarse grid did move
    coarse = qdframe.solve(model, nodes=11, direction=direction, continuation="none", max_iter=coarse_steps, eps=1e-6,
                           simulate_start=False)
    fine = Functional(model, Grid(model.T, 101, model.default_scheme))
    own = fine.objective(fine.initial_point())
    assert fine.objective(interpolate(fine, coarse)) > 100 * own
    start = next(r for r in result.history if r.nodes == 101)
    assert start.objective == own and result.objective <= own


def test_an_iterate_round_trips_through_interpolation_on_its_own_grid():
    """`iterate_view` reads a stage's start as `interpolate` reads a result (x, z, u, λ)."""
    functional = Functional(qdframe.load_model("paper-7.3"), Grid(1.0, 11, "implicit-euler"))
    xi = functional.initial_point() + 0.01 * np.random.default_rng(0).standard_normal(functional.initial_point().shape)
    xi[0, : functional.n] = functional.model.x0
    assert np.array_equal(interpolate(functional, iterate_view(functional, xi)), xi)


@pytest.mark.parametrize("nodes, grids", [(101, [101]), (1001, [101, 301, 1001])])
def test_gauss_newton_solves_paper_71_on_its_first_grid(nodes, grids, certified):
    """7.1's solution x1 = 0, x2 = t is linear: solved on 101 nodes, its interpolation solves
    every finer grid, which therefore takes no iteration (however many the first needed)."""
    result = qdframe.solve("paper-7.1", nodes=nodes)
    certified(result)
    assert result.solved and result.message.startswith("error estimate") and result.options["grids"] == grids
    first, *finer = result.options["iterations_per_grid"]
    assert first == result.iterations >= 1 and finer == [0] * (len(grids) - 1)


def test_a_finer_grid_from_a_solved_coarser_one_passes_its_kinks_with_full_steps():
    """paper-7.3 up the ladder 101, 301, 1001: on each finer grid the coarser solution's
    stick/slip boundaries are a few nodes off, and a line search lets semismooth Newton move
    them about one node per step. Where it cuts a step, a round of full steps moves them all
    at once (steps.EAGER_ROUNDS), where the line search alone moves them one node per step.
    (From the model's own start: the default, its motion under u ≡ 0, takes no ladder.)"""
    result = qdframe.solve("paper-7.3", nodes=1001, estimate=False, simulate_start=False)
    assert result.converged, result.message
    first, *finer = result.options["iterations_per_grid"]
    assert finer[-1] <= 8 and sum(finer) <= 12


def test_a_round_of_full_steps_not_kept_leaves_the_solver_as_it_was():
    """A watchdog round that finds no gain restores the solver's kept state (its damping, its
    KKT analysis), so that a descent that tried it goes on as if it had not."""
    from qdframe.descent.loop import DescentOptions
    from qdframe.registry import make_direction
    from qdframe.descent.steps import watchdog

    functional = Functional(qdframe.load_model("paper-7.3"), Grid(1.0, 11, "implicit-euler"))
    solver = make_direction("gauss-newton")
    solver.start(functional)
    xi = functional.initial_point()
    solver.compute(functional, xi, 1e-3)
    kept = solver.snapshot()
    assert watchdog(functional, solver, xi, 0.0, DescentOptions(), 2) == []  # nothing is below an objective of 0
    assert solver.snapshot().keys() == kept.keys() and all(solver.snapshot()[k] is v for k, v in kept.items())


def test_a_newton_descent_creeping_at_a_local_minimum_stops_stationary():
    """paper-7.3 on 1001 nodes from an 11- and a 31-node solution: Newton creeps at I ≈ 8e-8,
    the objective falling ~1e-9 of itself per step. It stops `stationary` after a window
    without a 4× fall (a watchdog round tried first) and the solve restarts from the straight
    line, which creeps too; without the window it spent all 500 iterations (`max_iter`)."""
    result = qdframe.solve("paper-7.3", nodes=1001, estimate=False, continuation=[11, 31], simulate_start=False)
    assert result.status in ("stationary", "uncertified"), result.message
    assert result.iterations < 300
    if result.status == "stationary":
        assert "fell by less than 4× in 40 iterations" in result.message
