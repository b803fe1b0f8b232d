"""`qdframe bench unknowns`: seconds per iteration with T or p unknown against fixed."""

from __future__ import annotations

import numpy as np

from qdframe.bench.unknown_cost import per_iteration, run, table
from qdframe.registry import load_model
from qdframe.unknowns import Unknowns, restated


def test_fixed_and_unknown_forms_of_one_model():
    """The fixed form has the model's own columns; the unknown one adds μ's x and z."""
    model = load_model("block-friction-coefficient")
    fixed = Unknowns(restated(model, False, None), fixed=True)
    assert fixed.state_names == ("p", "v") and fixed.n_states == 2
    assert Unknowns(model).state_names == ("p", "v", "mu")
    fixed_s, unknown_s = per_iteration(fixed, Unknowns(model), 101, iterations=3)
    assert fixed_s > 0 and unknown_s > 0


def test_run_and_table():
    cells = run(("block-stopping-time",), (201,), iterations=3)
    (cell,) = cells
    assert cell.columns == (5, 7) and cell.fixed > 0 and cell.unknown > 0
    text = table(cells)
    assert "block-stopping-time | 201 |" in text and "5 → 7" in text


def test_a_timed_iteration_can_be_repeated_from_the_same_state():
    """Each repeat times the same work: timing leaves the iterate and the solver's state (μ, the
    active set) as they were, and `advance` then takes that iteration."""
    from qdframe.bench.unknown_cost import _Iterates

    run = _Iterates(Unknowns(load_model("block-friction-coefficient")), 101)
    run.advance()
    xi, state = run.xi.copy(), run.solver.state
    assert run.timed() > 0 and run.timed() > 0
    assert np.array_equal(run.xi, xi) and run.solver.state is state  # replaced in the trials, never changed
    run.advance()
    assert not np.array_equal(run.xi, xi)
