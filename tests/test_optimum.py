"""Time-optimal problems (issue 32, item 3): a cost whose minimum over the solutions is not 0,
solved by raising the penalty λ of ∫cost + λ·I (qdframe/solve/optimum.py). Held against the exact
bang-bang answer of block-time-optimal, T* = (4/3)·√1.5."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

import qdframe
from qdframe.descent import multipliers
from qdframe.solve import optimum
from qdframe.descent.loop import DescentOptions, descend
from qdframe.directions.base import Direction, DirectionSolver
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.model import Cost
from qdframe.models.paper import Paper71
from qdframe.registry import make_line_search
from qdframe.models.identification import BlockTimeOptimal
from qdframe.sets import Interval, SetModel, Sgn
from qdframe.status import Status


@pytest.fixture(scope="module")
def fastest():
    return qdframe.solve("block-time-optimal")


def test_the_default_call_finds_the_shortest_time_and_the_bang_bang_motion(fastest):
    assert fastest.status == Status.SOLVED
    assert abs(fastest.T - BlockTimeOptimal.exact_T) <= 1e-6
    assert fastest.solution_error <= 1e-6
    # the estimate bounds the true error (the penalty's part included) and meets the target
    assert fastest.solution_error <= fastest.error_estimate <= 1e-6 * max(1.0, float(np.max(np.abs(fastest.x))))


def test_the_cost_is_the_time_and_the_message_its_estimate(fastest):
    """Issue 55: the summary showed `cost 1.653` for T = 1.633 (Radau IIA's weight h/4 at t_0, a
    velocity's in F(x_0), counted in ∫1 dt) and two error estimates (the grid's in the message,
    the sum in the table). The cost is the scheme's quadrature, ∫1 dt = T; the message says the sum."""
    # ∫ T(s) ds over the nodes: their T agree to the consistency check (the bug read 1.653 for T = 1.633)
    assert fastest.cost == pytest.approx(fastest.T, abs=1e-9)
    assert f"error estimate {fastest.error_estimate:.1e}" in fastest.message


def test_the_cost_estimate_bounds_the_distance_to_the_least_time(fastest):
    """The cost's estimate (the bisected mesh, the gap 2λ·I and Σ|y|·tol) bounds |T − T*|."""
    assert abs(fastest.cost - BlockTimeOptimal.exact_T) <= fastest.cost_estimate <= 1e-6 * max(1.0, fastest.cost)


def test_the_gap_2_lambda_I_is_the_distance_to_the_least_time(fastest):
    """The first-order optimality gap T* − T_λ ≈ 2λ·I (optimum's docstring), against the exact T*."""
    gap = fastest.options["optimality_gap"]
    assert gap == pytest.approx(2 * fastest.options["penalty"] * fastest.I)
    assert BlockTimeOptimal.exact_T - fastest.T == pytest.approx(gap, rel=0.05)


def test_the_penalty_is_raised_from_the_models_own(fastest):
    rounds = fastest.options["penalty_rounds"]
    assert rounds[0][0] == 1.0 and len(rounds) >= 2
    assert all(later[0] >= 10 * earlier[0] for earlier, later in zip(rounds, rounds[1:]))
    assert sum(count for _, count in rounds) <= fastest.iterations  # then the meshes of the accuracy refinement


def test_a_cost_with_minimum_zero_takes_one_round():
    """paper-7.1 (∫|x1| dt, zero on its solution): the method of multipliers (qdframe.descent.
    multipliers) finds a solution without the cost, and its first round at λ = MULTIPLIER_START
    ends there, the cost at its least value 0, with no shift: one round."""
    result = qdframe.solve("paper-7.1", nodes=101)
    assert result.solved and result.cost <= 1e-12
    assert result.options["penalty_rounds"] == [(multipliers.MULTIPLIER_START, result.iterations)]
    assert result.options["penalty"] == multipliers.MULTIPLIER_START and result.options["optimality_gap"] <= 1e-12


def _result(status: Status, I: float, checks: dict | None = None, stationary: bool = False) -> SimpleNamespace:
    """A stand-in with what :func:`optimum.raise_by` reads of a round's result."""
    return SimpleNamespace(status=status, I=I, checks=checks or {}, descent=SimpleNamespace(stationary_point=stationary))


