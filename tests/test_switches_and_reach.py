"""Issue 35, item 5: switch times inside [0, T], one per event within the mesh's resolution;
"may lie outside the reachable set" only where a test of reachability supports it, and
the value reached printed with the digits its gap needs."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

import qdframe
from qdframe.descent.diagnosis import _number
from qdframe.sets import SetModel, Sgn
from qdframe.certificates.switches import merge_close


# ---------------------------------------------------------------- switch times
@pytest.mark.parametrize("name", ["coulomb-rest-to-rest", "stick-slip-oscillator"])
def test_switch_times_lie_in_0_T(name):
    """At N = 101 these were −0 and 2.000019 (T = 2), and −0.56 (T = 100): extrapolations
    past an end, where the block is at rest at t = 0 and where it stops at T."""
    result = qdframe.solve(name, nodes=101, estimate=False)
    times = np.asarray(result.switch_times)
    assert result.converged and times.size
    assert np.all((times >= 0.0) & (times <= result.T)) and not np.any(np.signbit(times))


class TwoStops(SetModel):
    """a' ∈ −Sgn(a), b' ∈ −Sgn(b) from (1, 1.004): a stops at t = 1, b at 1.004."""

    name = "two-stops"
    state_names = "a b"
    default_x0 = (1.0, 1.004)
    default_T = 2.0

    def sets(self, a, b):
        return {a: -Sgn(a), b: -Sgn(b)}


def test_two_terms_switching_closer_than_the_mesh_step_are_two_switches():
    """Two blocks that stop 0.004 apart are two stops on a mesh of 0.02 too (each term's own
    time, located from its own smooth side; their mean, which is neither, was reported once)."""
    coarse = qdframe.solve(TwoStops(), nodes=101, estimate=False)  # h = 0.02
    assert np.allclose(coarse.switch_times, [1.0, 1.004], atol=0.02)
    fine = qdframe.solve(TwoStops(), nodes=1001, estimate=False)  # h = 0.002
    assert np.allclose(fine.switch_times, [1.0, 1.004], atol=1e-6)


def test_one_terms_times_closer_than_the_mesh_step_are_one():
    mesh = np.linspace(0.0, 1.0, 11)
    assert np.allclose(merge_close(np.array([0.5, 0.52]), mesh), [0.51])
    assert np.allclose(merge_close(np.array([0.5, 0.52]), mesh, within=1e-9), [0.5, 0.52])


def test_merge_close_keeps_times_apart_by_more_than_the_local_step():
    mesh = np.linspace(0.0, 1.0, 11)
    assert np.allclose(merge_close(np.array([0.3, 0.35, 0.62, 0.9]), mesh), [0.325, 0.62, 0.9])
    refined = np.array([0.0, 0.3, 0.32, 0.34, 0.36, 1.0])  # a mesh fine around 0.33 resolves 0.3 and 0.35
    assert np.allclose(merge_close(np.array([0.3, 0.35]), refined), [0.3, 0.35])
    assert merge_close(np.zeros(0), mesh).size == 0


# ---------------------------------------------------------------- the unmet-condition diagnosis
def _end(message: str, condition: str) -> str:
    """The end condition's clause and what follows it in the message."""
    start = message.find(f"end condition {condition} not reached: ")
    assert start >= 0, message
    return message[start:]


def test_a_reachable_end_point_is_not_called_unreachable():
    """paper-7.1 with the paper's method stops on its ε-rule 3e-4 short of x2(1) = 1, which
    the known solution x2 = t reaches: no reachability claim, and the value shows the gap."""
    result = qdframe.solve("paper-7.1", direction="native", nodes=101, estimate=False)
    assert result.status == "stationary" and "reachable set" not in result.message
    clause = _end(result.message, "x2(T) = 1")
    nearest = float(re.search(r"nearest (\S+) \(gap (\S+)\)", clause).group(1))
    assert nearest != 1.0 and abs(nearest - result.x[-1, 1]) < 1e-5  # was "nearest 1.000" for a gap of 3e-4


def test_no_claim_after_zero_iterations_on_a_reachable_target():
    result = qdframe.solve("paper-7.1", max_iter=0, nodes=101, estimate=False)
    assert result.status == "max_iter" and "not reached" in result.message and "reachable set" not in result.message


def test_a_speed_bound_supports_the_claim():
    """paper-7.2: |x'| ≤ 1, x(0) = 0, T = 1: x1(1) = 3 is out of reach, and the bound says so."""
    result = qdframe.solve(qdframe.load_model("paper-7.2", end_values=[3, 0]), nodes=101, estimate=False)
    assert "it may lie outside the reachable set (x1' ≤ 1 at every state tried, so x1(T) ≤ 1.000)" in result.message


def test_a_simulation_supports_the_claim_for_deterministic_dynamics():
    """block-stop-stick stops at p = 1 and sticks: its Filippov solution is the reachable set."""
    result = qdframe.solve(qdframe.load_model("block-stop-stick", end_values=[3, math.nan]), nodes=101, max_iter=60,
                           estimate=False)
    clause = _end(result.message, "position(T) = 3")
    found = re.search(r"the Filippov solution from x\(0\) ends at position\(T\) = (\S+)\)", clause)
    assert found and float(found.group(1)) == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("value, gap, text", [
    (0.999684, 3.2e-4, "0.999684"), (2.0, 1.0, "2.000"), (-2.0, 3.0, "-2.000"), (1.00000012, 1.2e-7, "1.00000012"),
    (12345.678, 0.5, "12345.68"), (1e-5, 1e-6, "1.000e-05"),
])
def test_the_value_reached_has_the_digits_its_gap_needs(value, gap, text):
    assert _number(value, gap) == text


def test_a_pin_counts_as_misplaced_only_beside_a_switch_it_holds():
    """misplaced_switches (the bisection estimate's term for pins both solves share): a pin one mesh
    interval from block-stop-stick's stop at t = 1 counts its distance to it; a pin where nothing
    switches (t = 0.225, three quarters of the horizon's first third away) counts nothing, where it
    had counted its distance to the stop (a state bound's junction, pinned on a coarse grid and not
    located on the next, made the estimate 2.2 on an error of 3e-3)."""
    from qdframe.certificates.estimates import misplaced_switches
    from qdframe.functional import Functional
    from qdframe.registry import load_model
    from qdframe.schemes.grid import Grid

    model = load_model("block-stop-stick")
    tau = np.linspace(0.0, model.T, 41)
    result = qdframe.solve(model, mesh=tau, scheme="radau-iia", estimate=False, continuation="none")
    assert np.allclose(result.switch_times, [1.0], atol=1e-9)
    jump = 2.0 * float(np.max(np.abs(result.z)))

    def misplaced(*pins: float) -> float:
        return misplaced_switches(Functional(model, Grid.from_mesh(tau, "radau-iia", switches=pins)), result)

    assert misplaced() == 0.0
    assert misplaced(0.225) == 0.0
    assert misplaced(1.05) == pytest.approx(0.05 * jump, rel=1e-6)
    assert misplaced(0.225, 1.05) == misplaced(1.05)
