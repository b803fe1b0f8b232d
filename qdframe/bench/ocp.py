"""`qdframe bench run --suite ocp`: optimal control with friction, qdframe against nosnoc, judged on cost.

Each problem of :mod:`.ocp_problems` is solved by qdframe (the default call, and with each
``accuracy=`` asked for) and by nosnoc (:mod:`.nosnoc_ocp`, for each number of control
stages). Every run is judged by one yardstick (:mod:`.two_modes`): its own control,
replayed through the true Filippov dynamics from x(0), gives the cost J that control
achieves and how far its motion misses the end conditions, its control the bounds and its
motion the state bounds (`violation`). A run's own cost (its discrete problem's) is shown beside it.

- qdframe's control is its scheme's own: on each mesh interval the polynomial through u at
  the interval's velocity points (:meth:`qdframe.schemes.base.Scheme.velocity`; linear
  through the two stages of Radau IIA), so u at t₀, which no rule reads, plays no part.
- nosnoc's control is constant on each control stage.

The work-precision summary gives, per model, solver and ε, the least wall time of a run
whose replayed cost is within ε·max(1, |J*|) of J* and whose violation is within
ε·max(1, |x0|, |xT|): the time to a cost within ε. Wall times include everything a call
does (nosnoc's CasADi/IPOPT build, qdframe's grids and certificate).
"""

from __future__ import annotations

import csv
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from ..schemes.grid import make_scheme
from ..status import Status
from . import nosnoc_ocp
from .nosnoc_peer import nosnoc_available
from .peer import package_version
from .storage import load_average, version_and_commit
from .ocp_problems import PROBLEMS, OcpProblem
from .two_modes import contact, integrate

ACCURACY = (1e-3, 1e-8)  # qdframe's accuracy= runs, beside the default call (1e-6)
STAGES = (10, 20, 30, 40)  # nosnoc's control stages (30: its motor example's) …
ELEMENTS = 2  # … of this many finite elements each
EPSILONS = (1e-2, 1e-4, 1e-6)  # the work-precision summary's ε
MET = 1e-6  # a run whose violation is within this (relative, as ε) met the conditions: it can set the best known J*


@dataclass
class Row:
    """One run, judged by its replayed control."""

    model: str
    solver: str  # qdframe or nosnoc
    setting: str  # the call, or the stages
    status: str  # the run's own
    cost: float  # J of the replayed motion
    own_cost: float  # the run's own (its discrete problem's)
    cost_error: float  # |cost − J*|
    violation: float  # max of the replayed motion's end miss and the control's bound excess
    wall_time_s: float
    points: int  # the run's own time points (qdframe) or finite elements (nosnoc)
    message: str = ""
    own_estimate: float | None = None  # qdframe's estimate of |own cost − J*| (result.cost_estimate); None: none


def scale(problem: OcpProblem) -> float:
    """max(1, |x0|, |xT|): what a violation is relative to."""
    return max(1.0, *np.abs(problem.x0), *(abs(v) for v in problem.end.values()))


def judge(problem: OcpProblem, solver: str, setting: str, status: Status, own_cost: float, wall: float, points: int,
          control: Callable[[float], np.ndarray], breaks: Sequence[float], samples: np.ndarray, message: str,
          own_estimate: float | None = None) -> Row:
    """The row of a run whose control is `control` (its `breaks`, and its values at `samples`)."""
    try:
        push = problem.push if problem.friction is not None and callable(problem.friction[1]) else None
        motion = integrate(contact(problem.numeric_field, problem.friction, push), problem.x0, problem.T, control,
                           breaks, lambda x, u: float(problem.running(x, u)), problem.terminal)
    except RuntimeError as exc:
        return Row(problem.name, solver, setting, Status(status).value, float("nan"), own_cost, float("nan"),
                   float("nan"), wall, points, f"{message}; {exc}", own_estimate)
    miss = max((abs(motion.x_end[i] - value) for i, value in problem.end.items()), default=0.0)
    excess = 0.0
    if problem.u_bounds is not None:
        lo, hi = problem.u_bounds
        excess = float(np.max(np.maximum(samples - hi, lo - samples), initial=0.0))
    for i, (lo, hi) in problem.x_bounds.items():  # along the replayed motion (at the integrator's steps)
        excess = max(excess, float(np.max(np.maximum(motion.samples[:, i] - hi, lo - motion.samples[:, i]), initial=0.0)))
    cost_error = abs(motion.cost - problem.best) if problem.best is not None else float("nan")
    message = f"{message}; replayed x(T) = ({', '.join(f'{value:.6g}' for value in motion.x_end)})"
    return Row(problem.name, solver, setting, Status(status).value, float(motion.cost), float(own_cost),
               float(cost_error), float(max(miss, excess, 0.0)), float(wall), int(points), message, own_estimate)


