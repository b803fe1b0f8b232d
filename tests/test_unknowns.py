"""Free end time and unknown parameters (qdframe.unknowns), against exact answers."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

import qdframe
from qdframe.errors import InputError
from qdframe.model import InclusionModel, SetBlock, SignTerm
from qdframe.models.identification import BlockFrictionCoefficient, BlockStoppingTime, RelayPeriod
from qdframe.sets import SetModel, Sgn
from qdframe.unknowns import Bound, Unknowns


@pytest.mark.parametrize("model", [BlockStoppingTime, RelayPeriod, BlockFrictionCoefficient])
def test_default_call_finds_T_and_parameters(model):
    """The default call: T and p within 1e-6 of the exact ones, x within 1e-6 of the closed
    form at the user's times, and the estimate not below the true error."""
    result = qdframe.solve(model())
    assert result.status == "solved", result.message
    if model.exact_T is not None:
        assert result.options["free_T"] and abs(result.T - model.exact_T) <= 1e-6
        assert result.t[-1] == pytest.approx(result.T, rel=1e-14)
    for name, value in model.exact_parameters.items():
        assert abs(result.parameters[name] - value) <= 1e-6
    error = np.max(np.abs(result.x - model().exact_solution(result.t)))
    assert error <= 1e-6 and error <= result.error_estimate
    assert result.solution_error == pytest.approx(error)
    assert result.x.shape[1] == 2 and result.state_names == tuple(model.state_names)


@pytest.mark.parametrize("scheme", ["implicit-euler", "trapezoid", "radau-iia"])
def test_every_scheme_on_a_fixed_grid_estimates_its_error(scheme):
    """On a fixed grid of every scheme the stopping time converges and the estimate, which
    covers T, is not below the error at the user's times (exact: p = 2t − t²)."""
    result = qdframe.solve(BlockStoppingTime(), nodes=61, scheme=scheme)
    assert result.status in ("solved", "uncertified"), result.message
    exact = BlockStoppingTime().motion(result.t)
    error = np.max(np.abs(result.x - exact))
    assert abs(result.T - 0.5) <= 0.02
    assert result.error_estimate is not None and error <= result.error_estimate
    assert np.allclose(np.gradient(result.x[:, 0], result.t), result.x[:, 1], atol=0.1)  # z and t in physical time


def test_accuracy_target_holds_at_the_users_times():
    result = qdframe.solve(RelayPeriod(T=4.5), accuracy=1e-8)
    assert result.status == "solved", result.message
    error = np.max(np.abs(result.x - RelayPeriod().motion(result.t)))
    assert error <= result.error_estimate <= 1e-8 * max(1.0, np.max(np.abs(result.x)))
    assert abs(result.T - 4 * np.sqrt(2)) <= 1e-8


def test_free_T_and_guesses_from_solve_and_from_the_model():
    """solve(free_T=True) on a fixed-T model; solve(parameters=…) and model(parameters=…)
    give guesses; free_T=False fixes a free T."""
    from qdframe.models.user_friction import RelayOscillator

    result = qdframe.solve(RelayOscillator(T=5.0, periodic=("x1", "x2")), free_T=True)
    assert result.solved and abs(result.T - 4 * np.sqrt(2)) <= 1e-6
    for found in (qdframe.solve(BlockFrictionCoefficient(), parameters={"mu": 3.0}),
                  qdframe.solve(BlockFrictionCoefficient(parameters={"mu": 0.5}))):
        assert found.solved and abs(found.parameters["mu"] - 2.0) <= 1e-6
        assert found.options["parameters_start"]["mu"] in (3.0, 0.5)
    fixed = qdframe.solve(BlockStoppingTime(T=0.5), free_T=False)
    assert fixed.T == 0.5 and not fixed.options.get("free_T")
    assert fixed.solved and abs(fixed.x[-1, 0] - 0.75) <= 1e-6


