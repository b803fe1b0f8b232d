"""`qdframe bench run`: work-precision sweeps of qdframe's solvers and the peers.

Each run is one :class:`Case`: a model, a solver (a direction and line search, or a peer)
and one setting of that solver's accuracy knob — the grid N, qdframe's ``accuracy=``
target, solve_bvp's ``tol``, nosnoc's finite elements (through N). :func:`run_case` turns
it into one row (a plain dict) in whatever process executes it — this one (``local``) or a
dask worker (``dask``). The driver alone writes the files, after every row:
``results.json`` (every row with its history) and ``results.csv`` (the same rows without
histories), each replaced atomically, so an interrupted sweep loses at most the runs in
flight. ``--resume`` keeps the rows present in both files (keyed by model, direction, line
search, knob) and runs the rest.

Every row is judged by one yardstick, :func:`~.references.judge`: ``error`` is the max over
the run's own time grid of |x − x_ref| against the model's reference (exact where the
problem has one solution, else the true motion replayed from the run's own trajectory),
with ``end_error`` and ``switch_error`` beside it. qdframe's own checks
(``Functional.residuals``: ``residual_error``) are kept as a second opinion.
"""

from __future__ import annotations

import csv
import datetime
import json
import math
import os
import platform
import sys
import time
import typing
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..solve.solving import solve
from ..registry import make_direction, make_line_search
from ..directions.base import Direction, DirectionSolver
from ..errors import InputError, QdframeError, UnknownNameError
from ..functional import Functional
from ..schemes.grid import Grid
from ..model import InclusionModel
from ..progress import bar
from ..registry import available, lookup, make_peer
from ..status import TIME_LIMIT, Status
from . import problems
from .references import SchemeRule, judge

FORMAT = "qdframe-bench-run/3"
KEY_FIELDS = ("model", "direction", "line_search", "knob")
FIELDS = (
    "model", "solver", "direction", "line_search", "knob", "nodes", "status", "found", "iterations", "wall_time_s",
    "setup_time_s", "error", "end_error", "switch_error", "reference_kind", "reference_uncertainty",
    "reference_time_s", "claim_tol", "claim", "objective", "I", "boundary_error", "inclusion_residual",
    "consistency_error", "surface_error", "residual_error", "error_estimate", "certificate", "estimate_time_s",
    "max_iter", "time_limit_s",
    "machine", "load_average", "started_at", "message",
)
# direction preference of the suites: the default, the paper's, then the QP backends
DIRECTION_PREFERENCE = ("gauss-newton", "native", "qpsolvers:daqp", "clarabel", "osqp", "cvxpy")
COMPARED_TARGETS = (1e-3, 1e-6)  # --directions all: accuracy= runs at these (report.TARGETS' errors)
RESIDUAL_TOL = 5e-3  # the paper's accuracy (boundary error ≤ 5e-3, Section 7)
CLAIM_TOL = RESIDUAL_TOL  # a run that reports success promises error ≤ this (an accuracy= run: its target)
ACCURACY_DIRECTION = "gauss-newton"  # accuracy= runs: the default direction, a line of their own
ALL = "all"  # --directions all: every installed direction and every step-QP backend of gauss-newton
STEP_QP_SPELLING = "gauss-newton[qp={}]"  # gauss-newton with a step-QP backend, as a sweep names it
DEFAULT_MAX_ITER = 500  # the default call's row: solve()'s own budget


class MissingDependency(QdframeError):
    """An optional package a requested feature needs is not installed."""


@dataclass(frozen=True)
class Suite:
    """A named sweep. `directions`: how many available directions (None: all);
    `every_line_search`: each direction with every line search, else with its own.
    Each solver sweeps its own accuracy knob: gauss-newton the `grids` and the `accuracy`
    targets, the other directions the `other_grids`, nosnoc the `peer_grids` (N − 1 finite
    elements), solve_bvp the `bvp_tols`."""

    name: str
    models: tuple[str, ...] | None  # None: every registered model
    directions: int | None
    grids: tuple[int, ...]
    max_iter: int
    time_limit_s: float
    every_line_search: bool = False
    accuracy: tuple[float, ...] = ()
    other_grids: tuple[int, ...] | None = None  # None: the grids
    peer_grids: tuple[int, ...] | None = None
    bvp_tols: tuple[float, ...] = ()