def run_qdframe(problem: OcpProblem, accuracy: float | None = None) -> Row:
    """qdframe.solve on the problem's model as a user calls it, with ``accuracy=`` where given."""
    from ..solve.solving import solve

    options = {} if accuracy is None else {"accuracy": accuracy}
    start = time.perf_counter()
    result = solve(problem.model(), **options)
    wall = time.perf_counter() - start
    control, breaks, samples = scheme_control(result)
    setting = "default call" if accuracy is None else f"accuracy={accuracy:g}"
    message = f"{result.iterations} iterations, N = {result.nodes}: {result.message}"
    own = float(result.cost) if result.cost is not None else float("nan")
    estimate = float(result.cost_estimate) if result.cost_estimate is not None else None
    return judge(problem, "qdframe", setting, result.status, own, wall, result.nodes, control, breaks, samples, message,
                 estimate)


def scheme_control(result) -> tuple[Callable[[float], np.ndarray], np.ndarray, np.ndarray]:
    """A qdframe result's control u(t) as its scheme reads it (module docstring), the mesh's
    interior times (its breaks) and u at its points and at each interval's start (where the
    polynomial is extrapolated)."""
    scheme = make_scheme(result.options["scheme"])
    t, u = np.asarray(result.t, dtype=float), np.asarray(result.u, dtype=float)
    mesh = np.arange(0, t.size, scheme.stages)
    tau = t[mesh]
    points = mesh[:-1, None] + np.asarray(scheme.velocity_points)[None, :]  # (K, q)
    local = t[points] - tau[:-1, None]
    # each interval's polynomial in the time since its start: coefficients by a Vandermonde solve
    powers = np.arange(points.shape[1])[::-1]
    vandermonde = local[:, :, None] ** powers[None, None, :]
    coefficients = np.linalg.solve(vandermonde, u[points])  # (K, q, m)
    starts = tau[:-1].tolist()

    def control(time: float) -> np.ndarray:
        k = min(max(int(np.searchsorted(starts, time, side="right")) - 1, 0), len(starts) - 1)
        return np.array([np.polyval(coefficients[k, :, i], time - starts[k]) for i in range(u.shape[1])])

    at_starts = np.einsum("kqm,q->km", coefficients, (0.0 ** powers).astype(float))
    return control, tau[1:-1], np.concatenate([u[points].reshape(-1, u.shape[1]), at_starts])


def run_nosnoc(problem: OcpProblem, stages: int, elements: int = ELEMENTS) -> Row:
    """nosnoc on the problem with `stages` control stages of `elements` finite elements."""
    done = nosnoc_ocp.run(problem, stages, elements)
    ends, controls = done.stage_times, done.controls

    def control(time: float) -> np.ndarray:
        k = min(max(int(np.searchsorted(ends, time, side="right")) - 1, 0), controls.shape[0] - 1)
        return controls[k]

    setting = f"{stages} stages × {elements} FE"
    if not controls.shape[0]:
        return Row(problem.name, "nosnoc", setting, Status(done.status).value, float("nan"), done.own_cost,
                   float("nan"), float("nan"), done.wall_time_s, 0, done.message)
    return judge(problem, "nosnoc", setting, done.status, done.own_cost, done.wall_time_s, stages * elements, control,
                 ends[1:-1], controls, done.message)


def run(models: Sequence[str] | None = None, accuracy: Sequence[float] = ACCURACY, stages: Sequence[int] = STAGES,
        peers: bool = True, progress: Callable[[str], None] | None = None) -> list[Row]:
    """Every problem of `models` (default: all) by qdframe's default call and each accuracy, then
    by nosnoc at each number of stages (with `peers`, where nosnoc runs here; `progress` says
    why not); J* filled in where it is the best known (:func:`with_best`)."""
    rows = []
    reason = nosnoc_available() if peers else None
    if reason is not None and progress is not None:
        progress(f"nosnoc skipped: {reason}")
    for name in models or PROBLEMS:
        problem = PROBLEMS[name]
        for target in (None, *accuracy):
            rows.append(run_qdframe(problem, target))
            _tell(progress, rows[-1])
        if peers and reason is None:
            for count in stages:
                rows.append(run_nosnoc(problem, count))
                _tell(progress, rows[-1])
    return with_best(rows)


def best(rows: Sequence[Row], name: str) -> float | None:
    """J* of a problem: exact where known, else the least replayed cost of its runs that met the
    conditions (violation within MET·scale); None where none did."""
    problem = PROBLEMS[name]
    if problem.best is not None:
        return problem.best
    met = [row.cost for row in rows if row.model == name and np.isfinite(row.cost)
           and row.violation <= MET * scale(problem)]
    return min(met) if met else None


def with_best(rows: Sequence[Row]) -> list[Row]:
    """The rows with cost_error against the best known J* where the problem has no exact one."""
    out = []
    for row in rows:
        reference = best(rows, row.model)
        out.append(replace(row, cost_error=abs(row.cost - reference) if reference is not None else float("nan")))
    return out


