"""The extension points take the number of places docs/architecture.md and
docs/benchmarks.md give them: a model, a direction, a min-norm QP backend, a step QP, a line
search, a scheme and a benchmark peer are each a class in a module of a fresh package and one
entry point, and run with nothing else in qdframe changed; a benchmark problem is one entry
of the catalogue, the only place in qdframe/bench besides hard.py's cases that names a model."""

from __future__ import annotations

import ast
import re
import textwrap
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

import qdframe
from qdframe import registry
from qdframe.bench import problems
from qdframe.bench.cases import SUITES, Case, plan
from qdframe.bench.execution import run_case

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = textwrap.dedent('''
    import numpy as np

    from qdframe.bench.peer import Peer, PeerRun
    from qdframe.directions.gauss_newton import GaussNewton
    from qdframe.directions.osqp_backend import OsqpDirection
    from qdframe.directions.step_qp import ActiveSetStep
    from qdframe.line_searches.armijo import Armijo
    from qdframe.models.exact_friction import BlockStopStick
    from qdframe.schemes.implicit_euler import ImplicitEuler
    from qdframe.status import Status


    class Model(BlockStopStick):
        name = "extension-model"


    class Direction(GaussNewton):
        name = "extension-direction"


    class MinNormQP(OsqpDirection):
        name = "extension-qp"


    class Step(ActiveSetStep):
        name = "extension-step"


    class Search(Armijo):
        name = "extension-search"


    class Scheme(ImplicitEuler):
        name = "extension-scheme"


    class Exact(Peer):
        """A peer that returns the problem's closed form on N uniform times."""

        name, inner, line, knob = "extension-peer", "closed form", "extension-peer", "nodes"

        def states(self, model):
            return model.exact_solution(np.zeros(1)) is not None

        def run(self, model, setting):
            t = np.linspace(0.0, model.T, int(setting))
            x = model.exact_solution(t)
            return PeerRun(Status.SOLVED, "exact", 0, 0.0, 0.0, x=x, z=np.gradient(x, t, axis=0), t=t)
''')
ENTRY_POINTS = {
    "qdframe.models": "extension-model = extension_plugin:Model",
    "qdframe.directions": "extension-direction = extension_plugin:Direction\nextension-qp = extension_plugin:MinNormQP",
    "qdframe.step_qps": "extension-step = extension_plugin:Step",
    "qdframe.line_searches": "extension-search = extension_plugin:Search",
    "qdframe.schemes": "extension-scheme = extension_plugin:Scheme",
    "qdframe.peers": "extension-peer = extension_plugin:Exact",
}


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """A fresh package: one module and one entry point per extension point."""
    (tmp_path / "extension_plugin.py").write_text(PLUGIN)
    with _distribution(tmp_path, "extension-plugin", ENTRY_POINTS, monkeypatch):
        yield


@contextmanager
def _distribution(folder: Path, name: str, entry_points: dict[str, str], monkeypatch):
    """An installed distribution `name` (its metadata in `folder`, on sys.path) with these
    entry points (group -> lines), seen by the registry meanwhile."""
    info = folder / f"{name.replace('-', '_')}-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("".join(f"[{group}]\n{lines}\n\n" for group, lines in entry_points.items()))
    monkeypatch.syspath_prepend(str(folder))
    registry.refresh()
    try:
        yield
    finally:
        monkeypatch.undo()
        registry.refresh()


def test_the_groups_here_are_every_registry_group():
    assert set(ENTRY_POINTS) == set(registry.GROUPS.values())


def test_a_model_direction_step_qp_line_search_and_scheme_are_a_module_and_an_entry_point(plugin):
    from qdframe.directions.base import with_options

    direction = with_options(registry.make_direction("extension-direction"), {"qp": "extension-step"})
    result = qdframe.solve("extension-model", nodes=31, direction=direction, line_search="extension-search",
                           scheme="extension-scheme", estimate=False)
    assert "the discrete problem is solved" in result.message and result.model == "extension-model"
    assert result.options["scheme"] == "extension-scheme" and result.line_search == "extension-search"
    assert "extension-step" in result.direction
    paper = qdframe.solve("paper-7.2", nodes=11, direction="extension-qp", max_iter=3, estimate=False)
    assert paper.direction == "extension-qp" and paper.iterations == 3  # the paper's direction on its QP


