"""Shared checks for the tests."""

from __future__ import annotations

import os
import re

import numpy as np
import pytest

RESIDUAL_TOL = 1e-8  # solve's default residual_tol


def check_certified(result, residual_tol: float = RESIDUAL_TOL) -> None:
    """What `solved` certifies pointwise (README, "How a run ends"), read from the result's
    own residuals rather than from its `checks`: the boundary, consistency and surface errors
    within residual_tol · max(1, max|x|), the inclusion within residual_tol · max(1, max|z|),
    the selections within residual_tol and inside [−1, 1]. The discrete problem is solved:
    the status is `solved`, or `uncertified` where its error estimate does not meet the
    target (a fixed grid is not meant to meet 1e-6)."""
    assert result.converged, result.message
    scale_x = max(1.0, float(np.max(np.abs(result.x))))
    scale_z = max(1.0, float(np.max(np.abs(result.z))))
    assert result.boundary_error <= residual_tol * scale_x
    assert result.consistency_error <= residual_tol * scale_x
    assert result.inclusion_residual <= residual_tol * scale_z
    if result.surface_error is not None:
        assert result.surface_error <= residual_tol * scale_x
    if result.selections is not None:
        assert result.selection_residual <= residual_tol
        assert np.all(np.abs(result.selections) <= 1.0 + residual_tol)


def entry_point_groups(bodies) -> dict[str, dict[str, str]]:
    """The `[project.entry-points."GROUP"]` sections of pyproject.toml texts: group → {key: value}
    (the plugin-package tests read the guide's packaging this way, as an installer would)."""
    groups: dict[str, dict[str, str]] = {}
    for body in bodies:
        group = None
        for line in body.splitlines():
            header = re.match(r'\[project\.entry-points\."([\w.]+)"\]', line.strip())
            if header:
                group = groups.setdefault(header.group(1), {})
            elif line.strip().startswith("["):
                group = None
            elif group is not None and "=" in line:
                key, value = (part.strip().strip('"') for part in line.split("=", 1))
                group[key] = value
    return groups


@pytest.fixture
def certified():
    """:func:`check_certified`, for tests in any folder."""
    return check_certified


# ---------------------------------------------------------------- skips of required modules fail in CI
# .ci/run exports QDFRAME_REQUIRE_ALL=1: there every test extra is installed (pip install -e
# '.[test,all]'), so a test skipped because one of them does not import is a test that never ran —
# a broken install, not an optional dependency. With the variable set, such a skip is a failure
# naming the module; skips for anything else (a module outside these extras, a plain pytest.skip)
# stay skips. The import names of the distributions in pyproject.toml's `test` and `all` extras
# (casadi: nosnoc's own dependency); tests/test_required_skips.py checks that this set covers them.
REQUIRED_MODULES = frozenset({
    "pytest", "xdist", "hypothesis",                    # test
    "osqp", "clarabel", "qpsolvers", "daqp", "proxsuite", "cvxpy",
    "nosnoc", "casadi", "dask", "distributed", "pandas", "xarray",  # all
})
_MISSING = re.compile(r"(?:could not import|No module named|import of) '?([A-Za-z_][\w.]*)'?")


def _required_but_missing(reason: str) -> str | None:
    """The required module a skip's reason says did not import, or None."""
    for name in _MISSING.findall(reason):
        if name.split(".")[0] in REQUIRED_MODULES:
            return name.split(".")[0]
    return None


def _fail_required_skip(report) -> None:
    if not report.skipped or os.environ.get("QDFRAME_REQUIRE_ALL") != "1":
        return
    if not (isinstance(report.longrepr, tuple) and len(report.longrepr) == 3):
        return  # xfail and the like: not a skip with a reason
    reason = str(report.longrepr[2]).removeprefix("Skipped: ")
    module = _required_but_missing(reason)
    if module is not None:
        report.outcome = "failed"
        report.longrepr = (f"required module '{module}' did not import (QDFRAME_REQUIRE_ALL=1: the test extras "
                           f"are installed here, so this skip is a failure): {reason}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    report = (yield).get_result()
    _fail_required_skip(report)


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    report = (yield).get_result()  # a module-level importorskip skips the module at collection
    if report is not None:
        _fail_required_skip(report)
