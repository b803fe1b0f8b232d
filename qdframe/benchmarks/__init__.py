"""Comparative benchmarks: `qdframe bench run` (speed against error, peers, dask).

* :mod:`.sweep` — the cases of a sweep, one run → one row, the result files, executors;
* :mod:`.report` — qpbenchmark-style metrics, the figures and report.md;
* :mod:`.models` — two problems qdframe and nosnoc can both state;
* :mod:`.peers` — nosnoc, run and judged by qdframe's residual checks;
* :mod:`.cli` — ``add_run_parser`` / ``main_run`` for ``qdframe bench run``.
"""

from .cli import add_run_parser, main_run
from .report import shifted_geometric_mean, summarize, write_report
from .sweep import Case, Plan, ResultStore, SUITES, execute, plan, run_case, run_sweep

__all__ = [
    "Case",
    "Plan",
    "ResultStore",
    "SUITES",
    "add_run_parser",
    "execute",
    "main_run",
    "plan",
    "run_case",
    "run_sweep",
    "shifted_geometric_mean",
    "summarize",
    "write_report",
]