SUITES = {  # each suite's models: the catalogue's problems with the suite's tag (qdframe.bench.problems)
    "quick": Suite("quick", problems.tagged("quick"), 2,
                   (11, 41, 161), max_iter=100, time_limit_s=30.0, accuracy=(1e-3,), other_grids=(11, 41),
                   peer_grids=(11, 41), bvp_tols=(1e-3, 1e-6)),
    "standard": Suite("standard", problems.tagged("standard"), 2, (11, 101, 1001, 10001, 100001), max_iter=500,
                      time_limit_s=30.0, accuracy=(1e-2, 1e-3, 1e-4, 1e-6, 1e-8), other_grids=(11, 101),
                      peer_grids=(11, 51, 101, 201), bvp_tols=(1e-2, 1e-3, 1e-4, 1e-6, 1e-8)),
    "full": Suite("full", problems.tagged("standard"), None, (11, 101, 1001, 10001, 100001), max_iter=500, time_limit_s=600.0,
                  every_line_search=True, accuracy=(1e-2, 1e-3, 1e-4, 1e-6, 1e-8), other_grids=(11, 101, 1001),
                  peer_grids=(11, 51, 101, 201), bvp_tols=(1e-2, 1e-3, 1e-4, 1e-6, 1e-8)),
}


@dataclass(frozen=True)
class Case:
    """One run. `peer` names the other tool (a registered :class:`~.peer.Peer`; then
    `direction` is the peer's name and `line_search` its inner solver), None for qdframe itself. The knob: `nodes` (qdframe's
    grid, nosnoc's N − 1 finite elements), `accuracy` (qdframe's ``accuracy=``, no grid
    given) or `tol` (solve_bvp's)."""

    model: str
    direction: str
    line_search: str
    nodes: int | None
    max_iter: int
    time_limit_s: float | None
    peer: str | None = None
    accuracy: float | None = None
    tol: float | None = None
    default: bool = False  # qdframe.solve(model) as a user calls it (its default target, 1e-6)

    @property
    def knob(self) -> str:
        if self.default:
            return "default"
        if self.accuracy is not None:
            return f"accuracy={self.accuracy:g}"
        if self.tol is not None:
            return f"tol={self.tol:g}"
        return f"N={self.nodes}"

    @property
    def solver(self) -> str:
        """The line of a work-precision diagram this run belongs to."""
        if self.peer is not None:
            return make_peer(self.peer).line
        label = f"{self.direction} / {self.line_search}"
        if self.default:
            return "qdframe.solve(model)"
        return label + " (accuracy=)" if self.accuracy is not None else label

    @property
    def key(self) -> tuple[str, str, str, str]:
        return (self.model, self.direction, self.line_search, self.knob)

    @property
    def label(self) -> str:
        return f"{self.model} {self.solver} {self.knob}"


@dataclass
class Plan:
    """The cases of a sweep, the directions left out (with why) and the settings."""

    cases: list[Case]
    skipped: dict[str, str] = field(default_factory=dict)
    settings: dict = field(default_factory=dict)


# ------------------------------------------------------------------------- planning


def model_names() -> list[str]:
    """Every model a sweep can run: the registered ones."""
    return sorted(available("models"))


def resolve_model(name: str) -> InclusionModel:
    """A registered model instance by name."""
    if name in available("models"):
        return lookup("models", name).obj()
    raise UnknownNameError("model", name, model_names())


def installed_directions(
    preference: Sequence[str] = DIRECTION_PREFERENCE, qpsolvers_all: bool = False, limit: int | None = None
):
    """Names of the registered directions that can be built here, in preference order (the
    first `limit` of them), and {name: why} for those that cannot. ``qpsolvers:`` expands to
    qpsolvers:daqp (or, with `qpsolvers_all`, to every solver qpsolvers finds installed)."""
    names = []
    for name in sorted(available("directions")):
        if name.endswith(":"):
            names += _expand_prefix(name, qpsolvers_all)
        else:
            names.append(name)
    rank = {name: i for i, name in enumerate(preference)}
    names.sort(key=lambda n: (rank.get(n, len(rank)), n))
    usable, skipped = [], {}
    for name in names:
        if limit is not None and len(usable) >= limit:
            break
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                make_direction(name)
        except Exception as exc:  # a missing package (BackendError) or a broken plugin
            skipped[name] = str(exc) if isinstance(exc, QdframeError) else f"{type(exc).__name__}: {exc}"
            continue
        usable.append(name)
    return usable, skipped


