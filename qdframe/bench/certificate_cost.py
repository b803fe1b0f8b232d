"""What a certified answer costs (`qdframe bench certificates`): the solve, its certificate
and the memory, per registered model, on fixed grids and by the default call.

Each cell runs in a process of its own (its peak resident memory, `ru_maxrss`, is its
own) and is one call of :func:`qdframe.solve`:

- **default**: ``solve(model)``, refined until its estimate meets 1e-6·max(1, |x|);
- **N** (each of `nodes`, default 10001 and 100001): ``solve(model, nodes=N)``, a fixed grid
  whose estimate is made once (and stopped where it passes the target: `uncertified`);
- **blocks k** (`--blocks`): the default call on k independent Coulomb blocks
  (:mod:`qdframe.models.coulomb_blocks`), whose mode choice at the i-th stop sees i + 1
  switches at their surfaces.

A row gives the status, the points, the whole call's seconds, the certificate's share
(`estimate_time_s`: the estimates' own solves and replays), the rest (the solves), the
process's peak resident memory and its baseline (after importing qdframe and building the
model, before the solve), and the estimate. `--out DIR` writes results.csv and report.md
there (the committed copy is docs/bench/certificates/, shown in docs/benchmark-results.md
by `qdframe bench pages`).
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from ..registry import names
from ..status import Status
from .storage import version_and_commit

NODES = (10001, 100001)
FIELDS = ("model", "grid", "status", "points", "seconds", "certificate_s", "solve_s", "peak_mb", "baseline_mb",
          "estimate", "message")
CELL_TIMEOUT = 300.0  # seconds a cell may take before it is recorded as timed out (--timeout)

CHILD = r"""
import json, resource, sys, time
import qdframe
from qdframe.models.coulomb_blocks import coulomb_blocks
name, grid = sys.argv[1], sys.argv[2]
model = coulomb_blocks(int(name.split(":")[1])) if name.startswith("blocks:") else qdframe.load_model(name)
def rss():
    with open("/proc/self/status") as handle:
        return next(int(line.split()[1]) / 1024 for line in handle if line.startswith("VmRSS"))
baseline = rss()
clock = time.perf_counter()
result = qdframe.solve(model) if grid == "default" else qdframe.solve(model, nodes=int(grid))
seconds = time.perf_counter() - clock
certificate = float(result.options.get("estimate_time_s") or 0.0)
print(json.dumps(dict(status=str(result.status), points=int(result.nodes), seconds=seconds, certificate_s=certificate,
                      solve_s=seconds - certificate, peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      baseline_mb=baseline, estimate=result.error_estimate, message=result.message)))
"""


def cell(model: str, grid: str, timeout: float = CELL_TIMEOUT) -> dict:
    """One measurement in a fresh process: `model` a registered name or ``blocks:k``,
    `grid` ``default`` or a node count."""
    row = {"model": model, "grid": grid}
    try:
        done = subprocess.run([sys.executable, "-c", CHILD, model, grid], capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return {**row, "status": "timed out", "seconds": timeout, "message": f"over {timeout:g} s"}
    lines = done.stdout.strip().splitlines()
    if done.returncode != 0 or not lines:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        return {**row, "status": "error", "message": tail}
    return {**row, **json.loads(lines[-1])}


def run(models: Sequence[str] | None = None, nodes: Sequence[int] = NODES, blocks: Sequence[int] = (),
        progress: Callable[[str], None] | None = None, timeout: float = CELL_TIMEOUT) -> list[dict]:
    """Every cell: each model's default call and its fixed grids, then the block counts."""
    cells = [(name, grid) for name in (models if models is not None else names("models"))
             for grid in ("default", *map(str, nodes))] + [(f"blocks:{k}", "default") for k in blocks]
    rows = []
    for index, (name, grid) in enumerate(cells, 1):
        rows.append(cell(name, grid, timeout))
        if progress is not None:
            row = rows[-1]
            progress(f"[{index}/{len(cells)}] {name} {grid}: {row['status']} in {row.get('seconds', 0):.2f} s, "
                     f"peak {row.get('peak_mb') or 0:.0f} MB")
    return rows


def _number(value, digits: int = 2, kind: str = "f") -> str:
    return "—" if value is None else f"{value:.{digits}{kind}}"


def table(rows: Sequence[dict]) -> str:
    """The rows as a Markdown table."""
    lines = ["| model | grid | status | points | s | certificate s | solve s | peak MB | estimate |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for row in rows:
        lines.append(f"| {row['model']} | {row['grid']} | {row.get('status')} | {row.get('points') or '—'} | "
                     f"{_number(row.get('seconds'))} | {_number(row.get('certificate_s'))} | "
                     f"{_number(row.get('solve_s'))} | {_number(row.get('peak_mb'), 0)} | "
                     f"{_number(row.get('estimate'), 1, 'e')} |")
    return "\n".join(lines)


def summary(rows: Sequence[dict]) -> str:
    """The figures the issue's targets name: the default calls' median and slowest, the block
    counts' times, each fixed grid's certificate against its solve and its peak memory."""
    defaults = sorted((row for row in rows if row["grid"] == "default" and not row["model"].startswith("blocks:")
                       and row.get("seconds") is not None), key=lambda row: row["seconds"])
    out = []
    if defaults:
        middle = defaults[len(defaults) // 2]["seconds"] if len(defaults) % 2 else \
            0.5 * (defaults[len(defaults) // 2 - 1]["seconds"] + defaults[len(defaults) // 2]["seconds"])
        out.append(f"default calls: {len(defaults)} models, median {middle:.2f} s, slowest "
                   f"{defaults[-1]['model']} {defaults[-1]['seconds']:.2f} s; "
                   f"{sum(row['status'] == Status.SOLVED for row in defaults)} solved")
    blocks = [row for row in rows if row["model"].startswith("blocks:")]
    if blocks:
        out.append("blocks: " + ", ".join(f"{row['model'].split(':')[1]} {_number(row.get('seconds'))} s "
                                          f"({row.get('status')})" for row in blocks))
    return "\n".join(out)


def read(path: str | Path) -> list[dict]:
    """The rows of a results.csv that :func:`write` made, numbers parsed back (empty: None)."""
    texts = {"model", "grid", "status", "message"}
    with open(path, newline="", encoding="utf-8") as handle:
        return [{name: (None if value in ("", None) else value if name in texts else
                        int(float(value)) if name == "points" else float(value))
                 for name, value in raw.items()} for raw in csv.DictReader(handle)]


def write(rows: Sequence[dict], folder: str | Path, command: str) -> None:
    """results.csv and report.md (the command, the summary and the table) into `folder`."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "results.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=FIELDS, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({name: row.get(name) for name in FIELDS})
    (folder / "report.md").write_text(f"# What a certified answer costs\n\n`{command}`\n\n| qdframe | {version_and_commit()} |\n"
                                      f"|---|---|\n\n{summary(rows)}\n\n{table(rows)}\n", encoding="utf-8")
