"""The storage of `qdframe bench run`'s rows: :class:`ResultStore` (results.json with every row's
history and results.csv without, each replaced atomically after every row; ``--resume`` keeps the
rows both hold), :func:`read_csv`, and the source commit a report names."""

from __future__ import annotations

import csv
import datetime
import json
import math
import os
import platform
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..status import Status


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


def claim(row: dict) -> str:
    """How a run's own success report compares with its reference error (qpbenchmark's
    "correct"): "confirmed" (solved, error ≤ claim_tol), "false" (solved, error > claim_tol
    or unknown), "missed" (not solved, error ≤ claim_tol), "none" (neither)."""
    error, tol = row.get("error"), row.get("claim_tol")
    within = error is not None and tol is not None and error <= tol
    if row.get("status") == Status.SOLVED:
        return "confirmed" if within else "false"
    return "missed" if within else "none"


def finite(value):
    """Non-finite floats to None (JSON has no NaN), NumPy scalars to Python ones."""
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


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
        document = {**self.meta, "format": FORMAT, "updated_at": now(), "rows": rows}
        _atomic(self.json_path, json.dumps(finite(document), indent=1, allow_nan=False) + "\n")
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


def qdframe_version() -> str:
    from .. import __version__

    return __version__


def version_and_commit() -> str:
    """qdframe's version and the commit of its source, as a committed report names them."""
    return f"{qdframe_version()}, commit {source_commit() or 'unknown'}"


def load_average() -> str:
    """The 1-minute load average ("?" where the system has none): other jobs slow every row alike."""
    try:
        return f"{os.getloadavg()[0]:.1f}"
    except (AttributeError, OSError):
        return "?"


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