def every_direction() -> tuple[list[str], dict[str, str]]:
    """`--directions all`: every installed direction (qpsolvers: each offered solver) and
    gauss-newton with each installed step-QP backend (``gauss-newton[qp=NAME]``; the
    default active-set is gauss-newton itself), and {name: why} for those that cannot run."""
    from ..directions.step_qp import step_qp_names

    directions, skipped = installed_directions(qpsolvers_all=True)
    for name in step_qp_names():
        if name == "active-set":
            continue
        try:
            bench_direction(STEP_QP_SPELLING.format(name))
        except Exception as exc:  # noqa: BLE001 - a missing package: reported, not run
            skipped[STEP_QP_SPELLING.format(name)] = str(exc)
            continue
        directions.append(STEP_QP_SPELLING.format(name))
    return directions, skipped


def bench_direction(name: str) -> DirectionSolver:
    """A direction by a sweep's name: a registered one, or ``NAME[key=value]`` with an option
    (``gauss-newton[qp=osqp]``; a bad key or value is an InputError)."""
    from ..directions.base import with_options

    base, bracket, rest = name.partition("[")
    if not bracket:
        return make_direction(name)
    if not rest.endswith("]") or "=" not in rest:
        raise InputError("--directions", "NAME or NAME[key=value], e.g. gauss-newton[qp=osqp]", name)
    options = dict(item.split("=", 1) for item in rest[:-1].split(",") if "=" in item)
    return with_options(make_direction(base), options)


def _base_direction(name: str) -> str:
    return name.partition("[")[0]


def _expand_prefix(prefix: str, every: bool) -> list[str]:
    if prefix != "qpsolvers:":
        return []
    try:
        import qpsolvers
    except ImportError:
        return ["qpsolvers:daqp"]  # fails to build: reported as skipped with the pip command
    solvers = sorted(qpsolvers.available_solvers)
    if every:
        return [prefix + s for s in solvers]
    return [prefix + ("daqp" if "daqp" in solvers else solvers[0])] if solvers else []


