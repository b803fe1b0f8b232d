"""The switch that makes a skip for a missing test extra a failure in CI (issue 56, item 8).

tests/conftest.py turns a skip whose reason is a module of pyproject.toml's `test`/`all` extras
that did not import into a failure naming the module when QDFRAME_REQUIRE_ALL=1, which .ci/run
exports: there every extra is installed, so such a skip means a test that never ran. Checked
here on a small generated test file run by pytest in a subprocess with the real conftest."""

from __future__ import annotations

import importlib.metadata
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python < 3.11
    import tomli as tomllib

from conftest import REQUIRED_MODULES

ROOT = Path(__file__).resolve().parents[1]

GENERATED = '''
import sys

import pytest


def test_a_required_extra_is_missing():
    sys.modules["osqp"] = None  # import osqp now raises ModuleNotFoundError, as on a machine without it
    pytest.importorskip("osqp")


def test_a_module_outside_the_extras_is_missing():
    pytest.importorskip("qdframe_no_such_module")


def test_a_plain_skip():
    pytest.skip("nothing to do with an import")
'''

MODULE_LEVEL = '''
import sys

import pytest

sys.modules["nosnoc"] = None
pytest.importorskip("nosnoc")


def test_never_collected():
    pass
'''


def _pytest(tmp_path: Path, source: str, require: bool) -> subprocess.CompletedProcess:
    shutil.copy(ROOT / "tests" / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_generated.py").write_text(source)
    env = {k: v for k, v in os.environ.items() if k != "QDFRAME_REQUIRE_ALL"}
    if require:
        env["QDFRAME_REQUIRE_ALL"] = "1"
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-rA", "-n", "0", "-p", "no:cacheprovider",
                           "--rootdir", str(tmp_path), str(tmp_path / "test_generated.py")],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)


def test_without_the_switch_a_missing_extra_is_a_skip(tmp_path):
    run = _pytest(tmp_path, GENERATED, require=False)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "3 skipped" in run.stdout and "failed" not in run.stdout


def test_with_the_switch_a_missing_extra_fails_and_names_the_module(tmp_path):
    run = _pytest(tmp_path, GENERATED, require=True)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "1 failed, 2 skipped" in run.stdout, run.stdout
    assert "FAILED test_generated.py::test_a_required_extra_is_missing" in run.stdout
    assert "required module 'osqp' did not import (QDFRAME_REQUIRE_ALL=1" in run.stdout
    # the others stay skips: a module no extra names, and a skip that is not about an import
    assert "SKIPPED [1] test_generated.py:13: could not import 'qdframe_no_such_module'" in run.stdout
    assert "nothing to do with an import" in run.stdout


def test_with_the_switch_a_module_level_skip_for_a_missing_extra_fails(tmp_path):
    run = _pytest(tmp_path, MODULE_LEVEL, require=False)
    assert "1 skipped" in run.stdout and "error" not in run.stdout.lower(), run.stdout  # (exit 5: nothing ran)
    run = _pytest(tmp_path, MODULE_LEVEL, require=True)
    assert run.returncode != 0 and "required module 'nosnoc' did not import" in run.stdout, run.stdout


def _extras() -> list[str]:
    """The requirements of the `test` and `all` extras, `all`'s qdframe[...] opened."""
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    requirements = list(extras["test"])
    for requirement in extras["all"]:
        own = re.fullmatch(r"qdframe\[(.*)\]", requirement)
        requirements += [r for name in own.group(1).split(",") for r in extras[name]] if own else [requirement]
    return requirements


def test_the_required_modules_are_the_test_extras():
    """A distribution added to the extras is named by the hook (by an import name of it), or a
    test that skips without it would still pass CI silently."""
    imports: dict[str, set[str]] = {}
    for module, distributions in importlib.metadata.packages_distributions().items():
        for distribution in distributions:
            imports.setdefault(re.sub(r"[-_.]+", "-", distribution).lower(), set()).add(module)
    names = set()
    for requirement in _extras():
        if ";" in requirement:  # tomli: only where Python < 3.11, and no test skips on it
            continue
        spec = re.match(r"([A-Za-z0-9_.-]+)(?:\[([^\]]*)\])?", requirement)
        names |= {spec.group(1)} | set(filter(None, (spec.group(2) or "").split(",")))
    missing = {}
    for name in names:
        distribution = re.sub(r"[-_.]+", "-", name).lower()
        # proxsuite installs through cmeel, whose metadata names its prefix rather than the module
        candidates = imports.get(distribution, set()) | {distribution.replace("-", "_")}
        if not candidates & REQUIRED_MODULES:
            missing[name] = sorted(candidates)
    assert not missing, f"tests/conftest.py REQUIRED_MODULES lacks {missing}"


def test_ci_sets_the_switch_before_the_tests():
    lines = (ROOT / ".ci" / "run").read_text().splitlines()
    switch = lines.index("export QDFRAME_REQUIRE_ALL=1")
    tests = next(i for i, line in enumerate(lines) if "-m pytest" in line)
    assert switch < tests
