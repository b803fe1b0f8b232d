"""The `qdframe` command (README, "The command line"): `list`, `solve` and `simulate`.

Bad input ends with one line naming the field and the expected form (exit status 2),
an error that stops a run without a result with one line too (exit status 1), and
`solve` exits with the code of its result's status (:data:`qdframe.status.EXIT_CODES`).
--debug adds the traceback and keeps the exit status.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import traceback
import warnings
from pathlib import Path

import numpy as np

from . import __version__
from .argtypes import (
    boundary_vector, continuation, figure_format, finite_float, integer, key_value, names, node_counts, parameter_guess,
    positive_float,
    vector, writable,
)
from .authoring.check import add_check_parser, main_check
from .bench.commands import add_bench_parser, main_bench
from .errors import InputError, QdframeError
from .registry import GROUPS, KIND_LABEL, PluginWarning, available, lookup
from .status import EXIT_CODES, EXIT_ERROR, EXIT_USAGE, Status


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

    lister = commands.add_parser("list", help="registered models, schemes, directions and line searches")
    lister.add_argument("--json", nargs="?", const="-", metavar="FILE", help="write JSON (to stdout without FILE)")

    solve = commands.add_parser("solve", help="solve a model by quasidifferential descent", epilog=_exit_codes(),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    solve.add_argument("model", help="model name (see `qdframe list`)")
    solve.add_argument("--direction", default="gauss-newton",
                       help="direction solver (default: gauss-newton; the paper's method: native)")
    solve.add_argument("--option", action="append", type=key_value, metavar="KEY=VALUE",
                       help="set a direction option, e.g. --option mu=1e-8 (repeatable; unknown keys list the known)")
    solve.add_argument("--line-search", help="line search (default: the direction's: armijo for gauss-newton, golden for native)")
    solve.add_argument("--nodes", type=integer(2),
                       help="a fixed grid of N ≥ 2 points, `solved` when its error estimate meets 1e-6 (without "
                            "--nodes: the mesh is refined to --accuracy from 21 points; with --accuracy: the first mesh)")
    solve.add_argument("--max-iter", type=integer(0),
                       help="iteration budget (default 500; to an accuracy, the direction's: 5000 for the paper's "
                            "min-norm directions)")
    solve.add_argument("--continuation", type=continuation, metavar="auto|none|N,N,..",
                       help="coarser grids to solve on first, e.g. 11,101; auto: the direction's ladder below N "
                            "(gauss-newton 101, 301, 1001, 3001, ...; the paper's method 11, 101, 1001, ...); "
                            "none: N alone (default: auto)")
    solve.add_argument("--tol", type=positive_float, help="stop `solved` when I ≤ tol (default: the model's)")
    solve.add_argument("--delta", type=positive_float, default=1e-3, help="δ of δ-active pieces (default 1e-3)")
    solve.add_argument("--eps", type=positive_float, default=1e-2, help="stationarity ε (default 1e-2)")
    solve.add_argument("--eps-floor", type=positive_float,
                       help="the paper's directions: ε and δ shrink by 10 where ε-stationary but not solved, down to "
                            "this (default: 1e-12 when the mesh is refined to the target; with --nodes, ε: fixed)")
    solve.add_argument("--gamma-max", type=positive_float, default=1.0, help="line-search bound γ̄ (default 1)")
    solve.add_argument("--T", type=positive_float, help="final time (overrides the model's)")
    solve.add_argument("--x0", type=boundary_vector, help="initial state V,V,... (overrides the model's); free: not given")
    solve.add_argument("--xT", type=boundary_vector,
                       help="end values of the model's fixed coordinates J, in order; or all n, free where not given")
    solve.add_argument("--periodic", type=names, metavar="I,I,..", help="coordinates (names or indices) with x(T) = x(0)")
    free = solve.add_mutually_exclusive_group()
    free.add_argument("--free-T", dest="free_T", action="store_const", const=True,
                      help="find T with x (a stopping time, a period), starting from --T or the model's T; "
                           "result.T is the T found")
    free.add_argument("--fixed-T", dest="free_T", action="store_const", const=False,
                      help="keep T fixed where the model leaves it free")
    solve.add_argument("--parameter", action="append", type=parameter_guess, metavar="NAME=GUESS",
                       help="starting guess of one of the model's unknown parameters (repeatable; "
                            "`qdframe list` shows them); result.parameters holds the values found")
    solve.add_argument("--scheme", help="discretization: implicit-euler, radau-iia (odd N), trapezoid "
                                        "(default: the model's, implicit-euler unless it says otherwise)")
    solve.add_argument("--signs", choices=("exact", "band"), default="exact",
                       help="sign terms a·Sgn(s): exact selections λ ∈ Sgn(s) (default) or the C¹ band")
    solve.add_argument("--inputs", choices=("held", "free"), default="held",
                       help="the choice in each fixed set (a bounded input): held on each mesh interval's "
                            "stages (default) or free at every point")
    solve.add_argument("--selection-scale", type=positive_float, default=1.0, help="c of the natural map (default 1)")
    solve.add_argument("--residual-tol", type=positive_float, default=None,
                       help="`solved` needs every pointwise residual ≤ this (default 1e-8, and at most "
                            "--accuracy/100)")
    solve.add_argument("--accuracy", type=positive_float,
                       help="refine the mesh (switch times located) until the error estimate is ≤ X·max(1, max|x|) "
                            "(default 1e-6 without --nodes; scheme default radau-iia)")
    solve.add_argument("--certificate", choices=("bisection", "replay"),
                       help="what makes the error estimate (default: replay where the solutions form a set or the "
                            "problem is an initial-value problem, else bisection)")
    solve.add_argument("--max-nodes", type=integer(3), default=100_001,
                       help="the most points --accuracy may use (default 100001)")
    solve.add_argument("--no-estimate", action="store_true",
                       help="skip the error estimate on a fixed grid (--nodes): the result is then at most "
                            "`uncertified`")
    solve.add_argument("--no-simulate-start", action="store_true",
                       help="start from the model's own guess, not its simulated Filippov motion (under its first "
                            "controls where it has controls)")
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

    add_bench_parser(commands, _Parser)

    add_check_parser(commands)
    return parser


EXIT_MEANINGS = {
    Status.SOLVED: "solved: certified pointwise",
    Status.UNCERTIFIED: "uncertified: the discrete problem solved, its error not certified within the target",
    Status.STATIONARY: "stationary: the descent stopped short of I = 0 (the message says where I sits)",
    Status.MAX_ITER: "max_iter: the iteration budget ran out",
    Status.FAILED: "failed: a backend reported an error mid-run",
}


def _exit_codes() -> str:
    """The epilog of `qdframe solve --help`: its exit status for each way a run ends."""
    lines = ["exit status:"]
    for status, code in sorted(EXIT_CODES.items(), key=lambda item: item[1]):
        lines.append(f"  {code}  {EXIT_MEANINGS[status]}")
        if status is Status.SOLVED:
            lines.append(f"  {EXIT_ERROR}  an error stopped the run without a result (e.g. the model returned NaN)")
            lines.append(f"  {EXIT_USAGE}  bad input (one line names the field and the expected form), or a plugin's own code "
                         "raised (one line names the plugin, the method and the line)")
    return "\n".join(lines)


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
            return main_bench(args, [a for a in argv if a != "--debug"])
        if args.command == "check-model":
            return main_check(args)
        return _solve(args)
    except BrokenPipeError:  # `qdframe solve … | head`: the reader has what it wanted
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error when Python flushes stdout
        return 0
    except _UsageError as exc:
        return _error(str(exc), EXIT_USAGE, debug)
    except InputError as exc:
        return _error(f"qdframe: error: {exc}", EXIT_USAGE, debug)
    except QdframeError as exc:
        return _error(f"qdframe: error: {exc}", EXIT_ERROR, debug)
    except Exception as exc:  # not raised on purpose: one line all the same, the traceback with --debug
        frames = traceback.extract_tb(exc.__traceback__)
        where = f" at {frames[-1].filename}:{frames[-1].lineno}" if frames else ""
        text = " ".join(str(exc).split())
        return _error(f"qdframe: error: unexpected {type(exc).__name__}{': ' + text if text else ''}{where} "
                      "(--debug shows the traceback; please report it)", EXIT_ERROR, debug)


def _error(line: str, code: int, debug: bool) -> int:
    """Print the one error line (after the traceback with --debug) and return the exit status."""
    if debug:
        traceback.print_exc(file=sys.stderr)
    print(line, file=sys.stderr)
    return code


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
            writable("--json", args.json)
            Path(args.json).write_text(text + "\n")
        return 0
    headings = {"step_qps": "step_qps (gauss-newton's step QP: --option qp=NAME):"}
    for kind, entries in listing.items():
        print(headings.get(kind, f"{kind}:"))
        width = max((len(e["name"]) for e in entries), default=0)
        for e in entries:
            print(f"  {e['name']:<{width}}  [{e['distribution']}]  {e['description']}")
    return 0


SOLVE_OPTIONS = ("nodes", "line_search", "max_iter", "tol", "delta", "eps", "eps_floor", "gamma_max", "continuation", "scheme", "signs",
                 "selection_scale", "inputs", "residual_tol", "accuracy", "max_nodes", "certificate")
"""Options of `qdframe solve` passed to :func:`qdframe.solve` under their own names."""


def _solve(args: argparse.Namespace) -> int:
    from .solve.plan import plan
    from .solve.solving import solve
    from .registry import load_model, make_direction
    from .directions.base import with_options

    to_stdout = args.json == "-"  # the JSON alone on stdout; the summary goes to stderr
    if args.plot:  # before the solve: a format matplotlib cannot write would fail after it
        figure_format("--plot", args.plot)
    for flag in ("json", "plot"):
        if getattr(args, flag) and not (flag == "json" and to_stdout):
            writable(f"--{flag}", getattr(args, flag))
    overrides = {"T": args.T, "x0": args.x0, "end_values": args.xT, "periodic": args.periodic, "free_T": args.free_T,
                 "parameters": dict(args.parameter) if args.parameter else None}
    model = load_model(args.model, **{k: v for k, v in overrides.items() if v is not None})
    direction = with_options(make_direction(args.direction), dict(args.option or ()))
    for kind, name in (("line_searches", args.line_search), ("schemes", args.scheme)):
        if name is not None:  # a misspelled name: before the model's start is built
            lookup(kind, name)
    arguments = dict(direction=direction, estimate=not args.no_estimate, simulate_start=not args.no_simulate_start,
                     **{name: getattr(args, name) for name in SOLVE_OPTIONS})
    chosen = plan(model, **arguments)  # what the solve will run, checked: a bad value is refused before any work
    show_progress = not args.quiet and sys.stderr.isatty()
    if show_progress:  # before the first iteration: a slow first evaluation is not a hang
        print(f"solving {model.name} {chosen.describe()} with {args.direction}, budget {chosen.budget} iterations …",
              end="", file=sys.stderr, flush=True)
    try:
        result = solve(model, progress=_progress_printer(chosen.budget) if show_progress else None, **arguments)
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
    return EXIT_CODES[Status(result.status)]


def _simulate(args: argparse.Namespace) -> int:
    from .registry import load_model
    from .simulate import simulate

    if args.json:
        writable("--json", args.json)
    model = load_model(args.model, x0=args.x0)
    run = simulate(model, args.t_start, args.t_end, args.x0, dt=args.dt, controls=args.u)
    if args.json:
        run.to_json(args.json)
    if not args.quiet:
        names = run.state_names
        print(f"{run.model}: t = {run.t[0]:g} → {run.t[-1]:g}, {len(run.t) - 1} steps of {run.dt:.3g}")
        print("x(T1) = " + ", ".join(f"{n} {v:.6f}" for n, v in zip(names, run.x[-1])))
    return 0


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


if __name__ == "__main__":
    sys.exit(main())