def _tell(progress: Callable[[str], None] | None, row: Row) -> None:
    if progress is not None:
        progress(f"{row.model}: {row.solver} {row.setting}: {row.status}, cost {row.cost:.10g}, violation "
                 f"{row.violation:.1e}, {row.wall_time_s:.2f} s")


def table(rows: Sequence[Row]) -> str:
    """Every run (Markdown)."""
    lines = ["| model | solver | setting | status | replayed cost | own cost | own estimate | abs(J − J*) | violation "
             "| wall time (s) | points |", "|:---|:---|:---|:---|---:|---:|---:|---:|---:|---:|---:|"]
    for row in rows:
        estimate = f"{row.own_estimate:.1e}" if row.own_estimate is not None else "—"
        lines.append(f"| {row.model} | {row.solver} | {row.setting} | {row.status} | {row.cost:.10g} | "
                     f"{row.own_cost:.10g} | {estimate} | {row.cost_error:.1e} | {row.violation:.1e} | "
                     f"{row.wall_time_s:.2f} | {row.points} |")
    return "\n".join(lines)


def work_precision(rows: Sequence[Row]) -> str:
    """Per model and solver, the time to a cost within each ε (module docstring; — where no run reached it)."""
    header = "| model | J* | solver | " + " | ".join(f"time to ε = {e:g} (s)" for e in EPSILONS) + " |"
    lines = [header, "|:---|---:|:---|" + "---:|" * len(EPSILONS)]
    for name in dict.fromkeys(row.model for row in rows):
        problem, reference = PROBLEMS[name], best(rows, name)
        for solver in dict.fromkeys(row.solver for row in rows if row.model == name):
            cells = []
            for eps in EPSILONS:
                times = [row.wall_time_s for row in rows if row.model == name and row.solver == solver
                         and row.cost_error <= eps * max(1.0, abs(reference or 0.0))
                         and row.violation <= eps * scale(problem)]
                cells.append(f"{min(times):.2f}" if times else "—")
            shown = f"{reference:.10g}" if reference is not None else "—"
            lines.append(f"| {name} | {shown} | {solver} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def report(rows: Sequence[Row], command: str, seconds: float) -> str:
    """The Markdown report: what was run, the work-precision summary, every run, each run's message."""
    lines = [
        "# Optimal control with friction: qdframe against nosnoc, on cost", "",
        f"Made by `{command}` in {seconds:.1f} s ({platform.python_implementation()} {platform.python_version()}, "
        f"{platform.machine()}, {os.cpu_count()} CPUs, load average {load_average()} at the end; nosnoc "
        f"{package_version('nosnoc')}).", "",
        f"| qdframe | {version_and_commit()} |", "|---|---|", "",
        "Every run's control is replayed through the true Filippov dynamics from x(0) "
        "(`qdframe/bench/two_modes.py`, an event-driven integration independent of qdframe's own): "
        "the replayed cost J, its distance to J*, and the violation (the replayed motion's end miss "
        "and the control's bound excess); beside them each run's own cost and qdframe's estimate of its distance "
        "to J* (`result.cost_estimate`, what a cost's `solved` certifies). J*: " + "; ".join(
            f"{name} {PROBLEMS[name].source}" for name in dict.fromkeys(row.model for row in rows)) + ".", "",
        "## Time to a cost within ε", "",
        "The least wall time of a run with abs(J − J*) ≤ ε·max(1, |J*|) and violation ≤ ε·max(1, |x0|, |xT|).", "",
        work_precision(rows), "",
        "## Every run", "",
        table(rows), "",
        "## Each run's own report", "",
    ]
    lines += [f"- {row.model}, {row.solver}, {row.setting}: {row.message}" for row in rows]
    return "\n".join(lines) + "\n"


def write_report(rows: Sequence[Row], out: str | Path, command: str, seconds: float) -> dict[str, Path]:
    """report.md and results.csv (one line per run) in `out`."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {"report": folder / "report.md", "results": folder / "results.csv"}
    paths["report"].write_text(report(rows, command, seconds))
    with open(paths["results"], "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(Row.__dataclass_fields__))
        writer.writeheader()
        writer.writerows(asdict(row) for row in rows)
    return paths


def read_rows(path: str | Path) -> list[Row]:
    """The rows of a results.csv (:func:`write_report`)."""
    numbers = {"cost", "own_cost", "cost_error", "violation", "wall_time_s"}

    def read(key: str, value: str):
        if key == "own_estimate":  # empty where the run has none (nosnoc's)
            return float(value) if value else None
        return float(value) if key in numbers else int(value) if key == "points" else value

    with open(path, newline="") as handle:
        return [Row(**{key: read(key, value) for key, value in line.items()}) for line in csv.DictReader(handle)]
