"""docs/architecture.md matches the code: every path it names exists, every package and
module of qdframe is named in it, and its entry-point groups are pyproject's."""

from __future__ import annotations

import re
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, from the test extra
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "architecture.md").read_text()


def _named_paths() -> set[str]:
    """Every file or folder the doc names: in backticks, in the diagram's boxes."""
    prose = re.sub(r"```.*?```", "", DOC, flags=re.S)  # the diagram's fence would pair the backticks wrong
    spans = re.findall(r"`([^`]+)`", prose) + re.findall(r"<br/>([\w/., ]+)<br/>", DOC)
    words = {w.strip(" ,()") for span in spans for w in re.split(r"[ ,()]+|<br/>", span)}
    return {w for w in words if re.fullmatch(r"[\w./-]+(\.py|/)", w) or w.startswith("qdframe/")}


def test_every_path_named_exists():
    """A path exists as written (from the repository or from qdframe/), or a module named
    inside its package's row exists in some package of qdframe."""
    missing = []
    for path in _named_paths():
        candidates = [ROOT / path, ROOT / "qdframe" / path]
        if not any(c.exists() for c in candidates) and not list((ROOT / "qdframe").rglob(path.rstrip("/"))):
            missing.append(path)
    assert _named_paths() > {"run.py", "problems.py", "sign_forms.py"}  # the table's modules are read
    assert not missing


def test_every_package_and_module_is_named():
    text = DOC
    packages = sorted(p.parent.name for p in (ROOT / "qdframe").glob("*/__init__.py"))
    modules = sorted(p.name for p in (ROOT / "qdframe").glob("*.py") if p.name != "__init__.py")
    assert [p for p in packages if f"qdframe/{p}/" not in text] == []
    assert [m for m in modules if m not in text] == []


def test_the_entry_point_groups_are_pyprojects():
    groups = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"])
    assert set(re.findall(r"`(qdframe\.[a-z_]+)` \|", DOC)) == groups
