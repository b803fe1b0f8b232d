"""A run that stops unsolved with I bounded away from 0 names the unmet condition (issue 14).

Targets outside a known reachable set: the stopping block (p(3) = 1 is the only reachable
end), 7.2 (|x(1)| ≤ 1), an empty set and a periodic or surface condition the inclusion
contradicts. I's minimizer is then a least-squares compromise: the iterate's x(T) lies
between the reachable set and the target, so the gap read from x is smaller than the
distance to the reachable set, and the dynamics carry the rest of I.
"""

import re

import numpy as np
import pytest

import qdframe
from qdframe.descent.diagnosis import condition_parts, unmet_conditions
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.sets import Interval, define_model, intersection

NAN = float("nan")


def end_clause(message: str, condition: str) -> tuple[float, float]:
    """The nearest value and the gap the message gives for `condition`, e.g. "position(T) = 3"."""
    found = re.search(re.escape(f"end condition {condition} not reached: nearest ") + r"(\S+) \(gap (\S+)\)", message)
    assert found, message
    return float(found.group(1)), float(found.group(2))


def test_an_end_value_past_where_the_block_sticks_is_named_with_the_value_reached_and_the_gap():
    """block-stop-stick stops at p = 1 for good; p(3) = 3 cannot be reached. The iterate
    gets to p(3) ≈ 2.91 only by breaking the friction law (σ carries most of I), so the
    end condition is named last, with its own small part of I, and says so."""
    result = qdframe.solve(qdframe.load_model("block-stop-stick", end_values=[3, NAN]), nodes=101, max_iter=60)
    assert result.status in {"stationary", "max_iter"} and result.I > 0.1
    nearest, gap = end_clause(result.message, "position(T) = 3")
    assert nearest == pytest.approx(result.x[-1, 0], abs=1e-3) and 1.0 < nearest < 3.0
    assert gap == pytest.approx(3.0 - result.x[-1, 0], rel=0.01)
    assert "only by violating the dynamics; it may lie outside the reachable set" in result.message
    # where I sits: the friction law's selection first
    assert result.message.index("selection of μg·Sgn(−v) not in Sgn(s)") < result.message.index("end condition")
    assert result.message.count("; ") >= 3  # the stop reason and three clauses (the end's hint after "; ")


def test_an_end_value_outside_the_unit_disc_is_named_with_the_inclusion_it_conflicts_with():
    """7.2: x' ∈ disc ∩ ellipse, x(0) = 0, T = 1, so |x(1)| ≤ 1; x(1) = (3, 0) is 2 away.
    The compromise z ≡ (2, 0) splits the 2 evenly: x1(T) = 2 (gap 1) and distance 1 from F."""
    result = qdframe.solve(qdframe.load_model("paper-7.2", end_values=[3, 0]))
    assert result.status == "stationary" and result.I == pytest.approx(1.0, rel=1e-6)
    nearest, gap = end_clause(result.message, "x1(T) = 3")
    assert nearest == pytest.approx(2.0, abs=1e-3) and gap == pytest.approx(1.0, rel=1e-3)
    distance = float(re.search(r"inclusion for \(x1, x2\)' \(F\) not met: distance (\S+)", result.message).group(1))
    assert gap + distance * 1.0 >= 1.9  # the gap and the drift bought by leaving F: the 2 outside |x(1)| ≤ 1
    assert "x2(T)" not in result.message  # x2(T) = 0 is met
    assert "empty" not in result.message


def test_an_empty_intersection_is_named_as_the_inclusion_that_may_be_empty():
    Empty = define_model("empty-velocity", "x", lambda x: {x: intersection(Interval(1, 2), Interval(3, 4))}, x0=(0.0,))
    result = qdframe.solve(Empty())
    assert result.status == "stationary"
    assert re.search(r"inclusion for x' \(F\[x\]\) not met: distance 5\.0e-01 at t = \S+; the set may be empty there",
                     result.message), result.message
    assert "end condition" not in result.message


def test_a_periodic_condition_the_inclusion_contradicts_is_named_with_both_ends():
    """x' ∈ [1, 2] only increases x: x(T) = x(0) is impossible."""
    Rising = define_model("rising", "x", lambda x: {x: Interval(1, 2)}, x0=(NAN,))
    result = qdframe.solve(Rising(periodic=["x"]))
    assert result.status == "stationary"
    found = re.search(r"periodic condition x\(T\) = x\(0\) not met: x\(0\) = (\S+), x\(T\) = (\S+) \(gap (\S+)\)",
                      result.message)
    assert found, result.message
    start, end, gap = map(float, found.groups())
    assert gap == pytest.approx(end - start, abs=2e-3) and gap > 0.4
    assert "inclusion for x'" in result.message


def test_a_surface_the_inclusion_leaves_is_named():
    """x1' ∈ [1, 2], x2' = 0 from 0 cannot stay on x1 = x2."""
    Apart = define_model("apart", "x1 x2", lambda x1, x2: {x1: Interval(1, 2), x2: 0}, x0=(0.0, 0.0),
                         surface=lambda x1, x2: x1 - x2)
    result = qdframe.solve(Apart())
    assert result.status == "stationary"
    assert re.search(r"surface e1 = 0 not met: max \|e1\| \S+ at t = 1\b", result.message), result.message


def test_a_run_out_of_iterations_keeps_the_diagnosis():
    result = qdframe.solve(qdframe.load_model("paper-7.2", end_values=[3, 0]), nodes=101, max_iter=2)
    assert result.status == "max_iter"
    assert result.message.startswith("2 iterations spent; ")
    end_clause(result.message, "x1(T) = 3")


@pytest.mark.parametrize("model", ["block-stop-stick", "paper-7.2"])
def test_a_solved_run_names_no_condition(model):
    result = qdframe.solve(model)
    assert result.status == "solved"
    assert not any(word in result.message for word in ("not met", "not reached", "not in Sgn"))


def test_the_parts_sum_to_I_and_at_most_three_are_named():
    """condition_parts splits I exactly (the equation blocks' h = |z − f|, the sets' max(0, ℓ))."""
    rng = np.random.default_rng(1)
    for name, end_values in (("block-stop-stick", [3, NAN]), ("paper-7.2", [3, 0]), ("slide-on-line", None)):
        model = qdframe.load_model(name, end_values=end_values) if end_values else qdframe.load_model(name)
        for signs in ("exact", "band"):
            functional = Functional(model, Grid(model.T, 41, model.default_scheme), signs=signs)
            xi = functional.initial_point() + 0.3 * rng.standard_normal(functional.initial_point().shape)
            parts = condition_parts(functional, xi)
            assert sum(clause.part for clause in parts) == pytest.approx(functional.terms(xi).I, rel=1e-12)
            text = unmet_conditions(functional, xi)
            assert 1 <= sum(text.count(word) for word in ("not met", "not reached", "not in Sgn")) <= 3
