"""The verdict on a solve: its switch times, its error estimate and its status against the
accuracy target. Under `accuracy` the mesh is refined until the estimate meets it
(:func:`qdframe.solve.adaptive.to_accuracy`); on a fixed grid the estimate is made once
(:func:`qdframe.solve.adaptive.on_fixed_grid`). `solved` stays only where the estimate is within
the target; a solved discrete problem without that is `uncertified` (:mod:`qdframe.status`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from . import adaptive
from . import optimum
from ..descent import checks
from ..descent.multipliers import after
from ..certificates import switches
from .continuation import interpolate
from ..descent.loop import ProgressCallback, descend
from ..functional import Functional
from ..result import SolveResult, VerdictRecord
from .plan import Plan
from .start import MODEL, Starts
from ..status import Status

COMPANION_ITERATIONS = 100  # the budget of the estimate's solve on the bisected grid


def certify_result(functional: Functional, result: SolveResult, plan: Plan, progress: ProgressCallback | None,
                   starts: Starts | None = None) -> tuple[Functional, SolveResult, "Refined"]:
    """The result with its switch times, its error estimate and its status against the
    plan's target: refining, refined until the estimate meets it (:func:`adaptive.to_accuracy`),
    else on its fixed grid (:func:`adaptive.on_fixed_grid`). `solved` stays only where the
    estimate is ≤ target·max(1, max|x|); a discrete solve whose estimate is larger, or that
    has none, is `uncertified`. The plan's direction re-solves on refined meshes, its
    `estimate_direction` solves the bisected grid of a bisection estimate. Every descent
    appends to the history."""
    solver, search, options = plan.direction, plan.line_search, plan.options
    wanted, certificate, max_nodes, scheme = plan.estimate, plan.certificate, plan.max_nodes, plan.scheme
    target = plan.target
    accuracy = target if plan.refining else None
    history, meshes, shrunk_to = result.history, [], []
    companion_solver, companion_search = plan.estimate_direction, plan.estimate_line_search

    def run(target_functional: Functional, previous: SolveResult, own: bool) -> SolveResult:
        """A descent on `target_functional` from `previous` interpolated: the user's solver
        (`own`, counted in the history) or gauss-newton for the estimate's bisected grid."""
        used = history[-1].iteration
        budget = max(options.max_iter - used, 0) if own else COMPANION_ITERATIONS
        stage = dataclasses.replace(options, max_iter=budget)
        start, near = interpolate(target_functional, previous), previous.status == Status.SOLVED
        label, motion = starts.best(target_functional) if starts is not None else (MODEL, None)
        if label != MODEL and target_functional.objective(motion) < target_functional.objective(start):
            start, near = motion, False  # the model's motion sampled here is nearer than the last mesh's solution
        chosen, line = (solver, search) if own else (companion_solver, companion_search)
        first = None
        if optimum.needs_easing(target_functional, start):  # a raised penalty far from its path: at EASE·λ first
            with optimum.eased(target_functional):
                first = descend(target_functional, chosen, line, stage, None, start, near_solution=near)
            if first.status in (Status.SOLVED, Status.STATIONARY):
                start = adaptive.iterate(target_functional, first)
            stage = dataclasses.replace(stage, max_iter=max(budget - first.iterations, 0))
        spent = used + (first.iterations if first is not None else 0)
        shown = None if progress is None or not own else (
            lambda record: progress(dataclasses.replace(record, iteration=record.iteration + spent)))
        out = descend(target_functional, chosen, line, stage, shown, start, near_solution=near)
        if first is not None:
            out = after(first, out)
        if own:
            meshes.append((target_functional.grid.nodes, out.iterations))
            shrunk_to.append((out.descent.eps, out.descent.delta))
            elapsed = history[-1].time_s
            history.extend(dataclasses.replace(r, iteration=r.iteration + used, time_s=r.time_s + elapsed)
                           for r in out.history)
        return out

    own, companion = (lambda f, r: run(f, r, True)), (lambda f, r: run(f, r, False))
    if accuracy is not None:
        outcome = adaptive.to_accuracy(functional, result, own, companion, accuracy, scheme, certificate, max_nodes)
    else:
        outcome = adaptive.on_fixed_grid(functional, result, companion, certificate, wanted, target)
    functional, result, found = outcome.functional, outcome.result, outcome.estimate
    result.history = history
    result.error_estimate = found.value
    result.certificate = found.certificate if found.value is not None else None
    result.accuracy = target
    solved = result.status == Status.SOLVED  # the discrete problem: every pointwise check passes
    result.switch_times = switches.switch_times(functional, adaptive.iterate(functional, result)) if solved \
        else np.zeros(0)
    note = _status(functional, result, found, target, outcome.note, refining=accuracy is not None) if solved \
        else outcome.note
    result.verdict = VerdictRecord(outcome.seconds, *((accuracy, max_nodes) if accuracy is not None else ()))
    if note:
        result.remarks.append(note)
    finer = found.companion if found.companion is not None and found.value is not None else None
    return functional, result, Refined(tuple(meshes), tuple(shrunk_to), finer)


@dataclasses.dataclass(frozen=True)
class Refined:
    """What the verdict's own descents add to the solve's record: (nodes, iterations) of each
    mesh a refinement solved on, the (ε, δ) each of them ended with, and the solve on the bisected
    mesh of the returned trajectory's estimate (a cost's :func:`qdframe.certificates.estimates.cost_estimate`)."""

    meshes: tuple[tuple[int, int], ...] = ()
    shrunk_to: tuple[tuple[float, float], ...] = ()
    finer: SolveResult | None = None  # the solve on the bisected mesh of the returned trajectory's estimate, if any


def _status(functional: Functional, result: SolveResult, found, target: float, note: str, refining: bool) -> str:
    """A solved discrete result's status against the target (`uncertified` where a periodic
    condition closes by tolerance alone, there is no estimate, or it passes the target), its
    switch times polished by a replay that is the solution; the note that says so."""
    bound = adaptive.tolerance(target, result, functional)
    hint = "" if refining else f"; more nodes, or accuracy={target:g}"
    unclosed = checks.closed_by_tolerance(functional, np.asarray(result.x, float))
    if unclosed:
        result.status = Status.UNCERTIFIED
        return _join(note, f"{unclosed}: a longer T, or with T free a lower bound (T_bounds)")
    if found.value is None:
        result.status = Status.UNCERTIFIED
        reason = found.detail or "no error estimate"
        return _join(note, f"the discrete problem is solved on {result.nodes} points, but its error is not "
                           f"certified: {reason}" + hint)
    if found.value > bound:
        result.status = Status.UNCERTIFIED
        return _join(note, f"the discrete problem is solved on {result.nodes} points, but its error estimate "
                           f"{found.value:.1e} ({found.certificate}) exceeds the target {bound:.1e}"
                     + ("" if refining else f": more nodes, or accuracy={target:g}"))
    note = _join(f"error estimate {found.value:.1e} ({found.certificate}) ≤ target {bound:.1e}", note)
    if found.detail:
        note = _join(note, found.detail)
    if found.switch_times is not None:  # certified, and its replay is the solution: that motion's events
        result.switch_times = switches.polish(result.switch_times, found.switch_times, functional.grid.mesh_times)
    return note


def _join(*parts: str) -> str:
    """The non-empty parts of a message, joined by "; "."""
    return "; ".join(part for part in parts if part)