def test_raise_by_follows_the_first_order_rates():
    # solved with the gap 2λI = 2e-9 within 0.1 of the target 1e-6: the answer
    assert optimum.raise_by(_result(Status.SOLVED, 1e-18), 1e9, 1e-6, 1e-10) is None
    # the gap 2e-5 is 200× too large: λ raised by 10·200 (I and the checks are within tolerance)
    factor = optimum.raise_by(_result(Status.SOLVED, 1e-14), 1e9, 1e-6, 1e-10)
    assert factor == pytest.approx(2000.0)
    # a stationary point whose worst check is 3× its tolerance: at least MIN_RAISE
    checks = {"inclusion": {"value": 3e-8, "tol": 1e-8}}
    assert optimum.raise_by(_result(Status.STATIONARY, 1e-30, checks, True), 1.0, 1.0, 1e-10) == pytest.approx(30.0)
    # the descent's own stop (a fixed ε, the budget), not a stationary point: λ is not what limits it
    assert optimum.raise_by(_result(Status.STATIONARY, 1e-3, checks, False), 1.0, 1.0, 1e-10) is None
    assert optimum.raise_by(_result(Status.MAX_ITER, 1e-3, checks, True), 1.0, 1.0, 1e-10) is None
    # far from the solutions (I = 1): the largest raise
    assert optimum.raise_by(_result(Status.STATIONARY, 1.0, {}, True), 1.0, 1.0, 1e-10) == optimum.MAX_RAISE