class HandWrittenCoefficient(InclusionModel):
    """p' = v, v' ∈ −μ·Sgn(v) written by hand: the pieces take y = (p, v, μ)."""

    name = "hand-written-coefficient"
    state_names = ("p", "v")
    parameter_names = ("mu",)
    default_parameters = (1.0,)
    parameter_bounds = {"mu": (0.5, 5.0)}  # both ends: μ = 0.5 + 4.5/(1 + e^−σ)
    default_x0 = (0.0, 2.0)
    end_indices = (0,)
    default_end_values = (1.0,)
    default_T = 1.5

    def blocks(self):
        def velocity(y):
            grad = np.zeros((y.shape[0], 3))
            grad[:, 1] = 1.0
            return y[:, 1], grad

        def amplitude(y):
            grad = np.zeros((y.shape[0], 1, 3))
            grad[:, 0, 2] = 1.0
            return y[:, 2:3], grad

        def switch(y):
            grad = np.zeros((y.shape[0], 3))
            grad[:, 1] = 1.0
            return y[:, 1], grad

        def none(y):
            return np.zeros(y.shape[0]), np.zeros((y.shape[0], 3))

        return (SetBlock.equation(0, velocity, "v"),
                SetBlock.equation(1, none, "0", signs=(SignTerm((amplitude,), switch, sense=-1.0, name="mu·Sgn(v)"),)))


def test_a_hand_written_model_with_a_bounded_parameter():
    result = qdframe.solve(HandWrittenCoefficient())
    assert result.solved, result.message
    assert abs(result.parameters["mu"] - 2.0) <= 1e-6
    assert np.max(np.abs(result.x - BlockFrictionCoefficient().motion(result.t))) <= 1e-6
    from qdframe.authoring import check_model

    assert check_model(HandWrittenCoefficient(), samples=8).ok


class ResolvedRelay(InclusionModel):
    """The relay with x1' = x2 resolved (no unknown z1): with T free it is X1' = T·X2."""

    name = "resolved-relay"
    state_names = ("x1", "x2")
    resolved = {0: 1}
    default_x0 = (1.0, 0.0)
    periodic = (0, 1)
    default_T = 5.0
    free_T = True

    def blocks(self):
        def none(y):
            return np.zeros(y.shape[0]), np.zeros((y.shape[0], 2))

        def switch(y):
            grad = np.zeros((y.shape[0], 2))
            grad[:, 0] = 1.0
            return y[:, 0], grad

        return (SetBlock.equation(1, none, "0", signs=(SignTerm(1.0, switch, sense=-1.0),)),)


def test_resolved_states_and_constant_amplitudes_scale_with_T():
    result = qdframe.solve(ResolvedRelay())
    assert result.solved, result.message
    assert abs(result.T - 4 * np.sqrt(2)) <= 1e-6
    assert np.max(np.abs(result.x - RelayPeriod().motion(result.t))) <= 1e-6


def test_the_restated_model_has_the_scaled_support():
    """c(T·F, ψ) = T·c(F, ψ): the wrapped pieces at σ_T = log T are T times the model's, with
    the chain rule through the parameter's bound."""
    model = Unknowns(BlockStoppingTime())
    assert model.state_names == ("p", "v", "T") and model.T == 1.0
    y = np.array([[0.1, 1.5, np.log(0.7)]])
    (group,) = model.blocks()[0].max_groups
    value, grad = group.pieces(y)
    assert value[0, 0, 0] == pytest.approx(0.7 * 1.5)
    assert grad[0, 0, 0] == pytest.approx([0.0, 0.7, 0.7 * 1.5])
    term = model.blocks()[1].signs[0]
    a, da = term.amplitude[0](y)
    assert a[0, 0] == pytest.approx(2 * 0.7) and da[0, 0, 2] == pytest.approx(2 * 0.7)
    wrapped = Unknowns(BlockFrictionCoefficient())
    assert wrapped.state_names == ("p", "v", "mu") and wrapped.T == 1.5


def test_bounds_map_the_real_line_onto_their_interval():
    sigma = np.linspace(-30, 30, 7)
    for lo, hi in ((-np.inf, np.inf), (0.0, np.inf), (-np.inf, 3.0), (0.5, 5.0)):
        bound = Bound(lo, hi)
        values = bound.value(sigma)
        assert np.all(values >= lo) and np.all(values <= hi) and np.all(np.diff(values) >= 0)
        for guess in (1.0, 2.0):
            assert bound.value(np.array(bound.inverse(guess))) == pytest.approx(guess)
        step = 1e-6
        numeric = (bound.value(np.array(0.3 + step)) - bound.value(np.array(0.3 - step))) / (2 * step)
        assert bound.slope(np.array(0.3)) == pytest.approx(numeric, rel=1e-6)


