"""Issue 35, item 4: a model that returns NaN partway through stops the run with one error
line after a bounded number of rejected trial points, naming piece, node, t and state
(gauss-newton used to reject ~24 trial points per iteration and run all 500 to max_iter)."""

from __future__ import annotations

import re

import pytest

import qdframe
from qdframe import registry
from qdframe.cli import main
from qdframe.descent.loop import REJECTED_LIMIT
from qdframe.errors import ModelOutputError
from qdframe.status import EXIT_ERROR
import numpy as np

from qdframe.model import InclusionModel, SetBlock


class NaNPastThreshold(InclusionModel):
    """pos' = vel, vel' = 1 − pos, pos(0) = 0, pos(1) = 1 (vel(0) free): the solution rises to
    pos = 1 at t = 1, but vel' is NaN where pos > threshold."""

    name = "test-nan-mid-run"
    state_names = ("pos", "vel")
    default_x0 = (0.0, float("nan"))
    end_indices = (0,)
    default_end_values = (1.0,)
    threshold = 0.5

    def blocks(self):
        threshold = self.threshold

        def position(y):
            grad = np.zeros_like(y)
            grad[:, 1] = 1.0
            return y[:, 1].copy(), grad

        def velocity(y):
            grad = np.zeros_like(y)
            grad[:, 0] = -1.0
            return np.where(y[:, 0] > threshold, np.nan, 1.0 - y[:, 0]), grad

        return (SetBlock.equation(0, position, name="pos'"), SetBlock.equation(1, velocity, name="vel'"))


def nan_model(threshold: float) -> InclusionModel:
    return type("NaNModel", (NaNPastThreshold,), {"threshold": threshold})()


@pytest.mark.parametrize("direction", ["gauss-newton", "native"])
@pytest.mark.parametrize("threshold", [0.9, 0.95])
def test_a_descent_that_keeps_stepping_into_nan_stops_with_the_trial_points_state(direction, threshold):
    """pos must rise to 1 but vel' is NaN past the threshold."""
    with pytest.raises(ModelOutputError) as info:
        qdframe.solve(nan_model(threshold), nodes=21, direction=direction)
    message = str(info.value)
    assert "\n" not in message and message.startswith("model 'test-nan-mid-run': block vel' max-group \"vel'\" is non-finite")
    match = re.search(r"at node (\d+) \(t = ([0-9.e+-]+)\) of a line-search trial point of iteration (\d+), "
                      r"where \(pos = ([0-9.e+-]+), vel = ([0-9.e+-]+)\); (\d+) trial points rejected", message)
    assert match, message
    node, t, iteration, pos, _, rejected = match.groups()
    assert float(t) == pytest.approx(int(node) / 20) and float(pos) >= threshold - 1e-6  # where the model is NaN
    assert REJECTED_LIMIT <= int(rejected) < REJECTED_LIMIT + 100 and int(iteration) < 100
    assert info.value.nonfinite and info.value.node == int(node)


def test_the_command_line_prints_the_one_line_and_exits_non_zero(monkeypatch, capsys):
    model = type("NaNPast09", (NaNPastThreshold,), {"threshold": 0.9})
    real = registry.lookup

    def lookup(kind, name):
        if kind == "models" and name == "test-nan-mid-run":
            return registry.Entry("models", name, "test", "test:NaNPast09", model)
        return real(kind, name)

    monkeypatch.setattr("qdframe.registry.lookup", lookup)
    assert main(["solve", "test-nan-mid-run", "--nodes", "21"]) == EXIT_ERROR
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "trial points rejected where the model is non-finite" in err


def test_a_few_rejected_trial_points_do_not_stop_a_run():
    """NaN just below the target only where the line search overshoots: the run ends on its own."""
    result = qdframe.solve(nan_model(0.99), nodes=21, direction="native")
    assert result.status == "stationary" and "line-search trial point(s) rejected" in result.message
