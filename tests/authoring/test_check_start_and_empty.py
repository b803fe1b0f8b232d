"""Issue 35, item 7: check-model calls initial_guess() and checks it (shapes, finite values),
and finds a set that is empty at every sample point or along the start."""

from __future__ import annotations

import numpy as np
import pytest

from qdframe import load_model
from qdframe.authoring import check_model
from qdframe.sets import Interval, SetModel


class Base(SetModel):
    name = "check-start"
    state_names = "x v"
    default_x0 = (0.0, 0.0)
    default_xT = {"x": 1.0}

    def sets(self, x, v):
        return {x: v, v: Interval(-1, 1)}


def _row(report, label):
    (row,) = [p for p in report.pieces if p.label == label]
    return row


def test_an_always_empty_set_fails():
    class Empty(Base):
        def sets(self, x, v):
            return {x: v, v: Interval(0, 1) & Interval(2, 3)}

    report = check_model(Empty())
    row = _row(report, "F[v] set")
    assert not report.ok and row.status == "empty set" and "empty at all 64 sample points and along the start" in row.detail
    assert report.message().startswith("model 'Empty': F[v] set: empty set")


def test_a_set_empty_along_the_start_fails():
    """[−1, 1] ∩ [x + 0.5, x + 1] is empty for x > 0.5, where this start x = 3t is from t = 0.2 on."""
    class EmptyLater(Base):
        def sets(self, x, v):
            return {x: v, v: Interval(-1, 1) & Interval(x + 0.5, x + 1)}

        def initial_guess(self, t):
            return np.stack([3 * t, np.zeros_like(t)], axis=1), np.zeros((t.size, 2))

    row = _row(check_model(EmptyLater()), "F[v] set")
    assert row.status == "empty set" and "along the start (initial_guess()) at t = 0.2" in row.detail


def test_a_set_empty_at_some_sample_points_only_is_noted_not_failed():
    report = check_model(load_model("disturbed-control"))
    row = _row(report, "F[x2] set")
    assert report.ok and row.ok and row.note.startswith("empty at 25 of 64 sample points")
    assert "empty at 25 of 64" in report.table()


@pytest.mark.parametrize("guess, status, detail", [
    (lambda t: (np.full((t.size, 2), np.nan), np.zeros((t.size, 2))), "non-finite", "returned nan for x['x'] at t = 0"),
    (lambda t: (np.zeros((t.size, 3)), np.zeros((t.size, 2))), "bad shape", "x of shape (11, 3) for 11 points"),
    (lambda t: (np.zeros((t.size, 2)), np.zeros(t.size)), "bad shape", "z of shape (11,)"),
    (lambda t: 1 / 0, "error", "ZeroDivisionError: division by zero at "),
])
def test_the_initial_guess_is_called_and_checked(guess, status, detail):
    model = type("Guessed", (Base,), {"initial_guess": lambda self, t: guess(t)})()
    report = check_model(model)
    row = _row(report, "initial_guess()")
    assert not report.ok and row.status == status and detail in row.detail


def test_a_good_start_and_sets_pass():
    report = check_model(Base())
    assert report.ok and _row(report, "initial_guess()").ok and _row(report, "F[v] set").ok
