"""The benchmark tables of README.md and docs/benchmark-results.md, made from the committed reports.

A page marks each generated block as

    <!-- generated: quick ranking -->
    ...
    <!-- end generated -->

and :func:`update` rewrites what lies between from docs/bench/<suite>/results.csv with the
report's own functions, so a figure on those pages is never typed by hand:
``qdframe bench pages`` after a suite is re-run into its folder; ``--check`` (and
tests/test_docs_numbers.py) fails when a page differs from its reports.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from . import certificate_cost, ocp
from .report import ranking, ratio_table, solver_times
from .storage import read_csv

PAGES = ("README.md", "docs/benchmark-results.md")
SUITES = ("quick", "standard", "directions")  # the folders of docs/bench; directions: --suite quick --directions all
BLOCKS: dict[str, tuple[str, Callable[[list[dict]], str]]] = {
    "quick ranking": ("quick", ranking),
    "standard ranking": ("standard", ranking),
    "standard ratios": ("standard", ratio_table),
    "directions times": ("directions", solver_times),
    "certificate costs": ("certificates", lambda rows: certificate_cost.summary(rows) + "\n\n"
                          + certificate_cost.table(rows)),
    "ocp work precision": ("ocp", ocp.work_precision),
}
MARK = re.compile(r"(<!-- generated: (?P<name>[a-z ]+) -->\n)(?P<body>.*?)(\n<!-- end generated -->)", re.S)


def render(text: str, rows: dict[str, list[dict]]) -> str:
    """`text` with every generated block made again from `rows` (suite -> its rows)."""
    def block(match: re.Match) -> str:
        name = match.group("name")
        if name not in BLOCKS:
            raise ValueError(f"unknown generated block {name!r}: one of {', '.join(BLOCKS)}")
        suite, make = BLOCKS[name]
        return match.group(1) + make(rows[suite]) + match.group(4)

    return MARK.sub(block, text)


def update(root: str | Path = ".", check: bool = False) -> list[Path]:
    """Rewrite the pages' generated blocks under `root` from its docs/bench reports; returns the
    pages that changed (with `check`, that would change, and writes nothing)."""
    root = Path(root)
    rows = {suite: read_csv(root / "docs" / "bench" / suite / "results.csv") for suite in SUITES}
    rows["certificates"] = certificate_cost.read(root / "docs" / "bench" / "certificates" / "results.csv")
    rows["ocp"] = ocp.read_rows(root / "docs" / "bench" / "ocp" / "results.csv")
    changed = []
    for name in PAGES:
        path = root / name
        text = path.read_text()
        new = render(text, rows)
        if new != text:
            changed.append(path)
            if not check:
                path.write_text(new)
    return changed
