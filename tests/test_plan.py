"""The public plan (issue 54): `qdframe.solve.plan(model, …)` decides what `qdframe.solve(model, …)`
runs from the same arguments, and the solve runs exactly that."""

from __future__ import annotations

import dataclasses

import pytest

import qdframe
from qdframe.errors import InputError
from qdframe.solve import Plan, plan


def test_the_plan_is_frozen_and_reached_from_the_solve_function():
    chosen = qdframe.solve.plan(qdframe.load_model("paper-7.3"))
    assert isinstance(chosen, Plan) and qdframe.solve.plan is plan
    with pytest.raises(dataclasses.FrozenInstanceError):
        chosen.nodes = 3  # type: ignore[misc]


def test_one_rule_sets_the_defaults_of_a_refined_and_a_fixed_solve():
    model = qdframe.load_model("block-stop-stick")
    refined, fixed = plan(model), plan(model, nodes=201)
    assert refined.refining and not fixed.refining
    assert (refined.nodes, refined.scheme, refined.first_scheme) == (21, "radau-iia", "implicit-euler")
    assert (fixed.nodes, fixed.scheme, fixed.first_scheme) == (201, model.default_scheme, model.default_scheme)
    assert refined.budget == refined.direction.certified_max_iter and fixed.budget == 500
    assert refined.options.eps_floor == 1e-12 and fixed.options.eps_floor == fixed.options.eps
    assert refined.from_motion and not fixed.from_motion
    assert plan(model, nodes=201, accuracy=1e-4).refining  # nodes with accuracy: the first mesh of a refinement
    assert refined.describe() == "from 21 points to accuracy 1e-06" and fixed.describe() == "on 201 nodes"


def test_the_solve_runs_its_plan():
    model = qdframe.load_model("block-stop-stick")
    chosen = plan(model, nodes=101, scheme="radau-iia")
    result = qdframe.solve(model, nodes=101, scheme="radau-iia")
    assert result.nodes == chosen.nodes and result.options["scheme"] == chosen.scheme
    assert result.options["max_iter"] == chosen.budget and result.accuracy == chosen.target


@pytest.mark.parametrize("arguments, field", [
    (dict(accuracy=0.0), "accuracy"), (dict(max_nodes=2), "max_nodes"), (dict(certificate="guess"), "certificate"),
    (dict(estimate=False), "estimate"), (dict(nodes=11, mesh=[0.0, 1.0]), "mesh"), (dict(nodes=11, tol=-1.0), "tol"),
])
def test_a_bad_argument_is_refused_by_the_plan_naming_it(arguments, field):
    with pytest.raises(InputError, match=field):
        plan(qdframe.load_model("block-stop-stick"), **arguments)