def plan(
    suite: str = "quick",
    models: Sequence[str] | None = None,
    directions: Sequence[str] | None = None,
    line_searches: Sequence[str] | None = None,
    nodes: Sequence[int] | None = None,
    peers: bool = False,
    max_iter: int | None = None,
    time_limit_s: float | None = None,
    accuracy: Sequence[float] | None = None,
    bvp_tols: Sequence[float] | None = None,
) -> Plan:
    """The cases of a sweep: the suite's choices, each overridden by an explicit list
    (`nodes` sets every solver's grids, peers' too; `accuracy` and `bvp_tols` the other knobs)."""
    if suite not in SUITES:
        raise InputError("--suite", f"one of: {', '.join(SUITES)}", suite)
    spec = SUITES[suite]
    known = model_names()
    models = list(models) if models is not None else [m for m in spec.models or known if m in known]
    for name in models:
        if name not in known:
            raise UnknownNameError("model", name, known)
    skipped: dict[str, str] = {}
    every = directions is not None and list(directions) == [ALL]
    if every:
        directions, skipped = every_direction()
    elif directions is None:
        directions, skipped = installed_directions(qpsolvers_all=spec.directions is None, limit=spec.directions)
    else:
        for name in directions:
            lookup("directions", _base_direction(name))  # an unknown name is a usage error; an uninstalled one a failed row
            if name != _base_direction(name):
                bench_direction(name)  # options: a bad key or value is a usage error, before any run
    searches = list(available("line_searches"))
    for name in line_searches or ():
        lookup("line_searches", name)
    grids = tuple(nodes) if nodes is not None else spec.grids
    if any(isinstance(n, bool) or int(n) != n or n < 2 for n in grids):
        raise InputError("--nodes", "node counts ≥ 2 like 11,51", ",".join(map(str, grids)))
    other_grids = grids if nodes is not None or spec.other_grids is None else spec.other_grids
    peer_grids = grids if nodes is not None or spec.peer_grids is None else spec.peer_grids
    targets = tuple(accuracy) if accuracy is not None else spec.accuracy
    if every and accuracy is None:  # every method to the certified answer, at each error the report times
        targets = tuple(sorted(set(targets) | set(COMPARED_TARGETS), reverse=True))
    tols = tuple(bvp_tols) if bvp_tols is not None else spec.bvp_tols
    default_budget = DEFAULT_MAX_ITER if max_iter is None else max_iter  # the default call's row: solve()'s own
    max_iter = spec.max_iter if max_iter is None else max_iter
    time_limit_s = spec.time_limit_s if time_limit_s is None else time_limit_s
    cases = []
    for model in models:
        for direction in directions:
            if line_searches:
                pairs = list(line_searches)
            elif spec.every_line_search:
                pairs = sorted(searches)
            else:
                pairs = [_default_line_search(direction)]
            base = _base_direction(direction)  # gauss-newton[qp=osqp]: gauss-newton's knobs
            ladder = grids if base == ACCURACY_DIRECTION else other_grids
            if every and direction not in DIRECTION_PREFERENCE[:2]:  # the backends: their certified runs alone
                ladder = ()
            for search in pairs:
                cases += [Case(model, direction, search, int(n), max_iter, time_limit_s) for n in ladder]
            if base == ACCURACY_DIRECTION or every:
                search = _default_line_search(direction)
                cases += [Case(model, direction, search, None, max_iter, time_limit_s, accuracy=float(e))
                          for e in targets]
                if targets and direction == ACCURACY_DIRECTION:  # the default call is an accuracy= run of its own:
                    # `--accuracy none` drops it too
                    cases.append(Case(model, direction, search, None, default_budget, time_limit_s, default=True))
    if peers:
        cases += _peer_cases(models, peer_grids, tols, max_iter, time_limit_s)
    settings = {
        "suite": suite,
        "models": list(models),
        "directions": list(directions),
        "line_searches": list(line_searches) if line_searches else ("every" if spec.every_line_search else "own"),
        "nodes": list(grids),
        "other_nodes": list(other_grids),
        "peer_nodes": list(peer_grids),
        "accuracy": list(targets),
        "bvp_tols": list(tols),
        "peers": bool(peers),
        "max_iter": max_iter,
        "time_limit_s": time_limit_s,
        "residual_tol": RESIDUAL_TOL,
        "claim_tol": CLAIM_TOL,
    }
    return Plan(cases, skipped, settings)


def _peer_cases(models: Sequence[str], grids: Sequence[int], tols: Sequence[float], max_iter: int,
                time_limit_s: float) -> list[Case]:
    """Each registered peer's runs on the models it states: its grids or its tolerances."""
    cases = []
    for model in models:
        instance = resolve_model(model)
        for name in sorted(available("peers")):
            peer = make_peer(name)
            if not peer.states(instance):
                continue
            if peer.knob == "nodes":
                cases += [Case(model, name, peer.inner, int(n), max_iter, time_limit_s, peer=name) for n in grids]
            else:
                cases += [Case(model, name, peer.inner, None, max_iter, time_limit_s, peer=name, tol=float(e))
                          for e in tols]
    return cases


def _default_line_search(direction: str) -> str:
    return lookup("directions", _base_direction(direction)).obj.default_line_search


# ------------------------------------------------------------------------- one run


