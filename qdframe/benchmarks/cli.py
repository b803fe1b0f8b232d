"""`qdframe bench run`: its arguments and what it does with them.

``add_run_parser(bench_subparsers)`` adds the ``run`` subcommand to ``qdframe bench`` and
``main_run(args)`` runs it (exit status 0, or 1 when a run could not be recorded).
Until the command is wired into ``qdframe``, ``python -m qdframe.benchmarks run ...`` runs
the same code.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from collections.abc import Sequence

from ..argtypes import integer, names, node_counts, positive_float, vector
from ..errors import InputError
from .references import cross_check
from .report import ratio_table, summary_table, time_table, write_report
from .sweep import SUITES, plan, run_sweep

def tolerances(text: str) -> list[float]:
    """Comma-separated positive numbers like 1e-3,1e-6, or `none` for an empty ladder."""
    if text.strip() == "none":
        return []
    values = vector(text)
    if not all(v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive numbers like 1e-3,1e-6 (or none), got {text!r}")
    return values


def add_run_parser(bench_subparsers) -> argparse.ArgumentParser:
    """Add `run` to the subparsers of `qdframe bench`; returns its parser."""
    run = bench_subparsers.add_parser(
        "run",
        help="work-precision sweep: each solver's accuracy knob, every run judged against a reference solution",
        description="Run a sweep and write results.csv, results.json (with histories), work-precision diagrams "
        "and report.md into --out, row by row (--resume continues an interrupted sweep). Every run's error is "
        "measured against the model's reference solution on the run's own time grid.",
    )
    run.add_argument("--suite", choices=sorted(SUITES), default="quick",
                     help="quick (CI, under 2 minutes): 5 models, gauss-newton to N = 161 and accuracy= 1e-3, 1e-6, "
                     "native to N = 41; standard: the paper's, plugin, friction, peer and T = 100 models, "
                     "gauss-newton to N = 100001 and accuracy= to 1e-8; full: standard with every direction "
                     "and line search")
    run.add_argument("--models", type=names, metavar="NAME,..", help="only these models (default: the suite's)")
    run.add_argument("--directions", type=names, metavar="NAME,..", help="only these directions (default: the suite's)")
    run.add_argument("--line-searches", type=names, metavar="NAME,..",
                     help="every direction with each of these (default: each direction's own; full: all)")
    run.add_argument("--nodes", type=node_counts, metavar="N,..", help="every solver's grids (default: the suite's)")
    run.add_argument("--accuracy", type=tolerances, metavar="E,..",
                     help="gauss-newton's accuracy= targets (default: the suite's; 'none' for none)")
    run.add_argument("--bvp-tols", type=tolerances, metavar="E,..",
                     help="solve_bvp's tol ladder (default: the suite's; 'none' for none)")
    run.add_argument("--peers", action="store_true",
                     help="also run the peers on the models they can state: nosnoc (Filippov problems with "
                     "an input) and scipy's solve_bvp (the friction and sliding models)")
    run.add_argument("--executor", choices=("local", "dask"), default="local",
                     help="local: one run after another here; dask: on dask.distributed (default local)")
    run.add_argument("--scheduler", metavar="ADDRESS",
                     help="with --executor dask: an existing scheduler (default: a LocalCluster)")
    run.add_argument("--workers", type=integer(1), help="with --executor dask and no --scheduler: LocalCluster workers (default: CPUs)")
    run.add_argument("--max-iter", type=integer(0), help="iteration budget per run (default: the suite's)")
    run.add_argument("--time-limit", type=positive_float, metavar="SECONDS", help="wall-time limit per run (default: the suite's)")
    run.add_argument("--resume", action="store_true", help="keep the rows already in --out and run the rest")
    run.add_argument("--out", default="qdframe-bench", metavar="DIR", help="output directory (default ./qdframe-bench)")
    run.add_argument("--quiet", action="store_true", help="print nothing but errors")
    return run


def main_run(args: argparse.Namespace, argv: Sequence[str] | None = None) -> int:
    """Run `qdframe bench run` with parsed `args`."""
    if args.scheduler and args.executor != "dask":
        raise InputError("--scheduler", "to be used with --executor dask", args.scheduler)
    sweep = plan(
        suite=args.suite,
        models=args.models,
        directions=args.directions,
        line_searches=args.line_searches,
        nodes=args.nodes,
        peers=args.peers,
        max_iter=args.max_iter,
        time_limit_s=args.time_limit,
        accuracy=args.accuracy,
        bvp_tols=args.bvp_tols,
    )
    say = None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True))
    command = "qdframe bench run " + " ".join(shlex.quote(a) for a in (argv if argv is not None else _echo(args)))
    if say:
        models = sweep.settings["models"]
        say(f"{len(sweep.cases)} runs: {len(models)} models × directions {', '.join(sweep.settings['directions'])} "
            f"× N = {', '.join(map(str, sweep.settings['nodes']))}"
            + (f" and accuracy= {', '.join(f'{e:g}' for e in sweep.settings['accuracy'])}" if sweep.settings['accuracy'] else "")
            + (" + peers" if args.peers else ""))
        for name, why in sweep.skipped.items():
            say(f"skipped direction {name}: {why}")
        if args.peers and not any(case.peer for case in sweep.cases):
            say("--peers: no model of the sweep is one the peers can state")
    try:
        outcome = run_sweep(sweep, args.out, resume=args.resume, executor=args.executor, scheduler=args.scheduler,
                            workers=args.workers, progress=say, command=command)
    except KeyboardInterrupt:
        print(f"qdframe: interrupted; the finished runs are in {args.out}: add --resume to continue",
              file=sys.stderr)
        return 130
    references = {name: cross_check(name) for name in sorted({r["model"] for r in outcome.rows})}
    paths = write_report(outcome.rows, outcome.meta, args.out, seconds=outcome.seconds, references=references)
    if not args.quiet:
        print(time_table(outcome.rows))
        if any(case.peer for case in sweep.cases):
            print("\n" + ratio_table(outcome.rows))
        print("\n" + summary_table(outcome.rows, sweep.settings["time_limit_s"]))
        print(f"\n{outcome.ran} runs in {outcome.seconds:.1f} s ({outcome.resumed} resumed); "
              f"{paths['report']}, {paths['work_precision']}, results.csv, results.json in {args.out}")
    return 0


def _echo(args: argparse.Namespace) -> list[str]:
    """The options of `args` as a command line (for the report)."""
    words = ["--suite", args.suite]
    for flag, value in (("--models", args.models), ("--directions", args.directions),
                        ("--line-searches", args.line_searches)):
        if value:
            words += [flag, ",".join(value)]
    if args.nodes:
        words += ["--nodes", ",".join(map(str, args.nodes))]
    for flag, value in (("--accuracy", args.accuracy), ("--bvp-tols", args.bvp_tols)):
        if value is not None:
            words += [flag, ",".join(f"{e:g}" for e in value) or "none"]
    words += ["--peers"] if args.peers else []
    if args.executor != "local":
        words += ["--executor", args.executor]
    if args.scheduler:
        words += ["--scheduler", args.scheduler]
    if args.workers:
        words += ["--workers", str(args.workers)]
    if args.max_iter is not None:
        words += ["--max-iter", str(args.max_iter)]
    if args.time_limit is not None:
        words += ["--time-limit", f"{args.time_limit:g}"]
    words += ["--resume"] if args.resume else []
    words += ["--out", args.out]
    return words
