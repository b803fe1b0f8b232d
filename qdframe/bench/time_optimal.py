"""`qdframe bench time-optimal`: the time-optimal block (``block-time-optimal``) by qdframe and by nosnoc, side by side.

qdframe runs the default call ``qdframe.solve("block-time-optimal")`` and the same call with
each ``accuracy=`` asked for; nosnoc runs its time-optimal statement
(:mod:`.nosnoc_time_optimal`) in each formulation (one speed of time ``global``, or one per
control stage, ``local``) for each number of control stages and each total number of finite
elements (split evenly over the stages; a total below the stages, or not a multiple of them, is
skipped).

Every run is judged the same way: its T against T* = (4/3)·√1.5, and its trajectory at its
own time points against the exact motion on the normalized time: x(t_k) against
x*(t_k·T*/T), t_k ∈ [0, T] the run's points, T its own end time (the exact motion is defined
on [0, T*]; where T = T* this is the plain error x(t_k) − x*(t_k)). Wall times include
everything a call does: nosnoc's CasADi/IPOPT build and qdframe's grids.
"""

from __future__ import annotations

import csv
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..models.identification import BlockTimeOptimal
from ..status import Status
from . import nosnoc_time_optimal as peer
from .storage import load_average

MODEL = BlockTimeOptimal.name  # not in the catalogue (problems.py): T free, judged here on the normalized time
STAGES = (10, 20)
ELEMENTS = (10, 20, 40, 80)  # finite elements in all, over the stages
ACCURACY = (1e-3,)


@dataclass
class Row:
    """One run, judged."""

    solver: str  # qdframe or nosnoc
    setting: str  # the call, or the formulation and the grid
    status: str
    wall_time_s: float
    T: float
    T_error: float  # T − T*
    trajectory_error: float  # max_k ‖x(t_k) − x*(t_k·T*/T)‖_∞ over the run's own points
    points: int  # the run's own time points
    message: str = ""


def trajectory_error(t: np.ndarray, x: np.ndarray, T: float) -> float:
    """max over the points t_k of ‖x(t_k) − x*(t_k·T*/T)‖_∞: the exact motion on the normalized time."""
    exact = BlockTimeOptimal()
    if not np.isfinite(T) or T <= 0 or len(t) == 0:
        return float("nan")
    s = np.clip(np.asarray(t, dtype=float) / T, 0.0, 1.0) * exact.exact_T
    return float(np.max(np.abs(np.asarray(x, dtype=float) - exact.motion(s))))


def judged(solver: str, setting: str, status: Status, wall: float, T: float, t, x, message: str = "") -> Row:
    return Row(solver, setting, Status(status).value, wall, T, T - BlockTimeOptimal.exact_T,
               trajectory_error(t, x, T), len(t), message)


def run_qdframe(accuracy: float | None = None) -> Row:
    """``qdframe.solve("block-time-optimal")``, with ``accuracy=`` when one is given."""
    from ..solve.solving import solve

    options = {} if accuracy is None else {"accuracy": accuracy}
    start = time.perf_counter()
    result = solve(MODEL, **options)
    wall = time.perf_counter() - start
    setting = "default call" if accuracy is None else f"accuracy={accuracy:g}"
    return judged("qdframe", setting, result.status, wall, float(result.T), result.t, result.x,
                  f"{result.iterations} iterations, N = {result.nodes}")


def run_nosnoc(formulation: str, stages: int, elements: int) -> Row:
    """nosnoc's time-optimal statement: `stages` control stages × `elements` finite elements each."""
    done = peer.run(formulation, stages, elements)
    setting = f"{formulation} s, {stages} stages × {elements} FE"
    return judged("nosnoc", setting, done.status, done.wall_time_s, done.T, done.t, done.x, done.message)