def test_results_carry_T_and_parameters():
    result = qdframe.solve(BlockFrictionCoefficient())
    data = json.loads(result.to_json())
    assert data["parameters"]["mu"] == pytest.approx(2.0) and data["T"] == 1.5
    assert "mu = 2" in result.summary() and "parameters: mu = 2" in repr(result)
    pytest.importorskip("pandas")
    assert result.to_dataframe().attrs["parameter_mu"] == pytest.approx(2.0)
    timed = qdframe.solve(BlockStoppingTime())
    assert "(found)" in timed.summary() and timed.to_dataframe().attrs["T"] == pytest.approx(0.5)


@pytest.mark.parametrize("make, field", [
    (lambda: BlockFrictionCoefficient(parameters={"nu": 1.0}), "parameters"),
    (lambda: BlockFrictionCoefficient(parameters={"mu": -1.0}), "parameters['mu']"),
    (lambda: BlockFrictionCoefficient(parameters=(1.0, 2.0)), "parameters"),
    (lambda: BlockStoppingTime(free_T="yes"), "free_T"),
    (lambda: qdframe.solve(BlockStoppingTime(), free_T=1), "free_T"),
    (lambda: qdframe.solve(BlockFrictionCoefficient(), parameters=[1.0]), "parameters"),
])
def test_bad_unknowns_are_named(make, field):
    with pytest.raises(InputError) as caught:
        make()
    assert caught.value.field == field


def test_bad_declarations_are_named():
    class Clash(SetModel):
        state_names = "p v"
        parameter_names = "v"
        default_parameters = (1.0,)
        default_x0 = (0.0, 1.0)

        def sets(self, p, v, v2):
            return {p: v, v: -v2}

    with pytest.raises(InputError, match="parameter_names"):
        Clash()

    class BadBounds(BlockFrictionCoefficient):
        parameter_bounds = {"mu": (3.0, 1.0)}

    with pytest.raises(InputError, match="parameter_bounds"):
        BadBounds()


def test_command_line_free_T_and_parameter(tmp_path, capsys):
    from qdframe.cli import main

    out = tmp_path / "r.json"
    assert main(["solve", "relay-oscillator", "--free-T", "--T", "5", "--periodic", "x1,x2", "--json", str(out),
                 "--quiet"]) == 0
    assert abs(json.loads(out.read_text())["T"] - 4 * np.sqrt(2)) <= 1e-6
    found = tmp_path / "mu.json"
    assert main(["solve", "block-friction-coefficient", "--parameter", "mu=4", "--json", str(found)]) == 0
    assert re.search(r"^parameters\s+mu = 2\s*$", capsys.readouterr().out, flags=re.M)  # not 2.5, not 25
    assert abs(json.loads(found.read_text())["parameters"]["mu"] - 2.0) <= 1e-6  # the exact μ = 2
    assert main(["solve", "block-stopping-time", "--fixed-T", "--T", "0.5", "--quiet"]) == 0
    assert main(["solve", "block-friction-coefficient", "--parameter", "mu"]) == 2
    assert "NAME=GUESS" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["solve", "--help"])
    helped = capsys.readouterr().out
    assert "--free-T" in helped and "--parameter" in helped


def test_gauss_newton_keeps_a_constant_state_one_unknown():
    """The step moves T (and p) by one amount at every node and never their z: the constant
    states are one unknown in the KKT systems (qdframe/directions/gauss_newton.py)."""
    from qdframe.registry import make_direction
    from qdframe.functional import Functional
    from qdframe.schemes.grid import Grid

    model = Unknowns(BlockFrictionCoefficient())
    assert model.constant_states == (2,)
    functional = Functional(model, Grid(model.T, 301, "implicit-euler"))
    xi = functional.initial_point()
    solver = make_direction("gauss-newton")
    solver.start(functional)
    step = solver.compute(functional, xi, 1e-3).step
    assert np.ptp(step[:, 2]) == 0.0 and abs(step[0, 2]) > 0  # σ_μ moves, the same everywhere
    assert np.all(step[:, 3 + 2] == 0.0)  # its z stays 0


