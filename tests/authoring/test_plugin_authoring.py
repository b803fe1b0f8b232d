"""docs/authoring.md, run: its model, direction and line search, installed as a fresh
package (a .dist-info with its entry points on sys.path), are discovered, checked and
solved without touching qdframe."""

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import qdframe
from qdframe import registry
from qdframe.authoring import check_model
from qdframe.cli import main

from conftest import entry_point_groups

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "authoring.md"


def _blocks(language):
    return [body for lang, body in re.findall(r"```(\w+)\n(.*?)```", GUIDE.read_text(), re.S) if lang == language]


@pytest.fixture
def guide_package(tmp_path, monkeypatch):
    """The guide's code as package `my_models` of distribution `my-models`."""
    package = tmp_path / "my_models"
    package.mkdir()
    (package / "__init__.py").write_text("")
    for body in _blocks("python"):
        first = body.strip().splitlines()[0]
        match = re.match(r'"""my_models/(\w+\.py)', first)
        if match:
            (package / match.group(1)).write_text(body)
    assert (package / "thermal.py").exists() and (package / "solvers.py").exists()
    groups = entry_point_groups(_blocks("toml"))
    assert set(groups) == {"qdframe.models", "qdframe.directions", "qdframe.line_searches"}
    info = tmp_path / "my_models-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my-models\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text(
        "".join(f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in entries.items()) for group, entries in groups.items())
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    registry.refresh()
    yield groups
    monkeypatch.undo()
    for name in [m for m in sys.modules if m == "my_models" or m.startswith("my_models.")]:
        del sys.modules[name]
    registry.refresh()


def test_the_guides_package_is_listed_under_its_distribution(guide_package, capsys):
    assert main(["list", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    mine = {(kind, e["name"]) for kind, entries in listing.items() for e in entries if e["distribution"] == "my-models"}
    assert mine == {("models", "heated-room"), ("directions", "damped-gauss-newton"), ("line_searches", "shrinking")}
    assert {e["name"]: e["distribution"] for e in listing["models"]}["paper-7.1"] == "qdframe"


def test_the_guides_model_checks_and_solves(guide_package, certified):
    model = qdframe.load_model("heated-room")
    assert check_model(model).ok
    result = qdframe.solve(model)
    certified(result)
    assert result.I <= 1e-10
    theta = result.x[:, 0]
    scale_x, scale_z = max(1.0, np.max(np.abs(result.x))), max(1.0, np.max(np.abs(result.z)))
    assert theta[-1] == pytest.approx(17.0, abs=1e-8 * scale_x)
    # heating lies in [0, 5]: θ' − 0.3(w − θ) − 0.1(5 − θ) within it at every node, to the inclusion's tolerance
    heat = result.z[:, 0] - 0.3 * (result.x[:, 1] - theta) - 0.1 * (5 - theta)
    assert np.all(heat >= -1e-8 * scale_z) and np.all(heat <= 5 + 1e-8 * scale_z)


def test_the_guides_solvers_run_from_the_command_line(guide_package, tmp_path):
    out = tmp_path / "r.json"
    assert main(["solve", "heated-room", "--direction", "damped-gauss-newton", "--line-search", "shrinking",
                 "--json", str(out), "--quiet"]) == 0
    data = json.loads(out.read_text())
    assert data["status"] == "solved" and data["direction"] == "damped-gauss-newton" and data["line_search"] == "shrinking"
