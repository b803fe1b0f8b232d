"""The package keeps the shape the redesign gave it (issue 34): no function over 120 lines,
no class over 300, the descent loop's module under 400 lines, each basename once but the
packages' `base.py` interfaces, and the status names written in qdframe/status.py alone."""

from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

import qdframe
from qdframe.status import TIME_LIMIT, Status

PACKAGE = Path(qdframe.__file__).parent
SHARED_BASENAMES = {"__init__.py", "base.py"}  # a package's interface module is its base.py


def _trees() -> dict[Path, ast.Module]:
    return {path: ast.parse(path.read_text()) for path in sorted(PACKAGE.rglob("*.py"))}


def test_no_function_over_120_lines_and_no_class_over_300():
    long = []
    for path, tree in _trees().items():
        for node in ast.walk(tree):
            limit = 120 if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else \
                300 if isinstance(node, ast.ClassDef) else None
            if limit and node.end_lineno - node.lineno + 1 > limit:
                long.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name}")
    assert long == []


def test_the_descent_module_stays_small():
    assert len((PACKAGE / "descent" / "loop.py").read_text().splitlines()) <= 400


def test_each_basename_once():
    counts = Counter(path.name for path in PACKAGE.rglob("*.py"))
    assert {name: count for name, count in counts.items() if count > 1 and name not in SHARED_BASENAMES} == {}


def test_status_names_are_written_in_the_status_module_alone():
    names = {status.value for status in Status} | {TIME_LIMIT}
    written = []
    for path, tree in _trees().items():
        if path.name == "status.py":
            continue
        for node in ast.walk(tree):
            # a status compared with or assigned as a string; dict keys and option names ("max_iter") are not statuses
            if isinstance(node, ast.Compare):
                operands = [node.left, *node.comparators]
            elif isinstance(node, ast.keyword) and node.arg == "status":
                operands = [node.value]
            else:
                continue
            written += [f"{path.relative_to(PACKAGE)}:{node.lineno}" for operand in operands
                        for value in ([operand] + list(getattr(operand, "elts", [])))
                        if isinstance(value, ast.Constant) and value.value in names]
    assert written == []


def test_the_solve_and_descent_folders_keep_their_functions_under_80_lines():
    """Issue 54: the cap of the outer loop and of one descent is 80 lines (a plan, a ladder, a loop
    whose state is an object), not the package's 120."""
    long = []
    for path, tree in _trees().items():
        if path.parent.name not in ("solve", "descent"):
            continue
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno + 1 > 80:
                long.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {node.name}")
    assert long == []


def test_the_command_line_imports_no_private_name_of_the_solve_package():
    tree = ast.parse((PACKAGE / "cli.py").read_text())
    private = [f"{node.module}.{alias.name}" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)
               and (node.module or "").startswith("solve") for alias in node.names if alias.name.startswith("_")]
    assert private == [] and any(isinstance(node, ast.ImportFrom) and node.module == "solve.plan"
                                 for node in ast.walk(tree))


def test_the_package_root_holds_at_most_15_files():
    assert len(list(PACKAGE.glob("*.py"))) <= 15
