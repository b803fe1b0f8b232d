"""Every command the README and the docs give works verbatim on a fresh copy.

Commands are read from the Markdown itself: the lines of ``sh`` code blocks and the inline
code spans that start with ``qdframe `` or ``python examples/``. Synopses (with
``[…]``, ``NAME``, ``…`` or ``a|b``) are usage, not commands. Each command is
parsed by the real CLI parser, and each one is run in a fresh copy of the repository (the
files git tracks), except those listed in NOT_RUN with the reason; installs are the CI's
own job (its set-up command is the README's).
"""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from qdframe.cli import build_parser

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
    # the same at N = 100001 alone, each cell in three processes: 8 min 35 s (2026-11-25)
    "qdframe bench scale --nodes 100001 --repeat 3": "a 9-minute measurement",
    # paper-7.2 alone at N = 100001, both paths, three processes each: 2 min 5 s (2026-11-25)
    "qdframe bench scale --models paper-7.2 --nodes 100001 --repeat 3": "a 2-minute measurement",
    # paper-7.3 at N = 100001 with the default continuation: solved in 171 iterations, 470 s on
    # the 2-core machine with a test run on the other core (2026-11-24); the same solve at
    # N = 101 runs in tests/test_masses_and_signs.py
    "qdframe solve paper-7.3 --nodes 100001": "an 8-minute solve",
    # sliding-mode-terminal on three grids and at accuracy 1e-3 and 1e-6: 5 min 1 s on the idle
    # 2-core machine (2026-11-24), 469 s in a loaded CI run, most of it the 1e-6 solve; the
    # README's `--accuracy 1e-3` variant runs here, the same code on every line but that solve
    "python examples/work_precision.py": "a 5-minute measurement",
}
"""Commands parsed but not run, and why."""


EXIT = {
    # runs the README shows ending unsolved, with the exit status `qdframe solve` gives for it
    # (qdframe/status.py: 4 stationary, 5 max_iter)
    "qdframe solve paper-7.2 --xT=3,0": 4,  # an end point outside the reachable set
    "qdframe solve paper-7.3 --nodes 101 --direction native": 5,  # the paper's method within 500 iterations
}
"""Commands whose documented outcome is a non-zero exit status (all others exit 0)."""


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


def test_every_expected_exit_is_a_documented_command():
    assert set(EXIT) <= {command for _, command in COMMANDS}


def test_the_docs_give_commands():
    names = [command for _, command in COMMANDS]
    assert any(c.startswith("qdframe solve") for c in names) and any(c.startswith("python examples/") for c in names)


@pytest.mark.parametrize("source, command", [c for c in COMMANDS if c[1].startswith("qdframe ")])
def test_every_qdframe_command_parses(source, command):
    build_parser().parse_args(shlex.split(command)[1:])


@pytest.fixture(scope="module")
def fresh_copy(tmp_path_factory) -> Path:
    """The files git tracks, copied: what a fresh clone holds."""
    target = tmp_path_factory.mktemp("fresh") / "qdframe"
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    for name in filter(None, tracked.decode().split("\0")):
        source = ROOT / name
        if source.is_file():
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name)
    return target


RUN = [c for c in COMMANDS if not _is_setup(c[1]) and c[1] not in NOT_RUN]


@pytest.mark.docs
@pytest.mark.parametrize("source, command", RUN)
def test_every_command_runs_on_a_fresh_copy(source, command, fresh_copy):
    words = shlex.split(command)
    if words[0] == "qdframe":
        words = [sys.executable, "-m", "qdframe.cli", *words[1:]]
    elif words[0] == "python":
        words[0] = sys.executable
    done = subprocess.run(words, cwd=fresh_copy, capture_output=True, text=True, timeout=600)
    expected = EXIT.get(command, 0)
    assert done.returncode == expected, (f"{source}: `{command}` exited {done.returncode}, expected {expected}:\n"
                                         f"{done.stderr[-2000:]}")


@pytest.mark.docs
def test_bench_directions_at_a_small_size(fresh_copy):
    words = [sys.executable, "-m", "qdframe.cli", "bench", "directions", "--nodes", "101", "--repeat", "1",
             "--directions", "native,osqp,clarabel,cvxpy,qpsolvers:daqp,qpsolvers:proxqp"]
    done = subprocess.run(words, cwd=fresh_copy, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "| qpsolvers:proxqp |" in done.stdout
