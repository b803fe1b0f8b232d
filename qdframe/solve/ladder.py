"""The second chances of a solve, as data: an ordered list of stages, each saying when it
applies to an :class:`Attempt` (the model, its plan made concrete, the descents' run) and what
it returns (cvxpy's solving chain is the model). :data:`LADDER` runs before the verdict:

1. :class:`FromTheModel` — the simulated start stopped a Newton-type descent at a local
   minimum of I: the grids again as if the model had no motion;
2. :class:`FromTheLine` — the model's own start did: the grids again from the straight line
   between the given ends;
3. :class:`RaisedPenalty` — a cost whose least value is not 0, solved by the paper's direction:
   rounds of ∫cost + λ·I with λ raised (:mod:`qdframe.solve.optimum`; a Newton-type direction
   finds the optimum within each descent, :mod:`qdframe.descent.multipliers`).

:class:`FreeInputs` runs after the verdict: where the inputs were held and a Newton-type
descent ended `stationary`, the whole solve again with each point's own choice."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from ..descent import multipliers
from ..descent.loop import ProgressCallback
from ..functional import Functional
from ..model import InclusionModel
from ..result import SolveResult
from ..status import Status
from . import optimum
from .grids import Run, Staged, again, run_grids, staged, stalled
from .plan import Plan
from .start import LINE, MODEL, SIMULATED, LineStarts


@dataclass
class Attempt:
    """What a solve has so far: the model, the plan, the plan made concrete (`staged`), the
    descents' run on it, and a cost's rounds (empty without a cost)."""

    model: InclusionModel
    plan: Plan
    staged: Staged
    run: Run
    progress: ProgressCallback | None = None
    rounds: list[optimum.Round] = field(default_factory=list)

    def restaged(self, model: InclusionModel | None = None, simulate: bool | None = None) -> Staged:
        """The plan made concrete again (on another model, or with the simulated start or not)."""
        plan = self.plan if simulate is None else dataclasses.replace(self.plan, simulate_start=simulate)
        return staged(self.model if model is None else model, plan)


class FromTheModel:
    """Where the simulated start stopped at a local minimum of I: the solve again as if the
    model had no motion (the model's own start, its grids). A model with controls is
    simulated under its first controls, whose motion can sit next to a local minimum on a
    coarse grid (paper-7.3 on 11 and 101 points)."""

    def applies(self, attempt: Attempt) -> bool:
        return attempt.run.first_start == SIMULATED and stalled(attempt.staged, attempt.run)

    def apply(self, attempt: Attempt) -> Attempt:
        plan, run = again(attempt.staged, attempt.run, attempt.restaged(simulate=False), MODEL,
                          "the model's own start", attempt.progress)
        return dataclasses.replace(attempt, staged=plan, run=run)


class FromTheLine:
    """Where the grids from the model's start (x ≡ x0, at rest) stopped at a local minimum of
    I: the grids again from the straight line between the given ends. paper-7.3 at N = 11:
    the model's start stops at a local minimum, the line is solved."""

    def applies(self, attempt: Attempt) -> bool:
        return (attempt.run.first_start == MODEL and stalled(attempt.staged, attempt.run)
                and bool(len(attempt.model.end_indices)))

    def apply(self, attempt: Attempt) -> Attempt:
        lined = dataclasses.replace(attempt.staged, starts=LineStarts(attempt.model))
        _, run = again(attempt.staged, attempt.run, lined, LINE, "the straight line between the given ends",
                       attempt.progress)
        return dataclasses.replace(attempt, run=run)


class RaisedPenalty:
    """A cost: the rounds of ∫cost + λ·I with λ raised (:func:`qdframe.solve.optimum.raise_penalty`),
    the last round's plan and run; its history is every round's, counted on."""

    def applies(self, attempt: Attempt) -> bool:
        # where the method of multipliers applies, each descent finds the optimum itself
        functional = attempt.run.functional
        return functional.cost is not None and not multipliers.applies(functional, attempt.staged.solver)

    def apply(self, attempt: Attempt) -> Attempt:
        last = {"plan": attempt.staged, "run": attempt.run}
        history = list(attempt.run.result.history)

        def rerun(model: InclusionModel) -> tuple[Functional, SolveResult]:
            last["plan"] = attempt.restaged(model)
            last["run"] = run_grids(last["plan"], attempt.progress)
            used, elapsed = history[-1].iteration, history[-1].time_s
            history.extend(dataclasses.replace(record, iteration=record.iteration + used, time_s=record.time_s + elapsed)
                           for record in last["run"].result.history)
            return last["run"].functional, last["run"].result

        def target(result: SolveResult) -> float:
            return attempt.plan.target * attempt.model.accuracy_scale(result.x)

        rounds = optimum.raise_penalty(attempt.model, (attempt.run.functional, attempt.run.result), target,
                                       attempt.plan.options.tol, rerun)
        last["run"].result.history = history
        return dataclasses.replace(attempt, staged=last["plan"], run=last["run"], rounds=rounds)


LADDER = (FromTheModel(), FromTheLine(), RaisedPenalty())


class FreeInputs:
    """After the verdict: where the last functional held the inputs and a Newton-type descent
    ended `stationary` there (no held choice meets the problem: one cannot follow a surface
    that moves the state within an interval), the solve again with each point's own choice.
    (A first-order method's stationary or max_iter says nothing of the held choice.)"""

    remark = "with the inputs held the solve ended {status}: each point chose its own (inputs=\"free\")"

    def applies(self, attempt: Attempt, functional: Functional, result: SolveResult) -> bool:
        return (functional.held is not None and result.status == Status.STATIONARY
                and attempt.staged.solver.full_steps)

    def plan(self, attempt: Attempt) -> Plan:
        return dataclasses.replace(attempt.plan, inputs="free")
