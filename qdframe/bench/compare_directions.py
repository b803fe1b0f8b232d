"""`qdframe bench directions`: speed and accuracy of the direction backends.

Instances (each a batch of min-norm QPs exactly as a direction solves them):

* ``paper-7.1`` and ``paper-7.2``: the batches of the first `iterations` iterations of a
  native descent (golden line search, the paper's δ) on N nodes, recorded by a
  :class:`~qdframe.directions.native.NativeDirection` subclass whose ``min_norm`` keeps
  what ``MinNormDirection.from_quasidifferential`` passes it;
* degenerate batches of N rows (G = 2 groups of m = 3 generators in R^4, some masked):
  duplicate generators, collinear generators, the origin as the center and a generator
  (so the minimum-norm point is 0), and random rows scaled by 1e-8 and by 1e8.

Every installed backend — each registered `MinNormDirection`, with ``qpsolvers:`` expanded
to every supported solver qpsolvers finds installed — solves every instance once untimed (building
its solvers) and then `repeat` timed passes over all instances in order (so warm starts
come from the previous, different, instance of the same shape, as in a descent). The
reference is the native solver (exact). Reported per backend: the median wall time of one
``min_norm`` call (one direction's QPs), the largest deviation max_b ‖p_b − p*_b‖ / s_b over
all rows of all successful calls, s_b the row's largest absolute entry, and the number
of calls that failed (BackendError or any exception).
"""

from __future__ import annotations

import json
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..descent.loop import DescentOptions, descend
from ..registry import load_model, make_line_search
from ..directions.base import MinNormDirection
from ..directions.native import NativeDirection
from ..errors import BackendError, QdframeError
from ..functional import Functional
from ..schemes.grid import Grid
from ..registry import available
from . import problems

MODELS = problems.tagged("directions")  # the paper's examples 7.1 and 7.2


@dataclass(frozen=True)
class Instance:
    """One batch of min-norm QPs: center (B, d), generators (B, G, m, d), mask (B, G, m)."""

    label: str
    group: str  # "paper-7.1", "paper-7.2" or "degenerate"
    center: np.ndarray
    generators: np.ndarray
    mask: np.ndarray

    @property
    def rows(self) -> int:
        return len(self.center)


