"""`qdframe bench …`: every benchmark subcommand, its arguments and what it runs.

``add_bench_parser(commands, parser_class)`` adds ``bench`` and its subcommands
(directions, hard, friction, accuracy, scale, unknowns, certificates, time-optimal, pages, run) to the ``qdframe`` parser, and
``main_bench(args, argv)`` runs the one chosen. Argument types and checks are the
command line's own (:mod:`qdframe.argtypes`).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from ..argtypes import counts, integer, names, node_counts, positive_float, tolerances, vector, writable
from ..errors import InputError
from ..registry import make_peer
from .cases import SUITES

OCP_SUITE = "ocp"  # `bench run --suite ocp`: qdframe.bench.ocp, judged on cost


def add_bench_parser(commands, parser_class: type[argparse.ArgumentParser]) -> None:
    """Add `bench` and its subcommands to the subparsers `commands` of `qdframe`."""
    bench = commands.add_parser("bench", help="benchmarks")
    benches = bench.add_subparsers(dest="bench_command", required=True, parser_class=parser_class)
    bench_directions = benches.add_parser(
        "directions", help="time every installed min-norm direction backend against native"
    )
    bench_directions.add_argument("--nodes", type=integer(2), default=1001, help="grid nodes N ≥ 2 (default 1001)")
    bench_directions.add_argument("--repeat", type=integer(1), default=3, help="timed passes R ≥ 1 (default 3)")
    bench_directions.add_argument("--directions", type=names, metavar="NAME,NAME,..", help="only these directions (default: all installed)")
    bench_directions.add_argument("--json", metavar="FILE", help="write the report as JSON")
    bench_directions.add_argument("--quiet", action="store_true", help="print nothing but errors")
    benches.add_parser("hard", help="the hard-case suite: what each case measured")
    pages = benches.add_parser("pages", help="rewrite the benchmark tables of README.md and docs/benchmark-results.md "
                                             "from docs/bench/quick and docs/bench/standard")
    pages.add_argument("--root", default=".", metavar="DIR", help="the project checkout (default .)")
    pages.add_argument("--check", action="store_true", help="write nothing; exit 1 when a page differs from its reports")
    bench_friction = benches.add_parser(
        "friction", help="the stick/slide/switch suite: status, iterations, time, strict residual, error and order per N"
    )
    bench_friction.add_argument("--nodes", type=node_counts, default=(101, 1001, 10001), metavar="N,N,..",
                                help="grids (default 101,1001,10001)")
    bench_friction.add_argument("--schemes", type=names, metavar="NAME,NAME,..",
                                help="schemes (default: each model's own)")
    bench_friction.add_argument("--models", type=names, metavar="NAME,NAME,..", help="models (default: the suite)")
    bench_accuracy = benches.add_parser("accuracy", help="nodes and time to a true error: uniform grids against accuracy=")
    bench_accuracy.add_argument("--models", type=names, metavar="NAME,NAME,..",
                                help="models (default: every one with an exact solution)")
    bench_accuracy.add_argument("--targets", type=vector, default=(1e-4, 1e-6), metavar="E,E,..",
                                help="true errors to reach (default 1e-4,1e-6)")
    bench_scale = benches.add_parser(
        "scale", help="seconds per iteration against N, against the floor (one KKT factorization + one model "
        "evaluation), the fitted exponent and peak memory")
    bench_scale.add_argument("--paths", type=names, metavar="NAME,NAME,..",
                             help="directions, each with its own line search (default gauss-newton,native)")
    bench_scale.add_argument("--models", type=names, metavar="NAME,NAME,..",
                             help="models (default paper-7.1,paper-7.2,paper-7.3)")
    bench_scale.add_argument("--nodes", type=node_counts, metavar="N,N,..", help="grids (default 1001,10001,100001)")
    bench_scale.add_argument("--iterations", type=integer(1), default=3, help="iterations timed per cell (default 3)")
    bench_scale.add_argument("--repeat", type=integer(1), default=1,
                             help="processes measuring each cell: the least s/iter and floor are kept (default 1)")
    bench_scale.add_argument("--json", metavar="FILE", help="write the cells and exponents as JSON")
    bench_unknowns = benches.add_parser(
        "unknowns", help="seconds per Newton iteration with T or parameters unknown against the same model with "
                         "them fixed")
    bench_unknowns.add_argument("--models", type=names, metavar="NAME,NAME,..",
                                help="models with unknowns (default block-friction-coefficient,block-stopping-time)")
    bench_unknowns.add_argument("--nodes", type=node_counts, metavar="N,N,..", help="grids (default 10001,100001)")
    bench_certificates = benches.add_parser(
        "certificates", help="the default call and fixed grids per model: the solve's seconds, the certificate's, "
        "peak memory")
    bench_certificates.add_argument("--models", type=names, metavar="NAME,NAME,..",
                                    help="models (default: every registered one)")
    bench_certificates.add_argument("--nodes", type=node_counts, metavar="N,N,..",
                                    help="fixed grids (default 10001,100001)")
    bench_certificates.add_argument("--blocks", type=counts, default=(), metavar="K,K,..",
                                    help="also the default call on K independent Coulomb blocks (none by default)")
    bench_certificates.add_argument("--out", metavar="DIR", help="write results.csv and report.md into DIR")
    bench_certificates.add_argument("--timeout", type=positive_float, default=300.0,
                                    help="seconds a cell may take, else it is recorded as timed out (default 300)")
    _add_time_optimal_parser(benches)
    _add_run_parser(benches)


def _add_time_optimal_parser(bench_subparsers) -> argparse.ArgumentParser:
    """Add `time-optimal` to the subparsers of `qdframe bench`; returns its parser."""
    parser = bench_subparsers.add_parser(
        "time-optimal", help="block-time-optimal (T free) by qdframe and by nosnoc's time-optimal statement: wall "
                             "time, T, |T − T*| and the trajectory's error, side by side")
    parser.add_argument("--accuracy", type=tolerances, default=(1e-3,), metavar="E,..",
                        help="qdframe's accuracy= runs besides the default call (default 1e-3; 'none' for none)")
    parser.add_argument("--formulations", type=names, default=("global", "local"), metavar="NAME,..",
                        help="nosnoc's speed of time: global (one s), local (one per control stage) (default both)")
    parser.add_argument("--stages", type=counts, default=(10, 20), metavar="K,..",
                        help="nosnoc's control stages (default 10,20)")
    parser.add_argument("--elements", type=counts, default=(10, 20, 40, 80), metavar="M,..",
                        help="nosnoc's finite elements in all, split evenly over the stages; a total below the "
                             "stages or not a multiple of them is skipped (default 10,20,40,80)")
    parser.add_argument("--out", default="docs/bench/time-optimal", metavar="DIR",
                        help="where report.md and results.csv go (default docs/bench/time-optimal)")
    return parser


def _add_run_parser(bench_subparsers) -> argparse.ArgumentParser:
    """Add `run` to the subparsers of `qdframe bench`; returns its parser."""
    run = bench_subparsers.add_parser(
        "run",
        help="work-precision sweep: each solver's accuracy knob, every run judged against a reference solution",
        description="Run a sweep and write results.csv, results.json (with histories), work-precision diagrams "
        "and report.md into --out, row by row (--resume continues an interrupted sweep). Every run's error is "
        "measured against the model's reference solution on the run's own time grid.",
    )
    run.add_argument("--suite", choices=sorted([*SUITES, OCP_SUITE]), default="quick",
                     help="quick (the tests run it, a minute or two): 5 models, gauss-newton to N = 161, accuracy= 1e-3 and the "
                     "default call (1e-6), "
                     "native to N = 41; standard: the paper's, plugin, friction, peer, T = 100 and users' friction models, "
                     "gauss-newton to N = 100001 and accuracy= to 1e-8; full: standard with every direction "
                     "and line search; ocp: the optimal-control problems, qdframe's default call and accuracy= 1e-3, "
                     "1e-8, nosnoc (--peers) at 10, 20, 30, 40 control stages, every run judged by the cost of its "
                     "control replayed (report.md, results.csv)")
    run.add_argument("--models", type=names, metavar="NAME,..", help="only these models (default: the suite's)")
    run.add_argument("--directions", type=names, metavar="NAME,..",
                     help="only these directions (default: the suite's); 'all': every installed direction and "
                          "gauss-newton with every step-QP backend (gauss-newton[qp=NAME]), each run to the certified "
                          "answer (accuracy= 1e-3 and 1e-6)")
    run.add_argument("--line-searches", type=names, metavar="NAME,..",
                     help="every direction with each of these (default: each direction's own; full: all)")
    run.add_argument("--nodes", type=node_counts, metavar="N,..", help="every solver's grids (default: the suite's)")
    run.add_argument("--accuracy", type=tolerances, metavar="E,..",
                     help="gauss-newton's accuracy= targets, each with a row for qdframe.solve(model) as a user calls it "
                          "(default: the suite's; 'none' for none, and no default row)")
    run.add_argument("--bvp-tols", type=tolerances, metavar="E,..",
                     help="the tol ladder of the peers whose knob is a tolerance, solve_bvp's (default: the "
                          "suite's; 'none' for none)")
    run.add_argument("--peers", action="store_true",
                     help="also run the registered peers (qdframe list) on the models they can state: nosnoc "
                     "(the friction and sliding models, and the problems with a bounded input), scipy's solve_bvp "
                     "(the friction and sliding models) and any plugin's")
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


def main_bench(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """Run the `qdframe bench` subcommand of `args`; `argv` is the command line (for reports)."""
    if args.bench_command == "run":
        return _run(args, argv)
    if args.bench_command == "time-optimal":
        return _time_optimal(args, argv)
    return {"directions": _directions, "hard": _hard, "friction": _friction, "accuracy": _accuracy,
            "scale": _scale, "pages": _pages, "unknowns": _unknowns,
            "certificates": lambda parsed: _certificates(parsed, argv)}[args.bench_command](args)


def _pages(args: argparse.Namespace) -> int:
    from .pages import PAGES, SUITES as REPORTS, update

    root = Path(args.root)
    missing = [str(root / p) for p in PAGES if not (root / p).is_file()]
    folders = (*REPORTS, "certificates", "ocp")
    missing += [str(root / "docs" / "bench" / s / "results.csv") for s in folders
                if not (root / "docs" / "bench" / s / "results.csv").is_file()]
    if missing:
        raise InputError("--root", "a qdframe checkout with README.md, docs/benchmark-results.md and "
                                   f"docs/bench/{{{','.join(folders)}}}/results.csv", f"{root} (missing {missing[0]})")
    changed = update(root, check=args.check)
    for path in changed:
        print(f"{path}: {'differs from its reports' if args.check else 'rewritten'}")
    if not changed:
        print("the pages' benchmark tables are their reports'")
    return 1 if changed and args.check else 0


def _say(quiet: bool = False):
    """Progress lines on stderr (None when quiet)."""
    return None if quiet else (lambda text: print(text, file=sys.stderr, flush=True))


def _directions(args: argparse.Namespace) -> int:
    from .compare_directions import bench_directions, format_table, write_json

    if args.json:
        writable("--json", args.json)
    report = bench_directions(args.nodes, repeat=args.repeat, names=args.directions, progress=_say(args.quiet))
    if args.json:
        write_json(report, args.json)
    if not args.quiet:
        print(format_table(report))
    failed = [row["direction"] for row in report["rows"] if row["failures"]]
    if failed:
        print(f"qdframe: error: failed calls by {', '.join(failed)} (see the table)", file=sys.stderr)
    return 1 if failed else 0


def _hard(args: argparse.Namespace) -> int:
    from . import hard

    results = hard.run(progress=True)
    print(hard.table(results))
    return 0 if all(r.passed for r in results) else 1


def _friction(args: argparse.Namespace) -> int:
    from . import friction

    rows = friction.run_suite(args.models or friction.SUITE, args.nodes, args.schemes or (None,), progress=True)
    print(friction.table(rows))
    return 0  # a measurement: the table says which rows are not solved


def _accuracy(args: argparse.Namespace) -> int:
    from . import accuracy

    print(accuracy.table(accuracy.run(args.models, args.targets, progress=True)))
    return 0  # a measurement: the table says which targets are not met


def _scale(args: argparse.Namespace) -> int:
    from . import scale

    if args.json:
        writable("--json", args.json)
    cells = scale.run(args.paths or scale.PATHS, args.models or scale.MODELS, args.nodes or scale.NODES,
                      args.iterations, progress=_say(), repeat=args.repeat)
    if args.json:
        Path(args.json).write_text(json.dumps(scale.to_json(cells), indent=1) + "\n")
    print(scale.table(cells))
    return 1 if any(cell.error for cell in cells) else 0


def _certificates(args: argparse.Namespace, argv: Sequence[str]) -> int:
    from . import certificate_cost

    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise InputError("--out", "a directory (made if missing)", args.out)
    rows = certificate_cost.run(args.models, args.nodes or certificate_cost.NODES, args.blocks, progress=_say(),
                                timeout=args.timeout)
    if args.out:
        certificate_cost.write(rows, args.out, shlex.join(["qdframe", *argv]))
    print(certificate_cost.summary(rows))
    print(certificate_cost.table(rows))
    return 1 if any(row["status"] in ("error", "timed out") for row in rows) else 0


def _unknowns(args: argparse.Namespace) -> int:
    from . import unknown_cost

    print(unknown_cost.table(unknown_cost.run(args.models or unknown_cost.MODELS, args.nodes or unknown_cost.NODES,
                                              progress=_say())))
    return 0  # a measurement


def _report_folder(out: str) -> None:
    """--out made and its report.md writable, before the runs (a measurement must not fail after them)."""
    try:
        Path(out).mkdir(parents=True, exist_ok=True)
    except OSError:
        raise InputError("--out", "a folder that can be made and written", out) from None
    writable("--out", str(Path(out) / "report.md"))


def _time_optimal(args: argparse.Namespace, argv: Sequence[str]) -> int:
    import time

    from . import time_optimal
    from .nosnoc_time_optimal import FORMULATIONS

    unknown = [name for name in args.formulations if name not in FORMULATIONS]
    if unknown:
        raise InputError("--formulations", f"some of {', '.join(FORMULATIONS)}", ",".join(unknown))
    _report_folder(args.out)
    start = time.perf_counter()
    rows = time_optimal.run(args.accuracy, args.formulations, args.stages, args.elements, progress=_say())
    paths = time_optimal.write_report(rows, args.out, shlex.join(["qdframe", *argv]), time.perf_counter() - start)
    print(time_optimal.table(rows))
    print(f"\n{paths['report']}, {paths['results']}")
    return 0  # a measurement: the table gives each run's status


def _ocp(args: argparse.Namespace, argv: Sequence[str]) -> int:
    """`bench run --suite ocp` (:mod:`.ocp`): the options of the other suites' sweeps do not apply."""
    import time

    from . import ocp
    from .ocp_problems import PROBLEMS

    for option in ("directions", "line_searches", "nodes", "bvp_tols", "scheduler", "workers", "max_iter",
                   "time_limit"):
        if getattr(args, option) is not None:
            raise InputError("--" + option.replace("_", "-"), "not given with --suite ocp (its runs are fixed: "
                             "docs/benchmarks.md)", getattr(args, option))
    if args.executor != "local" or args.resume:
        raise InputError("--executor" if args.executor != "local" else "--resume", "not given with --suite ocp",
                         args.executor if args.executor != "local" else True)
    unknown = [name for name in args.models or () if name not in PROBLEMS]
    if unknown:
        raise InputError("--models", f"some of {', '.join(PROBLEMS)} with --suite ocp", ",".join(unknown))
    _report_folder(args.out)
    start = time.perf_counter()
    rows = ocp.run(args.models, ocp.ACCURACY if args.accuracy is None else args.accuracy, peers=args.peers,
                   progress=_say(args.quiet))
    paths = ocp.write_report(rows, args.out, shlex.join(["qdframe", *argv]), time.perf_counter() - start)
    if not args.quiet:
        print(ocp.work_precision(rows) + "\n\n" + ocp.table(rows))
        print(f"\n{paths['report']}, {paths['results']}")
    return 0  # a measurement: the tables give each run's status and cost