def machine() -> str:
    """This machine in one line: host, CPU model, logical CPUs, OS, Python, NumPy."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as handle:
            for line in handle:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return (
        f"{platform.node()}; {cpu}; {os.cpu_count()} logical CPUs; {platform.system()} {platform.release()}; "
        f"Python {platform.python_version()}; NumPy {np.__version__}"
    )


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
               machine=machine(), load_average=_load_average(), started_at=_now(), setup_time_s=0.0,
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
    return _finite(row)


def claim(row: dict) -> str:
    """How a run's own success report compares with its reference error (qpbenchmark's
    "correct"): "confirmed" (solved, error ≤ claim_tol), "false" (solved, error > claim_tol
    or unknown), "missed" (not solved, error ≤ claim_tol), "none" (neither)."""
    error, tol = row.get("error"), row.get("claim_tol")
    within = error is not None and tol is not None and error <= tol
    if row.get("status") == Status.SOLVED:
        return "confirmed" if within else "false"
    return "missed" if within else "none"


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


def _finite(value):
    """Non-finite floats to None (JSON has no NaN), NumPy scalars to Python ones."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def _load_average() -> float | None:
    try:
        return round(os.getloadavg()[0], 2)
    except (OSError, AttributeError):
        return None


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


# ------------------------------------------------------------------------- the files


def row_key(row: dict) -> tuple[str, str, str, str]:
    return (str(row["model"]), str(row["direction"]), str(row["line_search"]), str(row["knob"]))


class ResultStore:
    """results.json and results.csv in `out`, rewritten (atomically) after every row."""

    def __init__(self, out: str | Path, resume: bool = False) -> None:
        self.out = Path(out)
        self.json_path = self.out / "results.json"
        self.csv_path = self.out / "results.csv"
        self.rows: dict[tuple, dict] = {}
        self.meta: dict = {}
        self.dropped: list[tuple] = []  # keys found in only one of the two files (rerun)
        if self.out.exists() and not self.out.is_dir():
            raise InputError("--out", "a directory (it is created if missing)", str(out))
        existing = self.json_path.exists() or self.csv_path.exists()
        if existing and not resume:
            raise InputError("--out", f"a directory without results, or --resume to continue the ones in {out}", str(out))
        self.out.mkdir(parents=True, exist_ok=True)
        if resume and existing:
            self._load()

    def _load(self) -> None:
        from_json: dict[tuple, dict] = {}
        if self.json_path.exists():
            try:
                data = json.loads(self.json_path.read_text())
                self.meta = {k: v for k, v in data.items() if k != "rows"}
                from_json = {row_key(r): r for r in data.get("rows", [])}
            except (ValueError, KeyError, TypeError) as exc:
                warnings.warn(f"{self.json_path} is unreadable ({exc}); resuming from {self.csv_path.name} alone")
                from_json = {}
        from_csv = {row_key(r): r for r in read_csv(self.csv_path)} if self.csv_path.exists() else {}
        if not from_json:
            for row in from_csv.values():
                row.setdefault("history", {"iteration": [], "objective": [], "I": [], "time_s": []})
            self.rows = from_csv
        elif not from_csv:
            self.rows = from_json
        else:
            self.rows = {k: r for k, r in from_json.items() if k in from_csv}
            self.dropped = sorted(set(from_json) ^ set(from_csv), key=str)

    def done(self) -> set[tuple]:
        return set(self.rows)

    def add(self, row: dict, order: Sequence[tuple] = ()) -> None:
        self.rows[row_key(row)] = row
        self.write(order)

    def ordered(self, order: Sequence[tuple] = ()) -> list[dict]:
        """Rows in the sweep's order, then any others in the order they were recorded."""
        planned = [self.rows[k] for k in order if k in self.rows]
        seen = set(order)
        return planned + [r for k, r in self.rows.items() if k not in seen]

    def write(self, order: Sequence[tuple] = ()) -> None:
        rows = self.ordered(order)
        document = {**self.meta, "format": FORMAT, "updated_at": _now(), "rows": rows}
        _atomic(self.json_path, json.dumps(_finite(document), indent=1, allow_nan=False) + "\n")
        _atomic(self.csv_path, _csv_text(rows))


def _csv_text(rows: Iterable[dict]) -> str:
    import io

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=FIELDS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _csv_cell(row.get(k)) for k in FIELDS})
    return buffer.getvalue()


def _csv_cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


INT_FIELDS = {"nodes", "iterations", "max_iter"}
TEXT_FIELDS = {"model", "solver", "direction", "line_search", "knob", "status", "reference_kind", "claim", "certificate",
               "machine", "started_at", "message"}


