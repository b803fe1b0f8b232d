"""Every command the README and the docs give works verbatim on a fresh copy, and ends as
the docs say it does.

Commands are read from the Markdown itself: the lines of ``sh`` code blocks and the inline
code spans that start with ``qdframe `` or ``python examples/``. Synopses (with
``[…]``, ``NAME``, ``…`` or ``a|b``) are usage, not commands. Each command is
parsed by the real CLI parser, and each distinct one runs once (however many pages give it)
in a fresh copy of the repository (the files git tracks, copied once per session and shared
by the xdist workers), except those listed in NOT_RUN with the reason (a long measurement,
a reader's plugin, a mention in prose); installs are the CI's own job (its set-up command is
the README's). A ``qdframe solve`` runs with ``--json -`` added and must end with the status
its page states, declared in STATUSES (and exit with that status's code): a solve without
a declared status fails test_every_run_solve_declares_its_status. Where the docs state more
(a number it prints, an error, a message, a table's verdict) OUTCOMES asserts it, within
the stated bound. Every script in examples/ is run, by a docs command or by EXAMPLES at a
small size; each exits non-zero where its printed answer misses what its page states, and
OUTCOMES or EXAMPLES check what it prints.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
import types
from pathlib import Path
from typing import Callable, NamedTuple

import numpy as np
import pytest

from conftest import check_certified
from qdframe.cli import build_parser
from qdframe.status import EXIT_CODES, Status

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SYNOPSIS = re.compile(r"\[|\]|\bNAME\b|\bMODEL\b|…|\.\.\.|\w\|\w|\bD\b$")

NOT_RUN = {
    # the authoring guide's tutorial: it runs after the reader has written and installed
    # the plugin the guide builds (tests/authoring/test_plugin_authoring.py installs the guide's
    # code as a package and lists, checks and solves it through the CLI)
    "qdframe solve heated-room": "the guide's plugin, installed by its reader",
    "qdframe check-model heated-room": "the guide's plugin, installed by its reader",
    "qdframe solve heated-room --direction damped-gauss-newton --line-search shrinking": "the guide's plugin",
    "qdframe solve heated-room --scheme theta": "the guide's plugin",
    "python -m pytest -q my-models/tests": "the guide's plugin package, written by its reader",
    "qdframe solve my-pendulum": "the README's plugin, once its reader registers it",
    # a measurement of every QP backend on 10000-row batches, 3 passes: 296 s on the 2-core
    # machine (exit 0, 2026-11-23); test_bench_directions_at_a_small_size runs its code path
    "qdframe bench directions --nodes 10000 --repeat 3 --directions native,osqp,clarabel,cvxpy,qpsolvers:daqp,"
    "qpsolvers:proxqp": "a 5-minute measurement",
    # the standard work-precision suite: 269 runs up to N = 100001, about an hour on the 2-core
    # machine with two dask workers; the quick suite runs the same code (and runs here and in
    # tests/bench/test_bench_run.py)
    "qdframe bench run --suite standard --peers --executor dask --workers 2 --out standard": "an hour-long measurement",
    # every path and paper model at N = 1001, 10001, 100001: 3 min 22 s on the idle 2-core machine (2026-11-25);
    # the docs' smaller `bench scale` command runs here, and tests/bench/test_bench_scale.py
    "qdframe bench scale": "a 4-minute measurement",
    # 4 models × 2 grids up to N = 100001: 28 s on the idle 2-core machine (2026-11-26); the docs'
    # `--nodes 1001` variant runs here, and tests/bench/test_unknown_cost.py runs its code
    "qdframe bench unknowns": "a 30-second measurement",
    # the same at N = 100001 alone, each cell in three processes: 8 min 35 s (2026-11-25)
    "qdframe bench scale --nodes 100001 --repeat 3": "a 9-minute measurement",
    # paper-7.2 alone at N = 100001, both paths, three processes each: 2 min 5 s (2026-11-25)
    "qdframe bench scale --models paper-7.2 --nodes 100001 --repeat 3": "a 2-minute measurement",
    # paper-7.3 at N = 100001 from its motion: 3 iterations, uncertified (its replay stops where
    # it passes the target, at t = 0.0061), 21.5 s and 2.1 GB on the 2-core machine (2026-11-28:
    # docs/bench/certificates); the same solve at N = 101 runs in tests/test_masses_and_signs.py
    "qdframe solve paper-7.3 --nodes 100001": "a 22-second solve at 2 GB",
    # every registered model's default call and fixed grids of 1e4 and 1e5 points, and 5 block
    # counts, each in its own process: 25 minutes on the 2-core machine (2026-11-28); the docs'
    # small variant runs here
    "qdframe bench certificates": "a 25-minute measurement",
    # the optimal-control suite, five problems by qdframe and nosnoc: 82 s on the idle 2-core machine
    # (2026-11-28, docs/bench/ocp); the docs' lq-terminal variant runs here, tests/bench/test_ocp_bench.py its code
    "qdframe bench run --suite ocp --peers --out docs/bench/ocp": "a 1-minute measurement",
    "qdframe bench certificates --blocks 2,5,10,20,40 --out docs/bench/certificates": "a 25-minute measurement, "
                                                                                      "into the docs",
    # the same without the estimate: 3 iterations from 7.3's motion under u ≡ 0, 17.5 s
    # (2026-11-27); at 1001 and 10001 they run here
    "qdframe solve paper-7.3 --nodes 100001 --no-estimate": "a 20-second solve",
    # from the model's own start, up the ladder: 48 iterations, 60 s (2026-11-26); its grids up
    # to 10001 run here
    "qdframe solve paper-7.3 --nodes 100001 --no-estimate --no-simulate-start": "a 1-minute solve",
    # 7.1, 7.2 and 7.3 at N = 11, 101, 1001 with both directions: 73 s on the 2-core machine
    # (2026-11-25), most of it native's 500 iterations on 7.3; EXAMPLES runs it at N = 11, 101
    # with 100 iterations
    "python examples/compare_directions.py": "a 73-second measurement",
    # the quick work-precision suite: 2–4 minutes each; tests/bench/test_bench_run.py runs the
    # first and judges every row, and runs a sweep through the dask executor
    "qdframe bench run --suite quick --peers --out quick": "a 3-minute measurement, run by test_bench_run.py",
    "qdframe bench run --suite quick --peers --out docs/bench/quick-new": "the same measurement, into the docs",
    "qdframe bench run --suite quick --peers --executor dask --out quick-dask": "the same through dask",
    # block-time-optimal by qdframe (2 calls) and nosnoc (14 runs): 88 s on the loaded 2-core machine
    # (2026-11-26); the docs' small variant runs here, tests/bench/test_time_optimal.py runs its code
    "qdframe bench time-optimal": "a 90-second measurement",
    # the paper's method carried to a certified answer on paper-7.1: 4726 iterations, 42 s on the
    # 2-core machine (2026-11-26); tests/test_eps_shrink.py runs the ε/δ shrinking on 21 points
    "qdframe solve paper-7.1 --direction native": "a 42-second solve",
    # every direction and step-QP backend to the certified answer on the quick suite's models: 190
    # runs, 614 s on the idle 2-core machine (2026-11-26); tests/bench/test_bench_run.py plans it
    # and runs a gauss-newton[qp=osqp] row, tests/directions/test_step_qp.py every backend
    "qdframe bench run --suite quick --directions all --out docs/bench/directions-new": "a 10-minute measurement",
    # every model with an exact solution at two targets, uniform ladders to 81921 points: 3–5
    # minutes; tests/bench/test_bench_accuracy.py runs its code on one model, every step
    "qdframe bench accuracy": "a 4-minute measurement, its code run by test_bench_accuracy.py",
    # benchmarks.md's prose ("`qdframe bench run --peers` then runs it [a new peer] on every problem it
    # states"): the quick suite with its peers, 2–4 minutes, which tests/bench/test_bench_run.py runs
    "qdframe bench run --peers": "a mention in prose of the quick suite, run by test_bench_run.py",
    # sliding-mode-terminal on three grids and at accuracy 1e-3 and 1e-6: 5 min 1 s on the idle
    # 2-core machine (2026-11-24), 469 s in a loaded CI run, most of it the 1e-6 solve; the
    # README's `--accuracy 1e-3` variant runs here, the same code on every line but that solve
    "python examples/work_precision.py": "a 5-minute measurement",
}
"""Commands parsed but not run, and why."""


MENTIONS = {"qdframe check-model", "qdframe simulate", "qdframe bench run", "qdframe solve"}
"""Subcommands named in prose, not commands to run."""


def _commands(path: Path) -> list[str]:
    text = path.read_text()
    found: list[str] = []
    for block in re.findall(r"```(?:sh|bash|shell)\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            command = line.split("  #")[0].strip()
            if command:
                found.append(command)
    prose = re.sub(r"```.*?```", "", text, flags=re.S)
    for span in re.findall(r"`([^`]+)`", prose):
        command = " ".join(span.split())  # inline spans may wrap across lines
        if command.startswith(("qdframe ", "python examples/")):
            found.append(command)
    return [c for c in dict.fromkeys(found) if not SYNOPSIS.search(c) and c not in MENTIONS]


COMMANDS = sorted({(path.name, command) for path in DOCS for command in _commands(path)})
SETUP = {"python3 -m venv", ".venv/bin/python -m pytest", "pip install", "pip uninstall"}


def _is_setup(command: str) -> bool:
    return any(command.startswith(prefix) or f" {prefix}" in command for prefix in SETUP)


def test_the_docs_give_commands():
    names = [command for _, command in COMMANDS]
    assert any(c.startswith("qdframe solve") for c in names) and any(c.startswith("python examples/") for c in names)


@pytest.mark.parametrize("source, command", [c for c in COMMANDS if c[1].startswith("qdframe ")])
def test_every_qdframe_command_parses(source, command):
    build_parser().parse_args(shlex.split(command)[1:])


@pytest.fixture(scope="session")
def fresh_copy(tmp_path_factory) -> Path:
    """The files git tracks, copied: what a fresh clone holds. Made once per test session: under
    pytest-xdist the first worker to take the lock (a folder, made atomically) copies into the
    session's folder, which all its workers share, and the others wait for its mark."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # the session's folder; a worker's own is popen-gwN inside it
    target, lock, mark = base / "fresh" / "qdframe", base / "fresh.lock", base / "fresh.made"
    try:
        lock.mkdir()
    except FileExistsError:
        deadline = time.monotonic() + 600
        while not mark.exists():
            assert time.monotonic() < deadline, "the worker making the fresh copy did not finish in 10 minutes"
            time.sleep(0.2)
        assert mark.read_text() == "made", "the worker making the fresh copy failed"
        return target
    made = False
    try:
        tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
        for name in filter(None, tracked.decode().split("\0")):
            source = ROOT / name
            if source.is_file():
                (target / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(source, target / name)
        made = True
    finally:
        mark.write_text("made" if made else "failed")
    return target


RUN = [(", ".join(sorted({page for page, same in COMMANDS if same == command})), command)
       for command in sorted({command for _, command in COMMANDS}) if not _is_setup(command) and command not in NOT_RUN]
"""(pages, command): each distinct command once, however many pages give it."""


class Outcome(NamedTuple):
    """What a command left: its output, a solve's JSON (``--json -``), and its folder."""

    stdout: str
    stderr: str
    data: dict | None
    cwd: Path


S, U, ST, MI = Status.SOLVED, Status.UNCERTIFIED, Status.STATIONARY, Status.MAX_ITER
STATUSES: dict[str, Status] = {
    # README: "the figure above is this solve's --plot", captioned "paper-7.1 solved"
    "qdframe solve paper-7.1 --nodes 101 --plot docs/figures/paper-7.1.png": S,
    # README: "refined until certified"; friction.md: "without --nodes certifies it"
    "qdframe solve block-stop-stick": S,
    # README: "the μ that stops a thrown block at p = 1: 2", "`solved` covers them"
    "qdframe solve block-friction-coefficient --parameter mu=4": S,
    # README: T = 4√2 and T* = (4/3)·√1.5, "`solved` covers them"
    "qdframe solve relay-period": S,
    "qdframe solve block-time-optimal": S,
    # cli.md: "finds the period 4√2 and … finds μ = 2, both `solved`"
    "qdframe solve relay-oscillator --free-T --T 5 --periodic x1,x2": S,
    # authoring.md: "Each ends `solved` in 2 iterations, as without them"
    "qdframe solve paper-7.1 --option mu=1e-8": S,
    "qdframe solve paper-7.1 --option mu=1e-8 --option mu_max=1e4": S,
    # cli.md: "`qdframe solve paper-7.1 --option qp=osqp` ends `solved`"
    "qdframe solve paper-7.1 --option qp=osqp": S,
    # cli.md: "ends `solved` on a nonuniform mesh of 99 points"
    "qdframe solve block-breakaway --accuracy 1e-6": S,
    # cli.md: "ends, with exit status 4, `stationary (…)`"
    "qdframe solve paper-7.2 --xT=3,0": ST,
    # friction.md: "`uncertified`: the discrete problem is solved"
    "qdframe solve block-stop-stick --nodes 101 --plot docs/figures/block-stop-stick.png": U,
    # README: "least ∫u² moving a Coulomb block rest to rest, |u| ≤ 1.5: J* = 37/18"
    "qdframe solve least-effort-bounded": S,
    # method.md: "the default call certifies on 71 points instead of 375"
    "qdframe solve coulomb-rest-to-rest": S,
    "qdframe solve coulomb-rest-to-rest --inputs free": S,
    # method.md: "stops `stationary` after 34 iterations"
    "qdframe solve paper-7.1 --direction native --nodes 101": ST,
    # benchmarks.md: the default continuation "starts the finest grid at a solution, and ends `solved`"
    "qdframe solve paper-7.1 --nodes 100001": S,
    # benchmarks.md, "Iterations up the ladder": "each solve below ends `uncertified`" (no estimate)
    "qdframe solve paper-7.3 --nodes 1001 --no-estimate --no-simulate-start": U,
    "qdframe solve paper-7.3 --nodes 10001 --no-estimate --no-simulate-start": U,
    "qdframe solve paper-7.3 --nodes 1001 --scheme radau-iia --no-estimate --no-simulate-start": U,
    "qdframe solve paper-7.3 --nodes 1001 --no-estimate": U,
    "qdframe solve paper-7.3 --nodes 10001 --no-estimate": U,
    # paper.md: "`solved` with estimate 6.8e-9"
    "qdframe solve paper-7.2 --nodes 100001": S,
    # paper.md: "exit status 5, `max_iter`"
    "qdframe solve paper-7.3 --nodes 101 --direction native --no-simulate-start": MI,
    # paper.md: "`uncertified`, as every fixed grid of 7.3 above: its discrete problem solved in 24 iterations"
    "qdframe solve paper-7.3 --nodes 101 --plot docs/figures/paper-7.3.png": U,
}
"""The status each `qdframe solve` that runs here ends with, as the docs' page states it:
`_run` asserts it and the exit code that goes with it (qdframe/status.py). A solve that runs without a declared
status fails test_every_run_solve_declares_its_status."""


def _run(command: str, cwd: Path) -> Outcome:
    """Run `command` in `cwd` as the docs give it (a solve with ``--json -`` added) and
    check how it ended: a solve with the status STATUSES declares for it and that status's
    exit code, anything else (an example's own check of its answer included) exit 0."""
    words = shlex.split(command)
    solve = words[:2] == ["qdframe", "solve"]
    if words[0] == "qdframe":
        words = [sys.executable, "-m", "qdframe.cli", *words[1:]]
    elif words[0] == "python":
        words[0] = sys.executable
    if solve:
        words += ["--json", "-"]
    done = subprocess.run(words, cwd=cwd, capture_output=True, text=True, timeout=600)
    data = json.loads(done.stdout) if solve and done.stdout.strip() else None
    expected = EXIT_CODES[STATUSES[command]] if solve else 0
    assert done.returncode == expected, (f"`{command}` exited {done.returncode}, expected {expected}:\n"
                                         f"{done.stdout[-2000:] if not solve else ''}{done.stderr[-2000:]}")
    if solve:
        assert data["status"] == STATUSES[command], f"`{command}` ended {data['status']}: {data['message']}"
    return Outcome(done.stdout, done.stderr, data, cwd)


def _table(text: str) -> list[dict[str, str]]:
    """The rows of the Markdown table in `text`, by header (the first table's header)."""
    lines = [line.strip() for line in text.splitlines() if line.strip().startswith("|")]
    header = [cell.strip() for cell in lines[0].strip("|").split("|")]
    rows = [[cell.strip() for cell in line.strip("|").split("|")] for line in lines[1:]]
    return [dict(zip(header, row)) for row in rows if row != header and not set("".join(row)) <= set("-:")]


def _number(cell: str) -> float:
    return float(cell.replace("−", "-"))


def _result(data: dict) -> types.SimpleNamespace:
    """A solve's JSON as the attributes check_certified reads."""
    arrays = {k: np.asarray(data[k], dtype=float) for k in ("x", "z")}
    selections = None if data["selections"] is None else np.asarray(data["selections"], dtype=float)
    return types.SimpleNamespace(**{**data, **arrays, "selections": selections})


def _readme() -> str:
    """The documentation's text, README and docs/ pages, whitespace folded (quotes wrap)."""
    return " ".join(" ".join(path.read_text() for path in DOCS).split())


# ------------------------------------------------------------------------- outcomes
def _solved(out: Outcome) -> None:
    """A `solved` whose residuals are within what it certifies."""
    check_certified(_result(out.data))


def _about(measured: float, stated: float, rel: float = 0.25) -> bool:
    """A count or an estimate a page gives as measured on its machine: such numbers move with the
    CPU's rounding, so they are held to a band (as in tests/test_docs_python.py); statuses and the
    values a solve finds are held to what they promise."""
    return abs(measured - stated) <= rel * abs(stated)


def _finds(exact: float, unknown: Callable[[dict], float]) -> Callable[[Outcome], None]:
    def check(out: Outcome) -> None:
        """`solved` with the unknown (T, a parameter) at its exact value within what `solved`
        promises: the target accuracy·max(1, max|x|) (docs/guide.md, "What `solved` promises")."""
        _solved(out)
        tol = out.data["accuracy"] * max(1.0, float(np.max(np.abs(out.data["x"]))))
        assert abs(unknown(out.data) - exact) <= tol, (unknown(out.data), exact, tol)
    return check


def _points(nodes: int) -> Callable[[Outcome], None]:
    def check(out: Outcome) -> None:
        """method.md: the default call certifies coulomb-rest-to-rest on 71 points, with free inputs on 375."""
        _solved(out)
        assert _about(out.data["nodes"], nodes), out.data["nodes"]
    return check


def _iterations(per_grid: list[int]) -> Callable[[Outcome], None]:
    def check(out: Outcome) -> None:
        """benchmarks.md's tables: the discrete problem solved on these grids, in about these iterations."""
        _solved(out)
        found = out.data["options"]["iterations_per_grid"]
        assert len(found) == len(per_grid) and _about(sum(found), sum(per_grid)), found
    return check


def _native_on_71(out: Outcome) -> None:
    """method.md: on a fixed grid the paper's method stops `stationary` after 34 iterations
    with a true error of 3.9e-4."""
    data = out.data
    assert _about(data["iterations"], 34) and data["solution_error"] < 3.95e-4, (data["iterations"], data["message"])


def _stop_stick_on_101(out: Outcome) -> None:
    """friction.md: implicit Euler at N = 101, 1 iteration from the model's simulated motion,
    its discrete problem solved, the true error 2.98e-2 of a first-order grid, the switch at 1."""
    _solved(out)
    assert out.data["iterations"] == 1 and round(out.data["solution_error"], 4) == 2.98e-2
    assert out.data["switch_times"] == pytest.approx([1.0], abs=1e-8)


def _paper_72_at_1e5(out: Outcome) -> None:
    """paper.md: 4 iterations over the grids 101, 301, …, 100001, `solved` with estimate 6.8e-9."""
    _solved(out)
    assert _about(out.data["iterations"], 4) and _about(out.data["error_estimate"], 6.8e-9)


def _paper_73_at_101(out: Outcome) -> None:
    """paper.md: gauss-newton solves 7.3's discrete problem on 101 points in 24 iterations."""
    _solved(out)
    assert _about(out.data["iterations"], 24), out.data["iterations"]


def _finest_grid_starts_solved(out: Outcome) -> None:
    """docs/benchmarks.md: the default continuation starts 7.1's finest grid at a solution."""
    _solved(out)
    assert out.data["options"]["iterations_per_grid"][-1] == 0


def _breakaway_to_1e_6(out: Outcome) -> None:
    """cli.md: `solved` on a nonuniform mesh of 99 points, switch time 1, error estimate 5.8e-7
    by replay (its true error), within the target."""
    _solved(out)
    data = out.data
    assert data["solution_error"] <= data["error_estimate"] <= 1e-6 and data["certificate"] == "replay"
    assert data["options"]["uniform"] is False and _about(data["nodes"], 99) and _about(data["error_estimate"], 5.8e-7)
    assert data["switch_times"] == pytest.approx([1.0], abs=1e-8)


def _unreachable_end(out: Outcome) -> None:
    """README quotes the message of `qdframe solve paper-7.2 --xT=3,0`: its diagnosis (which
    condition fails, how near it came, why: the reachable set's bound) must be the one printed.
    What follows it, the path the solve took to its stall (which grids, which scheme, how many
    iterations), moves with the CPU's rounding (a non-AVX-512 CPU stalls on another grid), so
    there the printed message must only have the quote's form: remarks of the solve's path."""
    readme = " ".join(_readme().split())  # the quote wraps across lines
    quoted = re.search(r"`qdframe solve paper-7\.2 --xT=3,0` \(.*?\) ends(?:, with exit status \d+,)? "
                       r"`(\w+) \((.+?)\)`;", readme)
    assert quoted, "the docs no longer quote the message"
    status, message = quoted.groups()
    diagnosis = re.compile(r"^(.*?reachable set \(.*?\)); (.*)$")
    stated, printed = diagnosis.match(message), diagnosis.match(out.data["message"])
    assert stated and printed, (message, out.data["message"])
    assert (out.data["status"], printed[1]) == (status, stated[1])
    assert re.search(r"(\d+) iterations: 21 nodes (\d+)", stated[2]) and "stationary" in printed[2]
    assert out.data["I"] > 1e-10
    # the numbers the diagnosis quotes are the problem's, not the run's: x1' ≤ 1 from x1(0) = 0 over T = 1
    assert "x1(T) ≤ 1.000" in printed[1] and "x1(T) = 3 not reached" in printed[1]


def _papers_method_on_73(out: Outcome) -> None:
    """README: neither grid schedule of the paper's method reaches the paper's accuracy on
    7.3 in 500 iterations (I ≤ 1e-3 with boundary error ≤ 5e-3); the budget is shared
    between the grids 11 and 101, the coarse one spending at most 500 // (2·2) = 125."""
    data = out.data
    assert data["status"] == "max_iter" and data["options"]["grids"] == [11, 101]
    coarse, fine = data["options"]["iterations_per_grid"]
    assert coarse <= 125 and coarse + fine == data["iterations"] == 500
    assert not any(r["I"] <= 1e-3 and r["boundary_error"] <= 5e-3 for r in data["history"] if r["nodes"] == 101)


def _simulated_reaching(out: Outcome) -> None:
    """README prints x(0) at six decimals; the command's own print must agree with it."""
    stated = re.search(r"x\(0\) = \(([^)]*)\) \(the paper", _readme())
    printed = re.search(r"x\(T1\) = (.*)", out.stdout)
    assert stated and printed, out.stdout
    expected = [_number(v) for v in stated.group(1).split(", ")]
    found = [float(pair.split()[1]) for pair in printed.group(1).split(", ")]
    assert found == pytest.approx(expected, abs=1e-6)


def _friction_suite(count: int) -> Callable[[Outcome], None]:
    def check(out: Outcome) -> None:
        """friction.md: every problem of the suite has its discrete problem solved at N = 101, 1001,
        10001 (`uncertified`: a fixed grid is not meant to meet 1e-6) with a strict residual ≤ 1e-8."""
        rows = _table(out.stdout)
        assert len(rows) == count
        for row in rows:
            assert _converged(row["status"]) and _number(row["strict residual"]) <= 1e-8, row
    return check


def _hard_cases(out: Outcome) -> None:
    """guide.md: every hard case passes (the command exits 1 otherwise), among them the
    unreachable end point (7.2 with xT = 5,5: `stationary`, I ≈ 9.2)."""
    unreachable = re.search(r"unreachable end point.*?\bpass\b.*?(\w+), I = ([\d.]+)", out.stdout)
    assert unreachable and unreachable[1] == "stationary" and _about(float(unreachable[2]), 9.2), out.stdout


SOLVED_BY = {  # README, "Which scheme for friction and sliding": (scheme, N) whose discrete problem is solved, and not
    scheme: {n: {"block-stop-stick", "block-stop-stick-bvp", "block-breakaway", "slide-on-line", "slide-after-reaching",
                 "coulomb-block", "two-surface-sliding", "block-stopping-time", "block-friction-coefficient"}
             | ({"sliding-mode-terminal"} if scheme == "radau-iia" else set())
             for n in (101, 1001)}
    for scheme in ("radau-iia", "trapezoid")
}
NOT_SOLVED_BY = {
    "radau-iia": {101: set(), 1001: set()},
    "trapezoid": {101: {"sliding-mode-terminal"}, 1001: {"sliding-mode-terminal"}},
}


def _friction_schemes(out: Outcome) -> None:
    rows = _table(out.stdout)
    assert len(rows) == 40
    for row in rows:
        scheme, nodes, model = row["scheme"], int(row["N"]), row["model"]
        if model in SOLVED_BY.get(scheme, {}).get(nodes, ()):
            assert _converged(row["status"]) and _number(row["strict residual"]) <= 1e-8, row
        if model in NOT_SOLVED_BY[scheme][nodes]:
            assert not _converged(row["status"]), row


def _accuracy_table(out: Outcome) -> None:
    """docs/guide.md: the two accuracy=1e-6 solves are `solved`, true error ≤ estimate ≤ 1e-6,
    the switch at its exact time; the default calls are `solved` with their error within the estimate."""
    rows = _table(out.stdout)
    exact_switch = {"block-breakaway": 1.0, "slide-after-reaching": np.sqrt(2.0) - 1.0}
    assert {r["model"] for r in rows} == set(exact_switch) and len(rows) == 4
    for row in rows:
        assert row["status"] == "solved", row
        assert _number(row["true error"]) <= _number(row["error estimate"]), row
        if row["solve"].startswith("accuracy="):
            assert _number(row["error estimate"]) <= 1e-6
            assert _number(row["switch times"]) == pytest.approx(exact_switch[row["model"]], abs=1e-8)


def _friction_example(out: Outcome) -> None:
    """README: the discrete problem solved at every N, |v| ≤ 1e-8 in the stick phase, λ = −1/3 there."""
    lines = [line.strip("| ").split(" | ") for line in out.stdout.splitlines() if line.startswith("| ")]
    rows = [line for line in lines[1:] if line[0].isdigit()]  # N, status, iterations, time, max |v| stuck, λ, error
    assert [r[0] for r in rows] == ["101", "1001", "10001"], out.stdout
    for nodes, status, _, _, v_stuck, lam, _ in rows:
        assert _converged(status) and _number(v_stuck) <= 1e-8, out.stdout
        low, high = (_number(v) for v in lam.split("…"))
        assert low == pytest.approx(-1 / 3, abs=1e-6) and high == pytest.approx(-1 / 3, abs=1e-6)


def _converged(status: str) -> bool:
    """A table's status of a solved discrete problem: `solved`, or `uncertified` on a fixed grid."""
    return status in (Status.SOLVED, Status.UNCERTIFIED)


def _summary_status(out: Outcome) -> str:
    return re.search(r"^status\s+(\w+)", out.stdout, flags=re.M).group(1)


def _solved_summary(out: Outcome) -> None:
    assert _summary_status(out) == "solved", out.stdout


def _checked_and_solved(out: Outcome) -> None:
    """The script checks its model (every piece agrees with finite differences) and solves it."""
    assert "all pieces agree with finite differences" in out.stdout
    assert _summary_status(out) == "solved"


def _paper_table(golden_default: bool, armijo_default: bool = False) -> Callable[[Outcome], None]:
    def check(out: Outcome) -> None:
        """README: 7.1 reaches the paper's accuracy (objective ≤ 1e-3, boundary error ≤ 5e-3) in
        every variant, within the paper's 37 iterations with golden and the default grids;
        7.2 with Armijo and the default grids within the paper's 15."""
        rows = _table(out.stdout)
        assert {r["example"] for r in rows} == {"paper-7.1", "paper-7.2"}
        for row in rows:
            reached = row["first iteration at the paper's accuracy"].split()[0]
            if row["example"] == "paper-7.1":
                assert reached != "—" and (not golden_default or int(reached) <= 37), row
            elif armijo_default:
                assert reached != "—" and int(reached) <= 15, row
    return check


def _work_precision(out: Outcome) -> None:
    """The example's point: every accuracy= solve that says `solved` holds up against the
    reference (a fixed grid's `solved` need not)."""
    rows = _table(out.stdout)
    adaptive = [r for r in rows if r["solve"].startswith("accuracy")]
    assert adaptive
    for row in adaptive:
        if row["status"] == "solved":
            assert row["`solved` holds up"] == "yes", row


def _compare_directions(models: set[str], nodes: set[int]) -> Callable[[Outcome], None]:
    def check(out: Outcome) -> None:
        """README: gauss-newton solves the discrete problems of 7.1 and 7.2 at every N and of
        7.3 from N = 101 (at N = 11 with the band and the trapezoid rule too); the paper's
        method solves none of them. 7.3's solutions form a set: on a fixed grid its estimate
        stays above the target, so its solved discrete problems are `uncertified`."""
        rows = _table(out.stdout)
        assert {r["model"] for r in rows} == models and {int(r["N"]) for r in rows} == nodes
        for row in rows:
            if row["direction"] == "native":
                assert row["status"] not in (Status.SOLVED, Status.UNCERTIFIED), row
            elif row["model"] != "paper-7.3" or int(row["N"]) >= 101:
                assert _discrete_solved(row), row
    return check


def _discrete_solved(row: dict) -> bool:
    """A table row whose discrete problem is solved: `solved`, or `uncertified` for 7.3."""
    wanted = {Status.SOLVED, Status.UNCERTIFIED} if row["model"] == "paper-7.3" else {Status.SOLVED}
    return row["status"] in wanted and _number(row["boundary error"]) <= 1e-8


def _band_73(out: Outcome) -> None:
    rows = _table(out.stdout)
    assert [int(r["N"]) for r in rows] == [11, 101, 1001]
    for row in rows:  # README: the band on the trapezoid rule solves 7.3's discrete problem at every N
        assert _discrete_solved(row), row


def _solve_paper(out: Outcome) -> None:
    """The paper's method on 7.1 at N = 101: `stationary` (its own stopping rule) within the
    paper's accuracy; the JSON and the figure written."""
    data = json.loads((out.cwd / "example-out" / "paper-7.1.json").read_text())
    assert data["status"] == "stationary" and data["objective"] <= 1e-3 and data["boundary_error"] <= 5e-3
    assert (out.cwd / "example-out" / "paper-7.1.png").read_bytes()[:4] == b"\x89PNG"


def _simulate_reaching(out: Outcome) -> None:
    """Its end is paper-7.3's x(0): the paper's rounded numbers, to their last digit."""
    printed = re.search(r"x\(0\) = (.*)", out.stdout).group(1)
    found = [float(pair.split()[1]) for pair in printed.split(", ")]
    assert found == pytest.approx([-1.053, 1.099, -0.787, 0.0, 0.026, 1.119], abs=1e-3)
    assert (out.cwd / "example-out" / "reaching-phase.png").read_bytes()[:4] == b"\x89PNG"


def _time_optimal_small(out: Outcome) -> None:
    """docs/benchmarks.md: qdframe's default call and nosnoc's global s on 4 stages (a stage boundary on
    the switch at 0.75·T*) both find T* to 1e-8, and the report is written."""
    rows = _table(out.stdout)
    assert [(row["solver"], row["status"]) for row in rows] == [("qdframe", "solved"), ("nosnoc", "solved")]
    assert all(_number(row["abs(T − T*)"]) <= 1e-8 for row in rows), rows
    assert (out.cwd / "time-optimal-small" / "report.md").is_file()


def _ocp_small(out: Outcome) -> None:
    """docs/benchmarks.md: on lq-terminal qdframe's default call reaches a cost within 1e-6 of J*;
    nosnoc's stagewise-constant control reaches 1e-2 and not 1e-4; the report is written."""
    rows = {row["solver"]: row for row in _table(out.stdout.split("\n\n")[0])}
    assert rows["qdframe"]["J*"] == "36.95652174" and rows["qdframe"]["time to ε = 1e-06 (s)"] != "—", rows
    assert rows["nosnoc"]["time to ε = 0.01 (s)"] != "—" and rows["nosnoc"]["time to ε = 0.0001 (s)"] == "—", rows
    assert (out.cwd / "ocp-small" / "report.md").is_file() and (out.cwd / "ocp-small" / "results.csv").is_file()


OUTCOMES: dict[str, Callable[[Outcome], None]] = {
    "qdframe solve paper-7.1 --nodes 101 --plot docs/figures/paper-7.1.png": _solved,
    "qdframe solve block-stop-stick": _solved,
    "qdframe solve block-friction-coefficient --parameter mu=4": _finds(2.0, lambda data: data["parameters"]["mu"]),
    "qdframe solve relay-period": _finds(4 * np.sqrt(2), lambda data: data["T"]),
    "qdframe solve relay-oscillator --free-T --T 5 --periodic x1,x2": _finds(4 * np.sqrt(2), lambda data: data["T"]),
    "qdframe solve block-time-optimal": _finds(4 / 3 * np.sqrt(1.5), lambda data: data["T"]),
    "qdframe solve paper-7.1 --option qp=osqp": _solved,
    "qdframe solve block-stop-stick --nodes 101 --plot docs/figures/block-stop-stick.png": _stop_stick_on_101,
    "qdframe solve coulomb-rest-to-rest": _points(71),
    "qdframe solve coulomb-rest-to-rest --inputs free": _points(375),
    "qdframe solve paper-7.1 --direction native --nodes 101": _native_on_71,
    "qdframe solve paper-7.3 --nodes 1001 --no-estimate --no-simulate-start": _iterations([21, 3, 6]),
    "qdframe solve paper-7.3 --nodes 10001 --no-estimate --no-simulate-start": _iterations([21, 3, 6, 2, 3]),
    "qdframe solve paper-7.3 --nodes 1001 --scheme radau-iia --no-estimate --no-simulate-start": _iterations([26, 3, 11]),
    "qdframe solve paper-7.3 --nodes 1001 --no-estimate": _iterations([3]),
    "qdframe solve paper-7.3 --nodes 10001 --no-estimate": _iterations([3]),
    "qdframe solve paper-7.3 --nodes 101 --plot docs/figures/paper-7.3.png": _paper_73_at_101,
    "qdframe solve paper-7.2 --nodes 100001": _paper_72_at_1e5,
    "qdframe solve paper-7.1 --nodes 100001": _finest_grid_starts_solved,
    "qdframe solve paper-7.1 --option mu=1e-8": _solved,
    "qdframe solve paper-7.1 --option mu=1e-8 --option mu_max=1e4": _solved,
    "qdframe solve block-breakaway --accuracy 1e-6": _breakaway_to_1e_6,
    "qdframe solve paper-7.2 --xT=3,0": _unreachable_end,
    "qdframe solve paper-7.3 --nodes 101 --direction native --no-simulate-start": _papers_method_on_73,
    "qdframe simulate paper-7.3 --from -0.2 --to 0 --x0=-1,1,-1,-1,1,1": _simulated_reaching,
    "qdframe bench friction": _friction_suite(30),
    "qdframe bench friction --models block-stopping-time,block-friction-coefficient": _friction_suite(6),
    "qdframe bench hard": _hard_cases,
    "qdframe bench time-optimal --accuracy none --formulations global --stages 4 --elements 4 "
    "--out time-optimal-small": _time_optimal_small,
    "qdframe bench run --suite ocp --models lq-terminal --accuracy none --peers --out ocp-small": _ocp_small,
    "qdframe bench friction --schemes radau-iia,trapezoid --nodes 101,1001": _friction_schemes,
    "python examples/custom_model.py": _solved_summary,
    "python examples/accuracy.py": _accuracy_table,
    "python examples/friction.py": _friction_example,
    "python examples/intersection_model.py": _checked_and_solved,
    "python examples/paper_table.py": _paper_table(golden_default=True),
    "python examples/paper_table.py --continuation none": _paper_table(golden_default=False),
    "python examples/paper_table.py --line-search armijo": _paper_table(golden_default=False, armijo_default=True),
    "python examples/paper_table.py --line-search armijo --continuation none": _paper_table(golden_default=False),
    "python examples/work_precision.py --accuracy 1e-3": _work_precision,
    "python examples/compare_directions.py --models paper-7.3 --directions gauss-newton --scheme trapezoid "
    "--signs band": _band_73,
}
"""Commands whose outcome the docs state, and the check of what they print (a solve's status
is STATUSES'; an example exits non-zero where its answer misses what its page states)."""

EXAMPLES: dict[str, Callable[[Outcome], None]] = {
    "python examples/solve_paper.py --out example-out": _solve_paper,
    "python examples/set_model.py": _checked_and_solved,
    "python examples/simulate_reaching.py --out example-out": _simulate_reaching,
    "python examples/compare_directions.py --nodes 11 101 --max-iter 100": _compare_directions(
        {"paper-7.1", "paper-7.2", "paper-7.3"}, {11, 101}),
}
"""The scripts of examples/ that no docs command runs (or runs only at full size), at a small size."""


def test_every_run_solve_declares_its_status():
    """A `qdframe solve` the docs give, and that runs here, ends as its page says: a new one
    declares in STATUSES the status its page states (a page that states none is to say it)."""
    solves = {command for _, command in RUN if command.startswith("qdframe solve ")}
    assert solves <= set(STATUSES), f"no declared status (STATUSES): {sorted(solves - set(STATUSES))}"
    assert set(STATUSES) <= solves, f"declared but not run: {sorted(set(STATUSES) - solves)}"


def test_each_command_runs_once():
    """A command given on several pages runs once; EXAMPLES holds none a page gives."""
    commands = [command for _, command in RUN]
    assert len(commands) == len(set(commands)) and not set(EXAMPLES) & set(commands)


def test_every_stated_outcome_is_a_docs_command():
    """An OUTCOMES key that the docs no longer give would check nothing."""
    assert set(OUTCOMES) <= {command for _, command in RUN}


def test_every_example_is_run():
    """Each script in examples/ is run by a docs command or by EXAMPLES."""
    run = {word for command in [c for _, c in RUN] + list(EXAMPLES) for word in shlex.split(command)}
    scripts = {f"examples/{path.name}" for path in (ROOT / "examples").glob("*.py")}
    assert scripts and scripts <= run, scripts - run


@pytest.mark.docs
@pytest.mark.parametrize("source, command", RUN)
def test_every_command_runs_on_a_fresh_copy(source, command, fresh_copy):
    out = _run(command, fresh_copy)
    if command in OUTCOMES:
        OUTCOMES[command](out)


@pytest.mark.docs
@pytest.mark.parametrize("command", sorted(EXAMPLES))
def test_every_example_runs_on_a_fresh_copy(command, fresh_copy):
    EXAMPLES[command](_run(command, fresh_copy))


@pytest.mark.docs
def test_bench_directions_at_a_small_size(fresh_copy):
    words = [sys.executable, "-m", "qdframe.cli", "bench", "directions", "--nodes", "101", "--repeat", "1",
             "--directions", "native,osqp,clarabel,cvxpy,qpsolvers:daqp,qpsolvers:proxqp"]
    done = subprocess.run(words, cwd=fresh_copy, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "| qpsolvers:proxqp |" in done.stdout


def test_the_readme_is_short_and_links_every_docs_page():
    """Issue 33: a README a newcomer reads in five minutes (≤ 350 lines), the rest in docs/,
    every page reached from it."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 350
    missing = [page.name for page in sorted((ROOT / "docs").glob("*.md")) if f"](docs/{page.name}" not in text]
    assert not missing, f"README does not link {missing}"


@pytest.mark.parametrize("path", DOCS, ids=lambda path: path.name)
def test_every_relative_link_of_the_docs_resolves(path):
    """Links and images to files of the repository point at files that exist (anchors aside)."""
    targets = re.findall(r"\]\(([^)\s]+)\)", path.read_text())
    broken = [target for target in targets if not re.match(r"[a-z]+://|#", target)
              and not (path.parent / target.split("#")[0]).exists()]
    assert not broken, broken
