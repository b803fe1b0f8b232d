"""Benchmarks: every `qdframe bench` subcommand, the problems they run and the references they
judge by.

* :mod:`.problems` — the problem catalogue: every benchmark problem, its suites and tags, its
  statements for the peers and the reference (adding a problem is one entry there);
* :mod:`.commands` — the `qdframe bench` subcommands' arguments (``add_bench_parser``, ``main_bench``);
* :mod:`.compare_directions` — `bench directions`: speed and accuracy of the min-norm QP backends;
* :mod:`.hard` — `bench hard`: the hard-case suite;
* :mod:`.friction` — `bench friction`: the stick/slide/switch suite per N;
* :mod:`.accuracy` — `bench accuracy`: nodes and time to a true error, uniform against `accuracy=`;
* :mod:`.scale` — `bench scale`: seconds per iteration against N, the floor and memory;
* :mod:`.unknown_cost` — `bench unknowns`: the cost per iteration of a free T or parameter;
* `bench run`, work-precision against references:
  :mod:`.run` (the cases, one run → one row, executors), :mod:`.references` (a row's
  error against the model's reference), :mod:`.replay_statements` (each model stated
  independently for the event-driven Filippov integrator), :mod:`.report` (diagrams,
  times to an error, report.md), :mod:`.sign_forms` (each friction and sliding model
  written once for the peers), the peer interface :mod:`.peer` and its registered peers
  :mod:`.nosnoc_peer` and :mod:`.solve_bvp_peer` (scipy's solve_bvp);
* `bench run --suite ocp`, optimal control judged on cost: :mod:`.ocp` (the runs, the
  work-precision table, report.md), :mod:`.ocp_problems` (each problem stated once for every
  tool), :mod:`.nosnoc_ocp` (nosnoc's statement) and :mod:`.two_modes` (the event-driven replay of
  a control, also the independent reference of :func:`qdframe.sets.Modes`' tests);
* :mod:`.pages` — `bench pages`: README's and docs/benchmark-results.md's tables from the reports.

The models the benchmarks pose live with every other built-in model, in :mod:`qdframe.models`.
"""

from .compare_directions import bench_directions, format_table, write_json
from .report import shifted_geometric_mean, summarize, write_report
from .cases import SUITES, Case, Plan, plan
from .execution import execute, run_case
from .run import run_sweep
from .storage import ResultStore

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