def _run(args: argparse.Namespace, argv: Sequence[str]) -> int:
    if args.suite == OCP_SUITE:
        return _ocp(args, argv)
    from .references import cross_check
    from .report import ranking, ratio_table, time_table, write_report
    from .cases import plan
    from .run import run_sweep

    if args.scheduler and args.executor != "dask":
        raise InputError("--scheduler", "to be used with --executor dask", args.scheduler)
    options = ("suite", "models", "directions", "line_searches", "nodes", "peers", "max_iter", "accuracy", "bvp_tols")
    sweep = plan(time_limit_s=args.time_limit, **{name: getattr(args, name) for name in options})
    say = _say(args.quiet)
    command = shlex.join(["qdframe", *argv])
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
    for name in sorted({case.peer for case in sweep.cases if case.peer}):  # said even with --quiet
        reason = make_peer(name).unavailable()
        if reason is not None:
            print(f"qdframe: peer {name} is not available here ({reason}); its runs are recorded `failed`",
                  file=sys.stderr)
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
        print("\n" + ranking(outcome.rows, sweep.settings["time_limit_s"]))
        print(f"\n{outcome.ran} runs in {outcome.seconds:.1f} s ({outcome.resumed} resumed); "
              f"{paths['report']}, {paths['work_precision']}, results.csv, results.json in {args.out}")
    return 0
