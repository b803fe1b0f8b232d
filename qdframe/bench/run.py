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

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..progress import bar
from .cases import Plan
from .storage import ResultStore, machine, now, qdframe_version, source_commit
from .execution import dask_module, execute


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
        dask_module()  # fail before any work when dask is missing
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
        "qdframe_version": qdframe_version(),
        "command": command or store.meta.get("command"),
    })
    commit = source_commit()
    store.meta["commits"] = list(dict.fromkeys([*store.meta.get("commits", []), commit])) if commit else \
        store.meta.get("commits", [])
    store.meta.setdefault("started_at", now())
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
    meta = {**store.meta, "updated_at": now()}
    return SweepOutcome(store.ordered(order), count[0], resumed, sweep, time.perf_counter() - start, store.dropped, meta)


def _fmt_seconds(value) -> str:
    return "— s" if value is None else f"{value:.2f} s"