def grids(stages: Sequence[int], elements: Sequence[int]) -> list[tuple[int, int]]:
    """(stages, elements per stage) for each number of stages and each total that is a multiple of it."""
    return [(n, total // n) for n in stages for total in elements if total >= n and total % n == 0]


def run(accuracy: Sequence[float] = ACCURACY, formulations: Sequence[str] = peer.FORMULATIONS,
        stages: Sequence[int] = STAGES, elements: Sequence[int] = ELEMENTS,
        progress: Callable[[str], None] | None = None) -> list[Row]:
    """qdframe's default call and one per accuracy, then nosnoc on every formulation and grid
    (none where nosnoc cannot run here: `progress` says why)."""
    rows = []
    for target in (None, *accuracy):
        rows.append(run_qdframe(target))
        _tell(progress, rows[-1])
    reason = peer.nosnoc_available()
    if reason is not None:
        if progress is not None:
            progress(f"nosnoc skipped: {reason}")
        return rows
    for formulation in formulations:
        for count, each in grids(stages, elements):
            rows.append(run_nosnoc(formulation, count, each))
            _tell(progress, rows[-1])
    return rows


def _tell(progress: Callable[[str], None] | None, row: Row) -> None:
    if progress is not None:
        progress(f"{row.solver} {row.setting}: {row.status}, T − T* = {row.T_error:.2e} in {row.wall_time_s:.2f} s")


def table(rows: Sequence[Row]) -> str:
    """The side-by-side table (Markdown)."""
    lines = ["| solver | setting | status | wall time (s) | T | abs(T − T*) | max abs(x − x*), normalized time | points |",
             "|:---|:---|:---|---:|---:|---:|---:|---:|"]
    for row in rows:
        lines.append(f"| {row.solver} | {row.setting} | {row.status} | {row.wall_time_s:.2f} | {row.T:.10f} | "
                     f"{abs(row.T_error):.1e} | {row.trajectory_error:.1e} | {row.points} |")
    return "\n".join(lines)


def report(rows: Sequence[Row], command: str, seconds: float) -> str:
    """The Markdown report: what was run, the table, and each run's own message."""
    exact = BlockTimeOptimal.exact_T
    versions = {row.message.split(":")[0] for row in rows if row.solver == "nosnoc" and row.message.startswith("nosnoc ")}
    lines = [
        "# Time-optimal: block-time-optimal, qdframe against nosnoc", "",
        f"Made by `{command}` in {seconds:.1f} s ({platform.python_implementation()} {platform.python_version()}, "
        f"{platform.machine()}, {os.cpu_count()} CPUs, load average {load_average()} at the end; "
        f"{', '.join(sorted(versions)) or 'nosnoc not run'}).", "",
        "The block p' = v, v' ∈ [−2, 2] − Sgn(v) from rest at 0 to rest at 1 in the shortest time: "
        f"T* = (4/3)·√1.5 = {exact:.10f}, full force forward until √1.5 = 0.75·T*, then full force back.", "",
        "- qdframe: `qdframe.solve(\"block-time-optimal\")` (T free, cost ∫1 dt; `qdframe/solve/optimum.py`) as a user "
        "calls it, and with `accuracy=`.",
        "- nosnoc: Stewart's form with the control |u| ≤ 2 (modes (v, u − 1), (v, u + 1) on c = v), terminal "
        "constraint x(T) = (1, 0), cost T through a speed of time s on the numerical horizon [0, 2]: `global`, one s "
        "(T = 2s; nosnoc's global variable, as nosnoc 0.2.0's SpeedOfTimeVariableMode.GLOBAL fails to build), "
        "`local`, one s per control stage (SpeedOfTimeVariableMode.LOCAL). Radau IIA, n_s = 2, comp_tol 1e-9.",
        "- Errors: abs(T − T*), and the trajectory at the run's own points t_k against the exact motion on the "
        "normalized time, x*(t_k·T*/T) (the same as x*(t_k) where T = T*). Wall times include nosnoc's "
        "CasADi/IPOPT build.", "",
        table(rows), "",
        "## Each run's own report", "",
    ]
    lines += [f"- {row.solver}, {row.setting}: {row.message}" for row in rows]
    return "\n".join(lines) + "\n"


def write_report(rows: Sequence[Row], out: str | Path, command: str, seconds: float) -> dict[str, Path]:
    """report.md and results.csv (one line per row) in `out`."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    paths = {"report": folder / "report.md", "results": folder / "results.csv"}
    paths["report"].write_text(report(rows, command, seconds))
    write_rows(rows, paths["results"])
    return paths


def write_rows(rows: Sequence[Row], path: Path) -> None:
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(Row.__dataclass_fields__))
        writer.writeheader()
        writer.writerows(asdict(row) for row in rows)


def read_rows(path: Path) -> list[Row]:
    """The rows of a results.csv (:func:`write_rows`)."""
    numbers = {"wall_time_s", "T", "T_error", "trajectory_error"}
    with open(path, newline="") as handle:
        return [Row(**{key: float(value) if key in numbers else int(value) if key == "points" else value
                       for key, value in line.items()}) for line in csv.DictReader(handle)]
