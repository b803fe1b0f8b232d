"""The benchmark tables in README.md and docs/benchmark-results.md are the committed reports'.

Each table there sits between `<!-- generated: NAME -->` marks and is what the report code
makes of the committed results.csv (docs/bench/quick, docs/bench/standard): a figure cannot
be typed by hand and go stale. `qdframe bench pages` rewrites them after a suite is re-run.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from qdframe.bench.pages import BLOCKS, MARK, render, update
from qdframe.cli import main as qdframe_main

ROOT = Path(__file__).resolve().parents[1]


def test_the_pages_are_their_reports():
    assert update(ROOT, check=True) == [], "run `qdframe bench pages` after re-running a suite"


def test_every_generated_block_is_on_a_page():
    names = {m.group("name") for page in ("README.md", "docs/benchmark-results.md")
             for m in MARK.finditer((ROOT / page).read_text())}
    assert names == set(BLOCKS)


def test_a_hand_edited_figure_is_found_and_rewritten(tmp_path):
    for page in ("README.md", "docs/benchmark-results.md"):
        (tmp_path / page).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / page).write_text((ROOT / page).read_text())
    for suite in ("quick", "standard", "directions", "certificates", "ocp"):
        (tmp_path / "docs" / "bench" / suite).mkdir(parents=True)
        (tmp_path / "docs" / "bench" / suite / "results.csv").write_text(
            (ROOT / "docs" / "bench" / suite / "results.csv").read_text())
    readme = tmp_path / "README.md"
    edited = re.sub(r"(\| qdframe\.solve\(model\) \| )\d+", r"\g<1>999", readme.read_text(), count=1)
    assert edited != readme.read_text()
    readme.write_text(edited)
    assert qdframe_main(["bench", "pages", "--root", str(tmp_path), "--check"]) == 1
    assert qdframe_main(["bench", "pages", "--root", str(tmp_path)]) == 0
    assert readme.read_text() == (ROOT / "README.md").read_text()


@pytest.mark.parametrize("suite", ["quick", "standard", "directions", "certificates", "ocp"])
def test_each_report_names_the_commit_that_made_it(suite):
    header = (ROOT / "docs" / "bench" / suite / "report.md").read_text()
    assert re.search(r"\| qdframe \| [^,]+, commit [0-9a-f]{7,}", header), f"docs/bench/{suite}/report.md"


def test_an_unknown_block_is_named():
    with pytest.raises(ValueError, match="unknown generated block 'quick typo'"):
        render("<!-- generated: quick typo -->\nx\n<!-- end generated -->", {})


def test_pages_outside_a_checkout_is_a_usage_error(tmp_path, capsys):
    assert qdframe_main(["bench", "pages", "--root", str(tmp_path)]) == 2
    assert "--root" in capsys.readouterr().err
