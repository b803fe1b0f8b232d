"""The execution of `qdframe bench run`'s cases: :func:`run_case` turns a :class:`~.cases.Case`
into one row (a plain dict), judged by :func:`~.references.judge`, in whatever process runs it —
this one (``local``) or a dask worker (``dask``, :func:`execute`)."""

from __future__ import annotations

import math
import os
import time
import typing
import warnings
from collections.abc import Callable, Sequence

import numpy as np

from ..solve.solving import solve
from ..registry import make_line_search
from ..directions.base import Direction, DirectionSolver
from ..errors import InputError
from ..functional import Functional
from ..schemes.grid import Grid
from ..model import InclusionModel
from ..registry import lookup, make_peer
from ..status import TIME_LIMIT, Status
from .references import SchemeRule, judge
from .cases import CLAIM_TOL, Case, MissingDependency, bench_direction, resolve_model
from .storage import FIELDS, claim, finite, machine, now


class _Deadline(DirectionSolver):
    """Wraps a direction: past `seconds` after the solve starts it reports "stationary"
    with a zero step, which ends the descent; `expired` then says the limit stopped it."""

    def __init__(self, inner: DirectionSolver, seconds: float) -> None:
        self.inner = inner
        self.seconds = seconds
        # the inner solver's class settings (name, line search, continuation ladder: coarsest_nodes,
        # ladder_steps, …), which solve reads from the direction it is given
        for setting in typing.get_type_hints(DirectionSolver, include_extras=False):
            if hasattr(inner, setting):
                setattr(self, setting, getattr(inner, setting))
        self.label = getattr(inner, "label", inner.name)
        self.expired = False
        self._deadline = math.inf

    def start(self, functional: Functional) -> None:
        """Called once per grid: the clock starts with the first (the limit covers all grids)."""
        self.inner.start(functional)
        if math.isinf(self._deadline):
            self.expired = False
            self._deadline = time.perf_counter() + self.seconds

    def compute(self, functional: Functional, xi: np.ndarray, delta: float) -> Direction:
        if time.perf_counter() > self._deadline:
            self.expired = True
            return Direction(np.zeros_like(xi), np.zeros(xi.shape[0]), 0.0, stationary=True)
        return self.inner.compute(functional, xi, delta)


def run_case(case: Case) -> dict:
    """Run one case and return its row (never raises: a failure is a row with status failed)."""
    row = {name: None for name in FIELDS}
    row.update(model=case.model, solver=case.solver, direction=case.direction, line_search=case.line_search,
               knob=case.knob, nodes=case.nodes, max_iter=case.max_iter, time_limit_s=case.time_limit_s,
               machine=machine(), load_average=_load_average(), started_at=now(), setup_time_s=0.0,
               claim_tol=case.accuracy if case.accuracy is not None else CLAIM_TOL)
    history: dict[str, list] = {"iteration": [], "objective": [], "I": [], "time_s": []}
    clock = time.perf_counter()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            if case.peer is None:
                _run_qdframe(case, row, history)
            else:
                _run_peer(case, row, history)
        notes = sorted({f"{w.category.__name__}: {w.message}" for w in caught if not _ignorable(w)})
        if notes:
            row["message"] = "; ".join(filter(None, [row["message"], f"{len(notes)} warning(s), first: {notes[0][:200]}"]))
    except Exception as exc:  # a failing run is a result, not an abort
        row.update(status=Status.FAILED, message=f"{type(exc).__name__}: {exc}", wall_time_s=time.perf_counter() - clock)
    row["found"] = row["status"] == Status.SOLVED
    row["claim"] = claim(row)
    row["history"] = history
    return finite(row)


def _ignorable(warning) -> bool:
    return issubclass(warning.category, (DeprecationWarning, PendingDeprecationWarning, ResourceWarning))


def _run_qdframe(case: Case, row: dict, history: dict) -> None:
    model = resolve_model(case.model)
    solver = bench_direction(case.direction)
    timed = _Deadline(solver, case.time_limit_s) if case.time_limit_s else solver
    if case.default:
        result = solve(model, direction=timed, max_iter=case.max_iter)
    else:
        result = solve(model, nodes=case.nodes, direction=timed, line_search=make_line_search(case.line_search),
                       accuracy=case.accuracy, max_iter=case.max_iter)
    # a `solved` result promises its own target: accuracy·max(1, max|x|)
    row["claim_tol"] = result.accuracy * max(1.0, float(np.max(np.abs(result.x))))
    status, message = result.status, result.message
    if isinstance(timed, _Deadline) and timed.expired:
        status = TIME_LIMIT
        message = f"time limit {case.time_limit_s:g} s reached after {result.iterations} iterations"
    row.update(status=status, message=message, iterations=result.iterations, wall_time_s=result.wall_time_s,
               nodes=result.nodes, objective=result.objective, I=result.I, boundary_error=result.boundary_error,
               inclusion_residual=result.inclusion_residual, consistency_error=result.consistency_error,
               surface_error=result.surface_error, error_estimate=result.error_estimate,
               estimate_time_s=result.options.get("estimate_time_s"), certificate=result.certificate)
    for record in result.history:
        for name in history:
            history[name].append(getattr(record, name))
    _residual_error(row)
    _judge(row, model, result.t, result.x, result.z, result.u, switch_times=result.switch_times,
           velocity=scheme_velocity(result), selections=result.selections)


