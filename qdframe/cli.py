"""The `qdframe` command (README, "The command line"): `list`, `solve` and `simulate`.

Bad input ends with one line naming the field and the expected form: exit status 2
for usage errors, 1 for failures, and a traceback only with --debug.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import numpy as np

from . import __version__
from .argtypes import (
    boundary_vector, continuation, finite_float, integer, key_value, names, node_counts, positive_float, vector,
)
from .benchmarks.cli import add_run_parser, main_run
from .authoring.check import add_check_parser, main_check
from .errors import InputError, QdframeError
from .registry import GROUPS, KIND_LABEL, PluginWarning, available


class _UsageError(Exception):
    """A command-line usage error, already formatted as one line."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit status 2)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise _UsageError(f"{self.prog}: error: {message}")

def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="qdframe", description="Trajectories of nonsmooth differential inclusions.")
    parser.add_argument("--version", action="version", version=f"qdframe {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks (anywhere on the command line)")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    lister = commands.add_parser("list", help="registered models, directions and line searches")
    lister.add_argument("--json", nargs="?", const="-", metavar="FILE", help="write JSON (to stdout without FILE)")

    solve = commands.add_parser("solve", help="solve a model by quasidifferential descent")
    solve.add_argument("model", help="model name (see `qdframe list`)")
    solve.add_argument("--direction", default="gauss-newton",
                       help="direction solver (default: gauss-newton; the paper's method: native)")
    solve.add_argument("--option", action="append", type=key_value, metavar="KEY=VALUE",
                       help="set a direction option, e.g. --option mu=1e-8 (repeatable; unknown keys list the known)")
    solve.add_argument("--line-search", help="line search (default: the direction's: armijo for gauss-newton, golden for native)")
    solve.add_argument("--nodes", type=integer(2), help="grid nodes N ≥ 2 (default 101; with --accuracy, 21: the first mesh)")
    solve.add_argument("--max-iter", type=integer(0), default=500, help="iteration budget (default 500)")
    solve.add_argument("--continuation", type=continuation, metavar="auto|none|N,N,..",
                       help="coarser grids to solve on first, e.g. 11,101; auto: 11, 101, ... below N "
                            "(default: the direction's: auto for the paper's method, none for gauss-newton)")
    solve.add_argument("--tol", type=positive_float, help="stop `solved` when I ≤ tol (default: the model's)")
    solve.add_argument("--delta", type=positive_float, default=1e-3, help="δ of δ-active pieces (default 1e-3)")
    solve.add_argument("--eps", type=positive_float, default=1e-2, help="stationarity ε (default 1e-2)")
    solve.add_argument("--gamma-max", type=positive_float, default=1.0, help="line-search bound γ̄ (default 1)")
    solve.add_argument("--T", type=positive_float, help="final time (overrides the model's)")
    solve.add_argument("--x0", type=boundary_vector, help="initial state V,V,... (overrides the model's); free: not given")
    solve.add_argument("--xT", type=boundary_vector,
                       help="end values of the model's fixed coordinates J, in order; or all n, free where not given")
    solve.add_argument("--periodic", type=names, metavar="I,I,..", help="coordinates (names or indices) with x(T) = x(0)")
    solve.add_argument("--scheme", help="discretization: implicit-euler, radau-iia (odd N), trapezoid "
                                        "(default: the model's, implicit-euler unless it says otherwise)")
    solve.add_argument("--signs", choices=("exact", "band"), default="exact",
                       help="sign terms a·Sgn(s): exact selections λ ∈ Sgn(s) (default) or the C¹ band")
    solve.add_argument("--selection-scale", type=positive_float, default=1.0, help="c of the natural map (default 1)")
    solve.add_argument("--residual-tol", type=positive_float, default=1e-8,
                       help="`solved` needs every pointwise residual ≤ this (default 1e-8)")
    solve.add_argument("--accuracy", type=positive_float,
                       help="refine the mesh (switch times located) until the error estimate is ≤ this "
                            "(scheme default radau-iia)")
    solve.add_argument("--max-nodes", type=integer(3), default=100_001,
                       help="the most points --accuracy may use (default 100001)")
    solve.add_argument("--no-estimate", action="store_true",
                       help="skip the error estimate (a second solve on the bisected mesh)")
    solve.add_argument("--json", metavar="FILE", help="write the result as JSON (- : to stdout, the summary to stderr)")
    solve.add_argument("--plot", metavar="FILE", help="write a figure (PNG, PDF or SVG)")
    solve.add_argument("--quiet", action="store_true", help="print nothing but errors")

    simulate = commands.add_parser("simulate", help="Filippov initial-value simulation of a model")
    simulate.add_argument("model", help="model name (see `qdframe list`)")
    simulate.add_argument("--from", dest="t_start", type=finite_float, required=True, help="start time T0")
    simulate.add_argument("--to", dest="t_end", type=finite_float, required=True, help="end time T1 > T0")
    simulate.add_argument("--x0", type=vector, required=True, help="state at T0: V,V,... (write --x0=-1,1 for a leading minus)")
    simulate.add_argument("--u", type=vector, help="constant controls (default 0)")
    simulate.add_argument("--dt", type=positive_float, default=1e-4, help="time step (default 1e-4)")
    simulate.add_argument("--json", metavar="FILE", help="write the trajectory as JSON")
    simulate.add_argument("--quiet", action="store_true", help="print nothing but errors")

    bench = commands.add_parser("bench", help="benchmarks")
    benches = bench.add_subparsers(dest="bench_command", required=True, parser_class=_Parser)
    bench_directions = benches.add_parser(
        "directions", help="time every installed min-norm direction backend against native"
    )
    bench_directions.add_argument("--nodes", type=integer(2), default=1001, help="grid nodes N ≥ 2 (default 1001)")
    bench_directions.add_argument("--repeat", type=integer(1), default=3, help="timed passes R ≥ 1 (default 3)")
    bench_directions.add_argument("--directions", metavar="NAME,NAME,..", help="only these directions (default: all installed)")
    bench_directions.add_argument("--json", metavar="FILE", help="write the report as JSON")
    bench_directions.add_argument("--quiet", action="store_true", help="print nothing but errors")
    benches.add_parser("hard", help="the hard-case suite: what each case measured")
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
    bench_scale.add_argument("--json", metavar="FILE", help="write the cells and exponents as JSON")
    add_run_parser(benches)

    add_check_parser(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in argv  # a global option, accepted anywhere on the line
    with warnings.catch_warnings():  # a broken plugin: one line, once
        warnings.simplefilter("once", PluginWarning)
        show = warnings.showwarning

        def one_line(message, category, *args, **kwargs) -> None:
            if issubclass(category, PluginWarning):
                print(f"qdframe: warning: {message}", file=sys.stderr)
            else:
                show(message, category, *args, **kwargs)

        warnings.showwarning = one_line
        return _main(argv, debug)


def _main(argv: list[str], debug: bool) -> int:
    try:
        args = build_parser().parse_args([a for a in argv if a != "--debug"])
        if args.command == "list":
            return _list(args)
        if args.command == "simulate":
            return _simulate(args)
        if args.command == "bench":
            commands = {"run": main_run, "hard": lambda _args: _bench_hard(), "directions": _bench_directions,
                        "friction": _bench_friction, "accuracy": _bench_accuracy, "scale": _bench_scale}
            return commands[args.bench_command](args)
        if args.command == "check-model":
            return main_check(args)
        return _solve(args)
    except _UsageError as exc:
        print(exc, file=sys.stderr)
        return 2
    except InputError as exc:
        if debug:
            raise
        print(f"qdframe: error: {exc}", file=sys.stderr)
        return 2
    except QdframeError as exc:
        if debug:
            raise
        print(f"qdframe: error: {exc}", file=sys.stderr)
        return 1


def _list(args: argparse.Namespace) -> int:
    listing = {
        kind: [
            {"name": e.name, "distribution": e.distribution, "description": e.description}
            for e in sorted(available(kind).values(), key=lambda e: e.name)
        ]
        for kind in GROUPS
    }
    if args.json is not None:
        text = json.dumps(listing, indent=1)
        if args.json == "-":
            print(text)
        else:
            _writable("--json", args.json)
            Path(args.json).write_text(text + "\n")
        return 0
    for kind, entries in listing.items():
        print(f"{kind}:")
        width = max((len(e["name"]) for e in entries), default=0)
        for e in entries:
            print(f"  {e['name']:<{width}}  [{e['distribution']}]  {e['description']}")
    return 0


def _solve(args: argparse.Namespace) -> int:
    from .descent import load_model, make_direction, solve
    from .directions.base import with_options

    to_stdout = args.json == "-"  # the JSON alone on stdout; the summary goes to stderr
    for flag in ("json", "plot"):
        if getattr(args, flag) and not (flag == "json" and to_stdout):
            _writable(f"--{flag}", getattr(args, flag))
    overrides = {"T": args.T, "x0": args.x0, "end_values": args.xT, "periodic": args.periodic}
    model = load_model(args.model, **{k: v for k, v in overrides.items() if v is not None})
    direction = with_options(make_direction(args.direction), dict(args.option or ()))
    show_progress = not args.quiet and sys.stderr.isatty()
    if show_progress:  # before the first iteration: a slow first evaluation is not a hang
        from .descent import ACCURACY_START_NODES, DEFAULT_NODES

        grid = (f"from {args.nodes or ACCURACY_START_NODES} points to accuracy {args.accuracy:g}" if args.accuracy
                else f"on {args.nodes or DEFAULT_NODES} nodes")
        print(f"solving {model.name} {grid} with {args.direction}, budget {args.max_iter} iterations …",
              end="", file=sys.stderr, flush=True)
    try:
        result = solve(
            model,
            nodes=args.nodes,
            direction=direction,
            line_search=args.line_search,
            max_iter=args.max_iter,
            tol=args.tol,
            delta=args.delta,
            eps=args.eps,
            gamma_max=args.gamma_max,
            continuation=args.continuation,
            progress=_progress_printer(args.max_iter) if show_progress else None,
            scheme=args.scheme,
            signs=args.signs,
            selection_scale=args.selection_scale,
            residual_tol=args.residual_tol,
            accuracy=args.accuracy,
            max_nodes=args.max_nodes,
            estimate=not args.no_estimate,
        )
    finally:  # end the progress line, also before an error's line
        if show_progress:
            print(file=sys.stderr)
    try:
        if to_stdout:
            print(result.to_json())
        elif args.json:
            result.to_json(args.json)
        if args.plot:
            from .plotting import plot_result

            plot_result(result, args.plot)
    except OSError as exc:
        raise QdframeError(f"could not write the output: {exc}") from None
    if not args.quiet:
        print(result.summary(), file=sys.stderr if to_stdout else sys.stdout)
    return 1 if result.status == "failed" else 0


def _simulate(args: argparse.Namespace) -> int:
    from .descent import load_model
    from .simulate import simulate

    if args.json:
        _writable("--json", args.json)
    model = load_model(args.model, x0=args.x0)
    run = simulate(model, args.t_start, args.t_end, args.x0, dt=args.dt, controls=args.u)
    if args.json:
        run.to_json(args.json)
    if not args.quiet:
        names = run.state_names
        print(f"{run.model}: t = {run.t[0]:g} → {run.t[-1]:g}, {len(run.t) - 1} steps of {run.dt:.3g}")
        print("x(T1) = " + ", ".join(f"{n} {v:.6f}" for n, v in zip(names, run.x[-1])))
    return 0


def _bench_directions(args: argparse.Namespace) -> int:
    from .bench import bench_directions, format_table, write_json

    if args.json:
        _writable("--json", args.json)
    names = None
    if args.directions is not None:
        names = [name.strip() for name in args.directions.split(",") if name.strip()]
        if not names:
            raise InputError("--directions", "comma-separated direction names like native,osqp", args.directions)
    say = None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True))
    report = bench_directions(args.nodes, repeat=args.repeat, names=names, progress=say)
    if args.json:
        write_json(report, args.json)
    if not args.quiet:
        print(format_table(report))
    failed = [row["direction"] for row in report["rows"] if row["failures"]]
    if failed:
        print(f"qdframe: error: failed calls by {', '.join(failed)} (see the table)", file=sys.stderr)
    return 1 if failed else 0