class RestoringRelay(SetModel):
    """x1' = x2, x2' ∈ −x1 − Sgn(x1) from (1, 0), periodic in x2 only: period 4π/3, the
    crossings at π/3 and π (a new user's problem: the pins of its crossings answered their
    own moves like a mirror, and the solve certified T 3e-4 off)."""

    name = "restoring-relay"
    state_names = "x1 x2"
    default_x0 = (1.0, 0.0)
    periodic = ("x2",)
    default_T = 5.0
    free_T = True

    def sets(self, x1, x2):
        return {x1: x2, x2: -x1 - Sgn(x1)}

    @staticmethod
    def motion(t):
        phase = np.mod(t, 4 * np.pi / 3)
        right = (phase <= np.pi / 3) | (phase >= np.pi)
        shifted = np.where(phase >= np.pi, phase - 4 * np.pi / 3, phase)
        x1 = np.where(right, -1 + 2 * np.cos(shifted), 1 - 2 * np.cos(phase - 2 * np.pi / 3))
        x2 = np.where(right, -2 * np.sin(shifted), 2 * np.sin(phase - 2 * np.pi / 3))
        return np.stack([x1, x2], axis=1)


def test_crossings_pinned_with_T_free_settle_and_the_estimate_holds():
    result = qdframe.solve(RestoringRelay())
    error = np.max(np.abs(result.x - RestoringRelay.motion(result.t)))
    assert error <= result.error_estimate  # whatever the status: the estimate bounds the error
    assert result.status == "solved", result.message
    assert abs(result.T - 4 * np.pi / 3) <= 1e-6 and error <= 1e-6 * 2
    assert np.allclose(result.switch_times, [np.pi / 3, np.pi], atol=1e-6)


def test_a_free_T_needs_a_condition_and_is_found_from_either_side():
    """Without an end value or a periodic condition every T would do: refused. A stopping
    time guessed 6× too long, past the stop, is found (the start's sweep looks downwards)."""
    from qdframe.models.user_friction import RelayOscillator

    with pytest.raises(InputError) as caught:
        qdframe.solve(RelayOscillator(), free_T=True)
    assert caught.value.field == "free_T"

    class Thrown(SetModel):
        name = "thrown"
        state_names = "p v"
        default_x0 = (0.0, 3.0)
        default_xT = {"p": 1.0}
        default_T = 3.0  # stops at t = 1 (p = 1.5); p = 1 at T* = 1 − √3/3
        free_T = True

        def sets(self, p, v):
            return {p: v, v: -3 * Sgn(v)}

    result = qdframe.solve(Thrown())
    assert result.solved and abs(result.T - (1 - np.sqrt(3) / 3)) <= 1e-6


@pytest.mark.parametrize("free_T", [True, False])
def test_a_periodic_condition_met_only_by_its_tolerance_is_not_solved(free_T):
    """Guessed T = 1e-8, the relay's orbit through (1, 0) is 'periodic' within the tolerance
    without turning back: not solved, and the message names the way out. With T free the
    error vs the known solution counts T (true 4√2)."""
    result = qdframe.solve(RelayPeriod(T=1e-8, free_T=free_T))
    assert result.status != "solved"
    assert "does not turn back" in result.message and "T_bounds" in result.message
    if free_T:
        assert result.solution_error == pytest.approx(4 * np.sqrt(2), abs=1e-6)


def test_an_equilibrium_is_periodic_for_every_T():
    """x ≡ 0 of x' ∈ −Sgn(x) closes every period exactly: a short T stays solved."""

    class Rest(SetModel):
        name = "rest"
        state_names = "x y"
        default_x0 = (0.0, 1.0)
        periodic = (0, 1)
        default_T = 1e-8

        def sets(self, x, y):
            return {x: -Sgn(x), y: -Sgn(x) * y}

    result = qdframe.solve(Rest())
    assert result.status == "solved", result.message
    assert np.max(np.abs(result.x - [0.0, 1.0])) <= 1e-12


def test_a_period_drawn_towards_zero_says_so():
    """Guessed at T = 1e-3, the relay's period shrinks towards the trivial T = 0 (ending
    `stationary` at T ≈ 1.6e-7): the message names the shrinkage and T_bounds."""
    result = qdframe.solve(RelayPeriod(T=1e-3))
    assert result.status != "solved" and result.T < 1e-5
    assert "T shrank from the guess 0.001" in result.message and "T_bounds" in result.message