class _PlusOne(Paper71):
    """paper-7.1 with its cost ∫(|x1| + 1) dt: the least cost over the solutions is T, not 0."""

    def cost(self) -> Cost:
        def one(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return np.ones((y.shape[0], 1)), np.zeros((y.shape[0], 1, y.shape[1]))

        return dataclasses.replace(super().cost(), max_groups=super().cost().max_groups + (one,))


class _Stall(DirectionSolver):
    """Proposes a step along which the objective rises, with a given slope (a line search then stalls)."""

    name = "stall"

    def __init__(self, slope: float) -> None:
        self.slope = slope

    def compute(self, functional, xi, delta):
        step = np.full_like(xi, 1e-3)
        step[0, : functional.n] = 0.0
        return Direction(step=step, deviation=np.abs(step).max(axis=1), slope=self.slope, stationary=False)


@pytest.mark.parametrize("relative_slope, status", [(-1e-13, Status.SOLVED), (-1e-6, Status.STATIONARY)])
def test_a_line_search_stall_is_a_stationary_point_only_where_the_slope_is_negligible(relative_slope, status):
    """A penalized round stops where its line search finds no decrease: at a stationary point of
    𝒥 + λ·I (so `solved` where I ≤ tol and the checks pass) where the step's slope is within
    descent.STALL_SLOPE of the objective (at λ ~ 1e9 the model's slope is λ-amplified rounding),
    else `stationary`, not an optimum."""
    model = _PlusOne()
    solved = qdframe.solve(model, nodes=101, estimate=False)
    functional = Functional(model, Grid(model.T, 101, model.default_scheme))
    start = functional.pack(solved.x, solved.z, None, solved.selections)
    objective = functional.objective(start)
    assert objective > DescentOptions().tol  # the cost ≈ T keeps it above tol
    result = descend(functional, _Stall(relative_slope * objective), make_line_search("armijo"), DescentOptions(),
                     start=start)
    assert result.status == status
    assert result.options["stationary_point"] == (status == Status.SOLVED)


def test_a_fresh_round_starts_from_the_straight_line_between_the_given_ends():
    """A round that does not continue the last one's path starts from the straight line (x(0)
    held, p drawn to p(T)): from the model's start at rest the second round of this block
    stopped on a stuck phase (`stationary`, T = 5.06 against T* = 3.65). The block of
    block-time-optimal moved to p = 5 instead of 1 (full force until 0.75·T*, then full force
    back: T* = √7.5·(1 + 1/3) = √(40/3))."""
    model = BlockTimeOptimal(end_values=(5.0, 0.0))
    t = np.linspace(0.0, 2.0, 5)
    x, z = optimum.penalized(model, 1e7, None).initial_guess(t)
    assert np.allclose(x[:, 0], 2.5 * t) and np.allclose(z[:, 0], 2.5) and not x[:, 1].any()
    result = qdframe.solve(model)
    assert result.solved and abs(result.T - np.sqrt(40 / 3)) <= 1e-6


def test_a_raised_penalty_far_from_its_path_is_eased_first():
    """needs_easing: a penalty above the multipliers' cap whose start has λ·I above its cost (the
    refinement's move from implicit Euler onto radau-iia: λ·I = 7.6e8 at λ = 3.5e9) is first solved
    at EASE·λ; not at the model's own λ, nor at the multipliers' cap, nor from a start whose λ·I
    is below its cost. eased() sets EASE·λ inside its block and gives λ back."""
    from qdframe.unknowns import Unknowns

    def functional_at(weight: float) -> Functional:
        model = optimum.penalized(BlockTimeOptimal(end_values=(5.0, 0.0)), weight, None)
        return Functional(Unknowns(model), Grid(1.0, 41, "radau-iia"))

    functional = functional_at(3.5e9)
    far = functional.initial_point()  # the straight line: λ·I ≫ T
    assert 3.5e9 * functional.terms(far).I > 1e3
    assert optimum.needs_easing(functional, far)
    with optimum.eased(functional):
        assert functional.penalty == pytest.approx(optimum.EASE * 3.5e9)
    assert functional.penalty == 3.5e9
    assert not optimum.needs_easing(functional_at(1.0), far)  # the model's own λ: the cost may win there
    assert not optimum.needs_easing(functional_at(multipliers.PENALTY_CAP), far)
    with functional.without_cost():  # the same start made a solution of the constraints (λ·I ≈ 0)
        found = descend(functional, qdframe.registry.make_direction("gauss-newton"), make_line_search("armijo"),
                        DescentOptions(max_iter=300), None, far)
    near = multipliers.iterate(functional, found)
    assert found.status == Status.SOLVED and not optimum.needs_easing(functional, near)


def _fastest_move(distance: float, force: float) -> SetModel:
    """Issue 53's fastest rest-to-rest move: p' = v, v' ∈ [−U, U] − Sgn(v), from rest at 0 to
    rest at D, T free from the guess 4, cost ∫1."""

    class FastestMove(SetModel):
        name = "fastest-move"
        state_names = "p v"
        default_x0 = (0.0, 0.0)
        default_xT = {"p": distance, "v": 0.0}
        default_T = 4.0
        free_T = True

        def sets(self, p, v):
            return {p: v, v: Interval(-force, force) - Sgn(v)}

        def running_cost(self, p, v):
            return 1.0 + 0 * p

    return FastestMove()


def _shortest(distance: float, force: float) -> float:
    """T*: v' = U − 1 until t₁ = √(2D(U + 1)/((U − 1)·2U)), then −(U + 1) until v = 0."""
    up, down = force - 1.0, force + 1.0
    first = np.sqrt(2 * distance * down / (up * (up + down)))
    return first * (1.0 + up / down)


_STALLS = ("the penalty rounds end away from T* (λ up to 3.5e9, issue 53), on both CPUs measured (the 2-core "
           "AVX-512 machine, and the same with OPENBLAS_CORETYPE=Haswell and NumPy's AVX-512 off): ")


@pytest.mark.parametrize("distance, force", [
    (1.0, 2.0), (2.0, 2.0),
    # max_iter at T = 9.88 on the 2-core AVX-512 machine, solved with OpenBLAS's Haswell kernels and NumPy's
    # AVX-512 off (the penalty path of the first grid depends on rounding): not strict
    pytest.param(2.0, 1.5, marks=pytest.mark.xfail(strict=False, reason="the penalty path's end depends on rounding: "
                                                                         "max_iter at T = 9.88 here, solved on the "
                                                                         "Haswell kernels; T* = 3.0984")),
    pytest.param(5.0, 1.5, marks=pytest.mark.xfail(strict=True, reason=_STALLS + "stationary at T = 1.93; T* = 4.8990")),
    # solved on the 2-core AVX-512 machine since armijo stops where a decrease is below the objective's
    # rounding; stationary at T = 4.56 with OpenBLAS's Haswell kernels alone and at 1.83 with NumPy's
    # AVX-512 off alone: where the penalty path ends depends on rounding (issue 56), so not strict
    pytest.param(5.0, 2.0, marks=pytest.mark.xfail(strict=False, reason="the penalty path's end depends on rounding: "
                                                                        "solved here, stationary at T = 4.56 or 1.83 on "
                                                                        "other kernels; T* = 3.6515")),
])
def test_the_fastest_move_from_a_guess_of_4(distance, force):
    """The default call finds T* to the default target (README, "Known failures", for the three that do not)."""
    result = qdframe.solve(_fastest_move(distance, force))
    assert result.solved and abs(result.T - _shortest(distance, force)) <= 1e-6 * max(1.0, distance), (
        result.status, result.T)


def test_a_round_that_shrank_T_to_0_is_compared_without_a_warning():
    """The raised penalty's first round can end at T = 0 (the cost won); the penalty's error
    compares each round with the one before at t = s·T, which divided by that T = 0 (a
    RuntimeWarning from NumPy in the user's run): such a round is now infinitely far, quietly."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        result = qdframe.solve(_fastest_move(2.0, 3.0))
    assert result.solved and abs(result.T - _shortest(2.0, 3.0)) <= 2e-6
