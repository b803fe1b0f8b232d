"""The cases of `qdframe bench run`: the suites, the solvers installed and their spellings, and the
plan of a sweep (:func:`plan`: every :class:`Case`, one model, one solver and one setting of its
accuracy knob)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

from ..registry import make_direction
from ..directions.base import DirectionSolver
from ..errors import InputError, QdframeError, UnknownNameError
from ..model import InclusionModel
from ..registry import available, lookup, make_peer
from . import problems


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