@dataclass(frozen=True)
class _Recorder(NativeDirection):
    """The native direction, keeping every batch it solves."""

    batches: list = field(default_factory=list, compare=False)

    def min_norm(self, center: np.ndarray, generators: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.batches.append((center.copy(), generators.copy(), mask.copy()))
        return super().min_norm(center, generators, mask)


def paper_instances(nodes: int, iterations: int = 4) -> list[Instance]:
    """The min-norm batches of the first iterations of native descents on the paper examples."""
    instances = []
    for name in MODELS:
        model = load_model(name)
        recorder = _Recorder()
        descend(Functional(model, Grid(model.T, nodes)), recorder, make_line_search("golden"), DescentOptions(max_iter=iterations))
        for k, (center, generators, mask) in enumerate(recorder.batches):
            instances.append(Instance(f"{name} iteration {k + 1}", name, center, generators, mask))
    return instances


def degenerate_instances(rows: int, seed: int = 0) -> list[Instance]:
    """Batches of `rows` rows with duplicate, collinear, origin and badly scaled generators."""
    rng = np.random.default_rng(seed)
    groups, width, dim = 2, 3, 4

    def random_mask() -> np.ndarray:
        mask = rng.random((rows, groups, width)) < 0.75
        mask[:, :, 0] = True
        return mask

    def base() -> tuple[np.ndarray, np.ndarray]:
        return rng.normal(size=(rows, dim)), rng.normal(size=(rows, groups, width, dim))

    out = []
    center, generators = base()
    generators[:, :, 1] = generators[:, :, 0]  # duplicates
    generators[:, 1, 2] = generators[:, 1, 0]
    out.append(Instance("degenerate: duplicate generators", "degenerate", center, generators, random_mask()))
    center, generators = base()
    t = rng.normal(size=(rows, groups, width, 1))
    generators = generators[:, :, :1] + t * rng.normal(size=(rows, groups, 1, dim))  # on one line per group
    out.append(Instance("degenerate: collinear generators", "degenerate", center, generators, random_mask()))
    center, generators = base()
    center[:] = 0.0
    generators[:, :, 0] = 0.0  # the origin is in the polytope: the point is 0
    out.append(Instance("degenerate: origin", "degenerate", center, generators, random_mask()))
    for scale in (1e-8, 1e8):
        center, generators = base()
        out.append(Instance(f"degenerate: scale {scale:g}", "degenerate", center * scale, generators * scale, random_mask()))
    return out


def installed_directions(names: list[str] | None = None) -> tuple[dict[str, MinNormDirection], dict[str, str]]:
    """Instances of every installed min-norm backend (or of `names`), and why others are skipped.

    A backend whose package is missing is skipped (with the reason); an unknown name in
    `names` raises UnknownNameError."""
    from ..registry import make_direction

    explicit = names is not None
    if names is None:
        names = []
        for entry in sorted(available("directions").values(), key=lambda e: (e.name != "native", e.name)):
            if not (isinstance(entry.obj, type) and issubclass(entry.obj, MinNormDirection)):
                continue
            if entry.name.endswith(":"):
                names.extend(_expand(entry.name))
            else:
                names.append(entry.name)
    solvers: dict[str, MinNormDirection] = {}
    skipped: dict[str, str] = {}
    for name in names:
        try:
            solver = make_direction(name)
        except QdframeError as exc:  # not installed; an unknown name given by the user is an error
            if explicit and not isinstance(exc, BackendError):
                raise
            skipped[name] = str(exc)
            continue
        if not isinstance(solver, MinNormDirection):
            skipped[name] = "not a min-norm direction"
            continue
        solvers[name] = solver
    if "native" not in solvers:
        solvers = {"native": NativeDirection(), **solvers}
    return solvers, skipped


def _expand(prefix: str) -> list[str]:
    """`qpsolvers:` → every supported solver qpsolvers finds installed."""
    if prefix == "qpsolvers:":
        try:
            import qpsolvers
        except ImportError:
            return [prefix + "daqp"]  # reported as skipped, with the pip command
        from ..directions.qpsolvers_backend import offered_solvers

        return [prefix + name for name in offered_solvers(qpsolvers)]
    return []


@dataclass
class BenchRow:
    direction: str
    times: dict[str, list[float]] = field(default_factory=dict)  # per instance group
    max_deviation: float = 0.0
    failures: int = 0
    messages: list[str] = field(default_factory=list)

    def median(self, group: str | None = None) -> float:
        values = [t for g, ts in self.times.items() if group in (None, g) for t in ts]
        return float(np.median(values)) if values else float("nan")

    def as_json(self) -> dict:
        return {
            "direction": self.direction,
            "median_time_s": _finite_or_none(self.median()),
            "max_deviation": _finite_or_none(self.max_deviation),
            "failures": self.failures,
            "median_time_s_by_instances": {g: _finite_or_none(self.median(g)) for g in self.times},
            "failure_messages": self.messages[:5],
        }


def _finite_or_none(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def bench_directions(
    nodes: int,
    repeat: int = 3,
    names: list[str] | None = None,
    iterations: int = 4,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Run the benchmark; returns {"nodes", "rows": [...], "instances", "skipped", "native_speedup"}."""
    say = progress or (lambda text: None)
    solvers, skipped = installed_directions(names)
    say(f"recording the direction subproblems of {iterations} native iterations at N = {nodes} ...")
    instances = paper_instances(nodes, iterations) + degenerate_instances(nodes)
    references = [NativeDirection().min_norm(i.center, i.generators, i.mask)[0] for i in instances]
    scales = [_row_scale(i) for i in instances]
    rows = []
    for name, solver in solvers.items():
        say(f"timing {name} ...")
        row = BenchRow(name, {i.group: [] for i in instances})
        failed = set()
        for sweep in range(repeat + 1):  # sweep 0 builds the solvers and is not timed
            for k, instance in enumerate(instances):
                if k in failed:
                    continue
                start = time.perf_counter()
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        points, _ = solver.min_norm(instance.center, instance.generators, instance.mask)
                except Exception as exc:  # a backend failure is a result, not an abort
                    failed.add(k)
                    row.failures += 1
                    kind = "" if isinstance(exc, BackendError) else f"{type(exc).__name__}: "
                    row.messages.append(f"{instance.label}: {kind}{exc}")
                    continue
                elapsed = time.perf_counter() - start
                if sweep:
                    row.times[instance.group].append(elapsed)
                deviation = np.linalg.norm(points - references[k], axis=1) / scales[k]
                row.max_deviation = max(row.max_deviation, float(deviation.max(initial=0.0)))
        rows.append(row)
    native = next(r for r in rows if r.direction == "native").median()
    others = [r for r in rows if r.direction != "native" and np.isfinite(r.median())]
    fastest = min(others, key=lambda r: r.median(), default=None)
    return {
        "nodes": nodes,
        "repeat": repeat,
        "rows": [r.as_json() for r in rows],
        "instances": [{"label": i.label, "rows": i.rows, "shape": list(i.generators.shape[1:])} for i in instances],
        "skipped": skipped,
        "native_speedup": None
        if fastest is None
        else {"fastest_qp_backend": fastest.direction, "ratio": fastest.median() / native},
    }


def _row_scale(instance: Instance) -> np.ndarray:
    """The largest absolute entry of each row (center and active generators); 1 for a zero row."""
    active = np.where(instance.mask[..., None], np.abs(instance.generators), 0.0).reshape(instance.rows, -1)
    scale = np.maximum(np.abs(instance.center).max(axis=1), active.max(axis=1, initial=0.0))
    return np.where(scale > 0.0, scale, 1.0)


def format_table(report: dict) -> str:
    """The report as a Markdown table, with the native speed-up below it."""
    groups = list(report["rows"][0]["median_time_s_by_instances"]) if report["rows"] else []
    head = ["direction", "median time / direction (s)", *[f"{g} (s)" for g in groups], "max deviation", "failures"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in report["rows"]:
        by = row["median_time_s_by_instances"]
        cells = [
            row["direction"],
            _fmt(row["median_time_s"]),
            *[_fmt(by.get(g)) for g in groups],
            "—" if row["max_deviation"] is None else f"{row['max_deviation']:.1e}",
            str(row["failures"]),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    speedup = report.get("native_speedup")
    if speedup:
        lines.append("")
        lines.append(
            f"native is {speedup['ratio']:.0f}× faster than the fastest QP backend "
            f"({speedup['fastest_qp_backend']}), by median time per direction."
        )
    for name, why in report.get("skipped", {}).items():
        lines.append(f"skipped {name}: {why}")
    for row in report["rows"]:
        for message in row["failure_messages"]:
            lines.append(f"{row['direction']} failed: {message}")
    return "\n".join(lines)


def _fmt(value: float | None) -> str:
    return "—" if value is None else f"{value:.4f}" if value >= 1e-3 else f"{value:.2e}"


def write_json(report: dict, path: str) -> None:
    Path(path).write_text(json.dumps(report, indent=1) + "\n")
