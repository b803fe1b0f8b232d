"""Benchmarks: every `qdframe bench` subcommand, and the reference solutions they judge by.

* :mod:`.cli` — the `qdframe bench` subcommands' arguments (``add_bench_parser``, ``main_bench``);
* :mod:`.directions` — `bench directions`: speed and accuracy of the min-norm QP backends;
* :mod:`.hard` — `bench hard`: the hard-case suite;
* :mod:`.friction` — `bench friction`: the stick/slide/switch suite per N;
* :mod:`.accuracy` — `bench accuracy`: nodes and time to a true error, uniform against `accuracy=`;
* :mod:`.scale` — `bench scale`: seconds per iteration against N, the floor and memory;
* `bench run`, work-precision against references:
  :mod:`.sweep` (the cases, one run → one row, executors), :mod:`.references` (a row's
  error against the model's reference), :mod:`.filippov` (an independent event-driven
  Filippov integrator), :mod:`.report` (diagrams, times to an error, report.md),
  :mod:`.statements` (each friction and sliding model written once for the peers),
  :mod:`.peers` (nosnoc) and :mod:`.bvp_peer` (scipy's solve_bvp);
* :mod:`.pages` — `bench pages`: README's and docs/benchmark-results.md's tables from the reports.

The models the benchmarks pose live with every other built-in model, in :mod:`qdframe.models`.
"""

from .directions import bench_directions, format_table, write_json
from .report import shifted_geometric_mean, summarize, write_report
from .sweep import SUITES, Case, Plan, ResultStore, execute, plan, run_case, run_sweep

__all__ = [
    "Case",
    "Plan",
    "ResultStore",
    "SUITES",
    "bench_directions",
    "execute",
    "format_table",
    "plan",
    "run_case",
    "run_sweep",
    "shifted_geometric_mean",
    "summarize",
    "write_json",
    "write_report",
]