@pytest.mark.parametrize("given", [{"mu": 2.0}, (2.0,), [2.0]])
def test_exact_parameters_are_a_mapping_or_the_values_in_order(given):
    """Issue 55: `exact_parameters = (0.2,)`, written like `default_parameters`, was ignored
    without a solution and raised AttributeError after the solve with one."""
    class Known(BlockFrictionCoefficient):
        exact_parameters = given

    model = Known()
    assert model.exact_parameters == {"mu": 2.0}
    result = qdframe.solve(model)
    assert result.solved and result.solution_error <= 1e-6


@pytest.mark.parametrize("given, field", [({"nu": 2.0}, "nu"), ((2.0, 3.0), "1 comma-separated numbers"),
                                          ("2.0", "name: value")])
def test_exact_parameters_of_another_form_are_refused_naming_the_field(given, field):
    class Known(BlockFrictionCoefficient):
        exact_parameters = given

    with pytest.raises(InputError, match=rf"Known\.exact_parameters: .*{re.escape(field)}"):
        Known()


class _BiasedRelay(SetModel):
    """x1' = x2, x2' ∈ −x1 − Sgn(x1) + 0.2 from (1, 0), x2 periodic, T free (issue 55): the
    orbit keeps its energy, and x2 = 0 at its far turning point too, so every half-period is a
    solution of the posed problem. Closed form: harmonic about −0.8 while x1 > 0 (from 1 to 0
    in t₁ = arccos(0.8/1.8)) and about 1.2 while x1 < 0 (τ₂ = π − arccos(−1.2/R), R² = 1.2² + v₁²)."""

    name = "biased-relay"
    state_names = "x1 x2"
    default_x0 = (1.0, 0.0)
    default_T = 5.1  # a guess above the period, nearer to one and a half periods
    free_T = True
    periodic = ("x2",)

    def sets(self, x1, x2):
        return {x1: x2, x2: -x1 - Sgn(x1) + 0.2}


def _biased_relay_period() -> float:
    t1 = np.arccos(0.8 / 1.8)
    speed = 1.8 * np.sin(t1)
    return 2 * t1 + 2 * (np.pi - np.arccos(-1.2 / np.hypot(1.2, speed)))


def test_a_period_from_a_guess_above_it_tries_the_sweeps_next_candidate():
    """From 5.1 the sweep's nearest candidate is one and a half periods (6.12), where the solve
    stalled and then, from the model's constant start, shrank T to 8.6e-8 (a constant x is
    periodic for any T): `stationary`. The next candidate, the period, is solved."""
    result = qdframe.solve(_BiasedRelay())
    assert result.solved, result.message
    assert abs(result.T - _biased_relay_period()) <= 1e-6 * max(1.0, float(np.max(np.abs(result.x))))
    assert "from the first T = 6.12" in result.message and "it is solved" in result.message


def test_a_periods_candidate_is_never_left_for_the_trivial_period():
    """Each candidate of the sweep is solved with T bounded below by half of it (PERIOD_FLOOR):
    from 6.12 (one and a half periods) the solve had shrunk T to 8.6e-8, from the guess 8.0
    (twice the period, 8.17) every try ended near T = 0 (`stationary` at T = 2e-9)."""
    result = qdframe.solve(_BiasedRelay(T=8.0))
    assert result.T > 0.5 * 4.0 and "T shrank" not in result.message
    first = qdframe.solve(_BiasedRelay())
    assert "from the first T = 6.12" in first.message and "(T = 6." in first.message


@pytest.mark.xfail(strict=True, reason="README, Known failures: a period of more than half an orbit from its "
                                       "candidate: `stationary` at T = 4.936002 (1.5 periods are 4.93578), its "
                                       "selections 5e-5 from Sgn")
def test_one_and_a_half_periods_of_a_smaller_orbit_are_solved():
    """Issue 55: (c, A) = (0.1, 0.5) from the guess 4.11, whose nearest candidates are one and a
    half periods (4.93578) and one period (3.29052): the default call ends at a solution."""
    class Smaller(_BiasedRelay):
        default_x0 = (0.5, 0.0)
        default_T = 4.11

        def sets(self, x1, x2):
            return {x1: x2, x2: -x1 - Sgn(x1) + 0.1}

    result = qdframe.solve(Smaller())
    assert result.solved, result.message
