"""The yardstick of `qdframe bench run` (qdframe/bench/references.py): each kind of
reference against numbers worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

import qdframe
from qdframe.bench.references import EVENTS, EXACT, PROJECTION, judge, kind


def _bang_bang(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """coulomb-rest-to-rest driven by u = 2 for t < 1, −2 after, from rest (F = 1): v = t to
    t = 1, v' = −3 until v = 0 at 4/3 (p = 2/3), then v' = −1; p(2) = 4/9. Returns x, z, u."""
    s, r = t - 1.0, t - 4.0 / 3.0
    p = np.where(t < 1, t**2 / 2, np.where(t < 4 / 3, 0.5 + s - 1.5 * s**2, 2 / 3 - r**2 / 2))
    v = np.where(t < 1, t, np.where(t < 4 / 3, 1 - 3 * s, -r))
    acceleration = np.where(t < 1, 1.0, np.where(t < 4 / 3, -3.0, -1.0))
    return np.stack([p, v], axis=1), np.stack([v, acceleration], axis=1), np.where(t < 1, 2.0, -2.0)


class BangBang:
    breaks = (1.0,)

    def __call__(self, t: float) -> np.ndarray:
        return np.array([2.0 if t < 1.0 else -2.0])


def test_each_model_has_the_reference_its_problem_allows():
    assert kind(qdframe.load_model("block-stop-stick")) == EXACT  # one solution, in closed form
    assert kind(qdframe.load_model("coulomb-rest-to-rest")) == EVENTS  # a set of solutions, an input to replay
    assert kind(qdframe.load_model("paper-7.2")) == PROJECTION  # a set of solutions, set-valued F


def test_exact_error_end_error_and_switch_error_by_hand():
    model = qdframe.load_model("block-stop-stick")
    t = np.linspace(0.0, model.T, 31)
    x = model.exact_solution(t).copy()
    x[7, 0] += 1e-3
    x[-1, 1] -= 2e-4
    verdict = judge(model, t, x, np.zeros_like(x), switch_times=[1.0 + 2.5e-3])
    assert verdict.kind == EXACT
    assert verdict.error == pytest.approx(1e-3, rel=1e-9)
    assert verdict.end_error == pytest.approx(2e-4, rel=1e-9)
    assert verdict.switch_error == pytest.approx(2.5e-3, rel=1e-9)
    assert judge(model, t, x, np.zeros_like(x)).switch_error is None  # the solver reported none


def test_an_events_replay_with_the_peers_own_input_sees_the_missed_end():
    """The bang-bang motion is a true motion: the replay reproduces it, and the error is how far
    that motion is from the end conditions p(2) = 1, v(2) = 0: max(|4/9 − 1|, |−2/3|) = 2/3."""
    model = qdframe.load_model("coulomb-rest-to-rest")
    t = np.linspace(0.0, 2.0, 61)
    x, z, _ = _bang_bang(t)
    verdict = judge(model, t, x, z, inputs=BangBang())
    assert verdict.kind == EVENTS
    assert verdict.distance < 1e-12
    assert verdict.end_error == pytest.approx(2 / 3, abs=1e-12)
    assert verdict.error == pytest.approx(2 / 3, abs=1e-12)


def test_an_events_replay_recovers_the_input_from_the_velocities():
    """Without the peer's input, u = clip(v' + F·sign(v), ±U) from the trajectory itself; a
    trajectory off the motion by δ in p is judged δ off."""
    model = qdframe.load_model("coulomb-rest-to-rest")
    t = np.linspace(0.0, 2.0, 4001)
    x, z, _ = _bang_bang(t)
    exact = judge(model, t, x, z)
    shifted = x.copy()
    shifted[1:, 0] += 1e-2
    moved = judge(model, t, shifted, z)
    assert exact.distance < 2e-3 and exact.end_error == pytest.approx(2 / 3, abs=2e-3)
    assert moved.distance == pytest.approx(1e-2, abs=2e-3) and moved.error == pytest.approx(moved.end_error)


def test_a_block_that_comes_to_rest_between_two_points_is_judged_by_the_admissible_input_that_fits():
    """v' = −2 from v = 2 (u = −1 against friction 1) reaches p = 1 and stops at t = 1, between
    two points, and rests there (the end conditions). The first point at rest has z_v = 0:
    without the run's selections its input is undetermined, the sign before (u = 1 there)
    or rest (u = 0). Both are admissible, so the judge replays both and takes the nearer:
    measured 6.9e-5 with rest, 2.2e-4 with the sign before (each linearly continued: the true
    input's jump from −1 to 0 at t = 1 falls between the points)."""
    model = qdframe.load_model("coulomb-rest-to-rest")
    t = np.linspace(0.0, 2.0, 40)
    v = np.maximum(2.0 - 2.0 * t, 0.0)
    x = np.stack([np.where(t < 1.0, 2.0 * t - t**2, 1.0), v], axis=1)
    z = np.stack([v, np.where(t < 1.0, -2.0, 0.0)], axis=1)
    verdict = judge(model, t, x, z)
    assert verdict.error < 1e-4, verdict