def read_csv(path: str | Path) -> list[dict]:
    """The rows of a results.csv, with numbers parsed back (empty cells are None)."""
    rows = []
    with open(path, newline="", encoding="utf-8") as handle:
        for raw in csv.DictReader(handle):
            row = {}
            for name, text in raw.items():
                if name is None:
                    continue
                if text in ("", None):
                    row[name] = None
                elif name in TEXT_FIELDS:
                    row[name] = text
                elif name == "found":
                    row[name] = text == "true"
                elif name in INT_FIELDS:
                    row[name] = int(float(text))
                else:
                    row[name] = float(text)
            rows.append(row)
    return rows


def _atomic(path: Path, text: str) -> None:
    temporary = path.with_name(path.name + ".tmp")
    with open(temporary, "w", encoding="utf-8") as handle:
        handle.write(text)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(temporary, path)


# ------------------------------------------------------------------------- executors


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


def _dask():
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

    distributed = _dask()
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


# ------------------------------------------------------------------------- the sweep


@dataclass
class SweepOutcome:
    """What a sweep did: the rows now on file, how many it ran and how many it skipped."""

    rows: list[dict]
    ran: int
    resumed: int
    plan: Plan
    seconds: float
    dropped: list = field(default_factory=list)
    meta: dict = field(default_factory=dict)


def run_sweep(
    sweep: Plan,
    out: str | Path,
    resume: bool = False,
    executor: str = "local",
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[str], None] | None = None,
    command: str | None = None,
) -> SweepOutcome:
    """Run the plan's cases not yet in `out` and record each row as it arrives."""
    if executor == "dask":
        _dask()  # fail before any work when dask is missing
    say = progress or (lambda text: None)
    store = ResultStore(out, resume=resume)
    done = store.done()
    pending = [case for case in sweep.cases if case.key not in done]
    order = [case.key for case in sweep.cases]
    store.meta.update({
        "settings": sweep.settings,
        "skipped_directions": sweep.skipped,
        "executor": executor if executor == "local" else f"dask ({scheduler or 'LocalCluster'})",
        "driver_machine": machine(),
        "qdframe_version": _version(),
        "command": command or store.meta.get("command"),
    })
    commit = source_commit()
    store.meta["commits"] = list(dict.fromkeys([*store.meta.get("commits", []), commit])) if commit else \
        store.meta.get("commits", [])
    store.meta.setdefault("started_at", _now())
    resumed = len(sweep.cases) - len(pending)
    if resumed:
        say(f"resuming: {resumed} of {len(sweep.cases)} runs already in {out}")
    for key in store.dropped:
        say(f"resume: {'/'.join(map(str, key))} was in only one of results.json and results.csv: run again")
    start = time.perf_counter()
    count = [0]
    runs = bar(len(pending), "bench run", enabled=progress is not None)

    def record(row: dict) -> None:
        store.add(row, order)
        count[0] += 1
        error = row.get("error")
        line = (f"[{count[0]}/{len(pending)}] {row['model']} {row['solver']} {row['knob']}: "
                f"{row['status']}, {'—' if row.get('iterations') is None else row['iterations']} it, "
                f"{_fmt_seconds(row.get('wall_time_s'))}, "
                f"error {'—' if error is None else f'{error:.1e}'}")
        if runs.disable:
            say(line)
        else:
            runs.write(line, file=sys.stderr)
            runs.update(1)

    with runs:
        execute(pending, record, executor=executor, scheduler=scheduler, workers=workers)
    store.write(order)  # also when every run was already there: the settings of this call
    meta = {**store.meta, "updated_at": _now()}
    return SweepOutcome(store.ordered(order), count[0], resumed, sweep, time.perf_counter() - start, store.dropped, meta)


def _fmt_seconds(value) -> str:
    return "— s" if value is None else f"{value:.2f} s"


def _version() -> str:
    from .. import __version__

    return __version__


def source_commit() -> str | None:
    """The git commit of the qdframe source that runs (short hash, "+changes" when the package's
    files differ from it), or None outside a git checkout."""
    import subprocess

    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                              text=True, timeout=10, check=True).stdout.strip()
        changed = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", "qdframe", "plugins"],
                                 capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{head}+changes" if changed else head or None
