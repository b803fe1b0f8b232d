"""Nodes and time to reach a true error, uniform grids against `accuracy=` (`qdframe bench accuracy`).

For every model with an exact solution and every target e:

- adaptive: ``solve(name, accuracy=e)`` (radau-iia from 21 points, refined until its
  error estimate is ≤ e): its nodes, wall time, true error max_k |x_k − x*(t_k)|, error
  estimate, whether the true error is ≤ e, and how far its switch times are from the
  model's known ones (the class attribute `switch_times`, where the model has it);
- uniform: the smallest N on the ladder of K = 20, 40, 80, … intervals (N = K + 1 for
  implicit Euler, 2K + 1 for radau-iia) with ``solve(name, nodes=N, scheme=S,
  estimate=False)`` whose true error is ≤ e, and the wall time of that one solve; the
  ladder stops at `max_nodes` points or when the next solve would pass `budget_s` seconds
  of the ladder's time (one ladder per model and scheme serves every target);
- the ratios nodes and time, uniform radau-iia over adaptive (the same scheme).

Times are `wall_time_s` of the solve (the whole call; the adaptive one includes its error
estimate, the uniform ones have none). Each model is solved once untimed first, so that
no row pays for first-call set-up (imports, caches).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..status import Status
from ..solve.solving import solve
from ..registry import load_model
from ..errors import InputError
from ..progress import bar
from ..registry import available

TARGETS = (1e-4, 1e-6)
SCHEMES = ("radau-iia", "implicit-euler")  # uniform grids: the adaptive solve's scheme first, then the default
FIRST_INTERVALS = 20  # the ladder's coarsest mesh: 20 intervals (21 points for implicit Euler)
MAX_NODES = 100_001  # the ladder's cap on points
BUDGET_S = 60.0  # the ladder's cap on time, per model and scheme
GROWTH = 2.0  # a ladder's next solve is assumed to take this × the last one (twice the points)


@dataclass(frozen=True)
class Uniform:
    """The uniform ladder of one scheme against one target: the first rung whose true error
    is ≤ the target, or, if none is (`nodes` None), the last rung tried."""

    scheme: str
    nodes: int | None  # the smallest N reaching the target; None: not reached
    seconds: float | None  # the wall time of that solve
    error: float | None  # its true error (not reached: the last rung's)
    status: str  # its status
    tried: int  # the largest N solved on the ladder

    @property
    def reached(self) -> bool:
        return self.nodes is not None


@dataclass(frozen=True)
class AccuracyRow:
    """One model at one target: the adaptive solve and the uniform ladders (radau-iia first)."""

    model: str
    target: float
    nodes: int  # adaptive
    seconds: float
    error: float  # true error max |x − x*| over the points
    estimate: float | None  # the solve's error_estimate
    status: str
    switch_offset: float | None  # max distance between found and known switch times (None: none known)
    switches: tuple[float, ...]  # found
    known_switches: tuple[float, ...] | None  # the model's, None where it does not say
    uniform: tuple[Uniform, ...]

    @property
    def met(self) -> bool:
        """The true error is within the target."""
        return self.error <= self.target

    @property
    def estimate_holds(self) -> bool:
        """The true error is within the error estimate."""
        return self.estimate is not None and self.error <= self.estimate

    def ratios(self, scheme: str = SCHEMES[0]) -> tuple[float | None, float | None]:
        """nodes and wall time of the uniform `scheme` over the adaptive solve (None: not reached)."""
        for u in self.uniform:
            if u.scheme == scheme and u.reached:
                return u.nodes / self.nodes, u.seconds / self.seconds
        return None, None


def exact_models() -> list[str]:
    """The registered models with an exact solution for their default data, by name."""
    found = []
    for name in sorted(available("models")):
        model = load_model(name)
        if model.exact_solution(np.linspace(0.0, model.T, 5)) is not None:
            found.append(name)
    return found


def ladder_nodes(scheme: str, max_nodes: int = MAX_NODES) -> list[int]:
    """N for K = 20, 40, 80, … intervals up to `max_nodes` points (radau-iia: 2K + 1)."""
    stages = 2 if scheme == "radau-iia" else 1
    out, intervals = [], FIRST_INTERVALS
    while stages * intervals + 1 <= max_nodes:
        out.append(stages * intervals + 1)
        intervals *= 2
    return out


def run(models: Sequence[str] | None = None, targets: Sequence[float] = TARGETS, schemes: Sequence[str] = SCHEMES,
        max_nodes: int = MAX_NODES, budget_s: float = BUDGET_S, progress: bool = False) -> list[AccuracyRow]:
    """The rows, model by model and target by target (`models` None: :func:`exact_models`);
    `progress`: a bar on stderr (on a terminal)."""
    targets = _targets(targets)
    models = exact_models() if models is None else list(models)
    for name in models:
        model = load_model(name)
        if model.exact_solution(np.linspace(0.0, model.T, 5)) is None:
            raise InputError("--models", "models with an exact solution (" + ", ".join(exact_models()) + ")", name)
    steps = bar(len(models) * (len(targets) + len(schemes)), "bench accuracy", enabled=progress)
    rows: list[AccuracyRow] = []
    for name in models:
        steps.set_postfix_str(f"{name} warm-up")
        solve(name, accuracy=targets[0])  # untimed: first-call set-up
        adaptive = {}
        for target in targets:
            steps.set_postfix_str(f"{name} accuracy={target:g}")
            adaptive[target] = solve(name, accuracy=target)
            steps.update(1)
        ladders = {}
        for scheme in schemes:
            steps.set_postfix_str(f"{name} uniform {scheme}")
            ladders[scheme] = _ladder(name, scheme, targets, max_nodes, budget_s,
                                      lambda n, s=scheme: steps.set_postfix_str(f"{name} {s} N={n}"))
            steps.update(1)
        known = getattr(type(load_model(name)), "switch_times", None)
        known = None if known is None else tuple(float(t) for t in known)
        for target in targets:
            result = adaptive[target]
            found = tuple(float(t) for t in result.switch_times)
            rows.append(AccuracyRow(
                name, target, result.nodes, result.wall_time_s, result.solution_error, result.error_estimate,
                result.status, _distance(found, known), found, known,
                tuple(_first(ladders[scheme], scheme, target) for scheme in schemes)))
    steps.close()
    return rows


def _targets(targets: Sequence[float]) -> tuple[float, ...]:
    values = tuple(targets)
    if not values or not all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0 for v in values):
        raise InputError("--targets", "positive true errors like 1e-4,1e-6", ",".join(map(str, values)))
    return values


def _ladder(name: str, scheme: str, targets: Sequence[float], max_nodes: int, budget_s: float,
            show) -> list[tuple[int, float, float, str]]:
    """(N, wall time, true error, status) up the ladder until every target is reached, or the cap."""
    rungs: list[tuple[int, float, float, str]] = []
    spent = 0.0
    for nodes in ladder_nodes(scheme, max_nodes):
        if rungs and spent + GROWTH * rungs[-1][1] > budget_s:
            break
        show(nodes)
        result = solve(name, nodes=nodes, scheme=scheme, estimate=False)
        rungs.append((nodes, result.wall_time_s, result.solution_error, result.status))
        spent += result.wall_time_s
        if all(any(error <= target for _, _, error, _ in rungs) for target in targets):
            break
    return rungs


def _first(rungs: list[tuple[int, float, float, str]], scheme: str, target: float) -> Uniform:
    for nodes, seconds, error, status in rungs:
        if error <= target:
            return Uniform(scheme, nodes, seconds, error, status, rungs[-1][0])
    if not rungs:  # max_nodes below the first rung
        return Uniform(scheme, None, None, None, "not run", 0)
    nodes, _, error, status = rungs[-1]
    return Uniform(scheme, None, None, error, status, nodes)


def _distance(found: tuple[float, ...], known: tuple[float, ...] | None) -> float | None:
    """The Hausdorff distance of the two sets of times (inf when exactly one is empty)."""
    if known is None:
        return None
    if not found and not known:
        return 0.0
    if not found or not known:
        return math.inf
    a, b = np.asarray(found), np.asarray(known)
    gaps = np.abs(a[:, None] - b[None, :])
    return float(max(gaps.min(axis=1).max(), gaps.min(axis=0).max()))


def table(rows: Sequence[AccuracyRow]) -> str:
    """A Markdown table: the adaptive solve, each uniform ladder, and the ratios against radau-iia."""
    schemes = [u.scheme for u in rows[0].uniform] if rows else list(SCHEMES)
    head = ["model", "target", "adaptive N", "time (s)", "true error", "estimate", "≤ target", "switch offset"]
    for scheme in schemes:
        head += [f"uniform {scheme} N", "time (s)"]
    head += [f"N ratio ({schemes[0]})", f"time ratio ({schemes[0]})"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r.model, f"{r.target:.0e}", str(r.nodes) + ("" if r.status == Status.SOLVED else f" ({r.status})"),
                 f"{r.seconds:.2f}", f"{r.error:.1e}", "—" if r.estimate is None else f"{r.estimate:.1e}",
                 "yes" if r.met else "**no**", _offset(r)]
        for u in r.uniform:
            if u.reached:
                cells += [str(u.nodes) + ("" if u.status in (Status.SOLVED, Status.UNCERTIFIED) else f" ({u.status})"),
                          f"{u.seconds:.2f}"]
            else:
                cells += [f"not reached ({u.tried}, {_error(u.error)})", "—"]
        nodes_ratio, time_ratio = r.ratios(schemes[0])
        if nodes_ratio is None:  # not reached: more than the largest N tried
            cells += [f"> {r.uniform[0].tried / r.nodes:.1f}", "—"]
        else:
            cells += [f"{nodes_ratio:.1f}", f"{time_ratio:.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _offset(row: AccuracyRow) -> str:
    if row.switch_offset is None:
        return "—"
    if math.isinf(row.switch_offset):
        return f"{len(row.switches)} found, {len(row.known_switches or ())} known"
    return "none (none known)" if not row.known_switches else f"{row.switch_offset:.1e}"


def _error(error: float | None) -> str:
    return "no error" if error is None else f"{error:.1e}"