def test_a_peer_is_a_module_and_an_entry_point(plugin):
    sweep = plan("quick", models=["block-stop-stick", "paper-7.2"], directions=["gauss-newton"], nodes=[21],
                 accuracy=[], peers=True)
    mine = [case for case in sweep.cases if case.peer == "extension-peer"]
    assert [(case.model, case.nodes) for case in mine] == [("block-stop-stick", 21)]  # paper-7.2: declined
    row = run_case(mine[0])
    assert row["status"] == "solved" and row["direction"] == "extension-peer"
    assert row["error"] is not None and row["error"] < 1e-12  # judged by the one yardstick
    assert Case("block-stop-stick", "extension-peer", "closed form", 21, 10, None, peer="extension-peer").solver \
        == "extension-peer"


def test_the_peer_in_the_benchmark_doc_runs_as_written(tmp_path, monkeypatch):
    """docs/benchmarks.md's example peer, copied from the doc into a fresh package, states the
    initial-value problems only and its runs are judged against the reference."""
    doc = (ROOT / "docs" / "benchmarks.md").read_text()
    code = re.search(r'```python\n("""my_peers/ivp\.py.*?)```', doc, re.S).group(1)
    (tmp_path / "my_peers").mkdir()
    (tmp_path / "my_peers" / "__init__.py").write_text("")
    (tmp_path / "my_peers" / "ivp.py").write_text(code)
    with _distribution(tmp_path, "my-peers", {"qdframe.peers": "solve_ivp = my_peers.ivp:SolveIVP"}, monkeypatch):
        sweep = plan("quick", models=["block-stop-stick", "block-stop-stick-bvp"], directions=["gauss-newton"],
                     nodes=[21], accuracy=[], bvp_tols=[1e-6], peers=True)
        mine = [case for case in sweep.cases if case.peer == "solve_ivp"]
        assert [case.model for case in mine] == ["block-stop-stick"]  # the two-point form: declined
        row = run_case(mine[0])
        assert row["status"] == "solved" and row["error"] < 1e-4 and row["claim"] == "confirmed"


def test_an_unavailable_peer_fails_its_rows_with_the_reason(plugin, monkeypatch):
    from extension_plugin import Exact

    monkeypatch.setattr(Exact, "unavailable", lambda self: "not here; pip install extension-plugin")
    monkeypatch.setattr(Exact, "run", lambda self, model, setting: pytest.fail("run called on an unavailable peer"))
    row = run_case(Case("block-stop-stick", "extension-peer", "closed form", 21, 10, None, peer="extension-peer"))
    assert row["status"] == "failed" and "pip install extension-plugin" in row["message"]


def _name_literals() -> dict[str, set[str]]:
    """Each registered model name -> the files of qdframe/bench holding it as a string literal."""
    names = set(registry.names("models"))
    found: dict[str, set[str]] = {}
    for path in sorted((ROOT / "qdframe" / "bench").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
                found.setdefault(node.value, set()).add(path.name)
    return found


def test_a_benchmark_problem_is_one_catalogue_entry():
    literals = _name_literals()
    assert set(literals) >= set(problems.CATALOGUE)  # the catalogue names its problems
    assert {name: files for name, files in literals.items() if not files <= {"problems.py", "hard.py"}} == {}
    assert SUITES["quick"].models == problems.tagged("quick")
    assert SUITES["standard"].models == SUITES["full"].models == problems.tagged("standard")
    assert all(name in registry.names("models") for name in problems.CATALOGUE)  # each a registered model


def test_a_catalogue_entry_carries_a_problems_statements(monkeypatch):
    """A new entry with a sign form and a replay statement is all the peers and the reference need."""
    entry = problems.problem("block-stop-stick")
    monkeypatch.setitem(problems.CATALOGUE, "slide-on-line",
                        problems.Problem("slide-on-line", frozenset({"friction"}), entry.sign_form, entry.replay))
    model = qdframe.load_model("slide-on-line")
    assert problems.sign_form(model).terms([0.0, 1.0])[0][1] == 1.0  # the block's c = v, now this model's
    assert problems.statement(model).names == problems.statement(qdframe.load_model("block-stop-stick")).names


def test_the_architecture_doc_counts_two_places_for_each_registered_kind():
    doc = (ROOT / "docs" / "architecture.md").read_text()
    places = {}  # entry-point group -> the "places" cell of its rows
    for row in doc.splitlines():
        group = re.match(r"\| [a-zA-Z -]+ \| `qdframe\..*?`(qdframe\.[a-z_]+)` \|", row)
        if group:
            places[group.group(1)] = row.rstrip(" |").rsplit("|", 1)[1].strip()
    assert {group: count for group, count in places.items() if group in ENTRY_POINTS} == \
        {group: "2" for group in ENTRY_POINTS}
