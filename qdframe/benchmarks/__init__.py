"""Comparative benchmarks: `qdframe bench run` (work-precision against references, peers, dask).

* :mod:`.sweep` — the cases of a sweep (each solver's accuracy knob), one run → one row,
  the result files, executors;
* :mod:`.references` — the one yardstick: a row's error against the model's reference;
* :mod:`.filippov` — an independent event-driven Filippov integrator (references, replays);
* :mod:`.replay` — the true motion rebuilt from a trajectory where the solution is not unique;
* :mod:`.report` — work-precision diagrams, times to an error, qpbenchmark-style metrics, report.md;
* :mod:`.models` — two problems qdframe and nosnoc can both state;
* :mod:`.peers` — nosnoc; :mod:`.bvp_peer` — scipy's solve_bvp;
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