def _bench_friction(args: argparse.Namespace) -> int:
    from .benchmarks import friction

    rows = friction.run_suite(args.models or friction.SUITE, args.nodes, args.schemes or (None,), progress=True)
    print(friction.table(rows))
    return 0  # a measurement: the table says which rows are not solved


def _bench_accuracy(args: argparse.Namespace) -> int:
    from .benchmarks import accuracy

    print(accuracy.table(accuracy.run(args.models, args.targets, progress=True)))
    return 0  # a measurement: the table says which targets are not met


def _bench_scale(args: argparse.Namespace) -> int:
    from .benchmarks import scale

    if args.json:
        _writable("--json", args.json)
    cells = scale.run(args.paths or scale.PATHS, args.models or scale.MODELS, args.nodes or scale.NODES,
                      args.iterations, progress=lambda text: print(text, file=sys.stderr, flush=True))
    if args.json:
        Path(args.json).write_text(json.dumps(scale.to_json(cells), indent=1) + "\n")
    print(scale.table(cells))
    return 1 if any(cell.error for cell in cells) else 0


def _bench_hard() -> int:
    from . import hard

    results = hard.run(progress=True)
    print(hard.table(results))
    return 0 if all(r.passed for r in results) else 1


def _progress_printer(budget: int):
    """One line on stderr, rewritten per iteration: elapsed time and the budget left."""

    def show(record) -> None:
        print(
            f"\r\033[Kiteration {record.iteration:5d} of {budget}   {record.time_s:7.2f} s   "
            f"objective {record.objective:.3e}   I {record.I:.3e}   step {record.step:.2e}   N {record.nodes}",
            end="",
            file=sys.stderr,
            flush=True,
        )

    return show


def _writable(field: str, path: str) -> None:
    """Fail early, with one line, if `path` cannot be written (tries to open it)."""
    target = Path(path).expanduser()
    existed = target.exists()
    try:
        if target.is_dir():
            raise IsADirectoryError(path)
        with open(target, "a"):
            pass
    except OSError:
        raise InputError(field, "a file path in an existing, writable directory", path) from None
    if not existed:
        target.unlink(missing_ok=True)


if __name__ == "__main__":
    sys.exit(main())