def scheme_velocity(result) -> SchemeRule:
    """The rule a result's scheme makes of values at its points (:meth:`~qdframe.schemes.base.Scheme.velocity`),
    for replaying its input: it may jump at the mesh points."""
    scheme = lookup("schemes", result.options["scheme"]).obj()
    t = np.asarray(result.t, float)
    return SchemeRule(scheme, t, np.arange(0, t.size, scheme.stages))


def _run_peer(case: Case, row: dict, history: dict) -> None:
    model = resolve_model(case.model)
    runner = make_peer(case.peer)
    reason = runner.unavailable()
    if reason is not None:  # not usable here: a failed row that says why (and how to install it)
        row.update(status=Status.FAILED, message=reason)
        return
    peer = runner.run(model, case.nodes if runner.knob == "nodes" else case.tol)
    row.update(status=peer.status, message=peer.message, iterations=peer.iterations,
               wall_time_s=peer.wall_time_s, setup_time_s=peer.setup_time_s)
    if case.time_limit_s and peer.wall_time_s > case.time_limit_s:  # a peer is not interrupted: judged as if it were
        row.update(status=TIME_LIMIT, message=f"time limit {case.time_limit_s:g} s passed ({peer.status} after "
                                                f"{peer.wall_time_s:.1f} s); {peer.message}")
    if peer.x is None:
        return
    t = peer.t if peer.t is not None else Grid(model.T, case.nodes).t
    row["nodes"] = int(t.size)
    if np.all(np.diff(t) > 0):  # qdframe's checks need a grid; the peer's own mesh is one
        functional = Functional(model, Grid.from_mesh(t) if peer.t is not None else Grid(model.T, t.size),
                                signs="band")  # Filippov's set, no selections to choose
        xi = functional.pack(peer.x, peer.z)
        terms, residuals = functional.terms(xi), functional.residuals(xi)
        row.update(objective=terms.objective, I=terms.I, boundary_error=residuals.boundary_error,
                   inclusion_residual=residuals.inclusion_residual, consistency_error=residuals.consistency_error,
                   surface_error=residuals.surface_error)
        _residual_error(row)
    for record in peer.history:
        for name in history:
            history[name].append(record[name])
    _judge(row, model, t, peer.x, peer.z, None, inputs=peer.inputs)


def _residual_error(row: dict) -> None:
    parts = [row["boundary_error"], row["inclusion_residual"], row["consistency_error"], row["surface_error"] or 0.0]
    row["residual_error"] = float(max(parts))


def _judge(row: dict, model: InclusionModel, t, x, z, u, switch_times=None, inputs=None, velocity=None,
           selections=None) -> None:
    """The row's error against the model's reference (:func:`~.references.judge`)."""
    try:
        verdict = judge(model, t, x, z, u, switch_times=switch_times, inputs=inputs, velocity=velocity,
                        selections=selections)
    except Exception as exc:  # a reference that cannot be made leaves the error unknown, and says why
        row["message"] = "; ".join(filter(None, [row["message"], f"no reference error: {type(exc).__name__}: {exc}"]))
        return
    row.update(error=verdict.error, end_error=verdict.end_error, switch_error=verdict.switch_error,
               reference_kind=verdict.kind, reference_uncertainty=verdict.uncertainty,
               reference_time_s=verdict.seconds)


def _load_average() -> float | None:
    try:
        return round(os.getloadavg()[0], 2)
    except (OSError, AttributeError):
        return None


def execute(
    cases: Sequence[Case],
    on_row: Callable[[dict], None],
    executor: str = "local",
    scheduler: str | None = None,
    workers: int | None = None,
) -> None:
    """Run `cases`, calling `on_row` in this process with each row as it completes."""
    if executor == "local":
        for case in cases:
            on_row(run_case(case))
        return
    if executor != "dask":
        raise InputError("--executor", "local or dask", executor)
    _execute_dask(cases, on_row, scheduler, workers)


def dask_module():
    try:
        import distributed
    except ImportError as exc:
        raise MissingDependency(
            f"--executor dask needs dask.distributed: pip install 'qdframe[dask]' (or pip install 'dask[distributed]')"
            f" ({type(exc).__name__}: {exc})"
        ) from exc
    return distributed


def _execute_dask(cases, on_row, scheduler, workers) -> None:
    import logging

    distributed = dask_module()
    cluster = None
    if scheduler:
        try:
            client = distributed.Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as exc:
            raise InputError("--scheduler", "the address of a running dask scheduler, like tcp://host:8786",
                             f"{scheduler} ({type(exc).__name__}: {exc})") from exc
    else:
        cluster = distributed.LocalCluster(
            n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
            dashboard_address=None, silence_logs=logging.ERROR,
        )
        client = distributed.Client(cluster)
    try:
        futures = {client.submit(run_case, case, key=f"qdframe-bench-{i}-{case.label}", pure=False): case
                   for i, case in enumerate(cases)}
        for future in distributed.as_completed(futures):
            case = futures[future]
            try:
                row = future.result()
            except Exception as exc:  # the worker died or the task could not run
                row = {name: None for name in FIELDS}
                row.update(model=case.model, solver=case.solver, direction=case.direction, line_search=case.line_search,
                           knob=case.knob, nodes=case.nodes, status=Status.FAILED, found=False, claim="none",
                           max_iter=case.max_iter,
                           time_limit_s=case.time_limit_s, message=f"dask: {type(exc).__name__}: {exc}",
                           history={"iteration": [], "objective": [], "I": [], "time_s": []})
            on_row(row)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
