"""The Python of README.md, docs/guide.md and docs/authoring.md, run as a reader runs it.

Each page's ```python blocks are executed in order in one namespace (a module, so that
dataclasses and pickling find their classes), in a temporary directory, like a doctest
session: a later block may use what an earlier one defined, as a reader pasting the page
into one session would. Where the page states an outcome (a status, a value, a count, a
switch time) in a comment of the block or in the sentences around it, CHECKS asserts it
right after the block ran. Every model class a page defines is also built and passed
through `check_model` (a class body runs at definition, its `sets` only when the model is
built: a name the block forgot to import shows there).

A block that cannot run standalone is marked in the Markdown, on the line before its fence,
``<!-- not run: reason -->``; the reason is required. authoring.md's plugin package
(its ``my_models/*.py`` modules, its ``pyproject.toml`` entry points and its tests) is
assembled as the page lays it out, and its tests are run.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import sys
import types
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import qdframe
from qdframe import registry
from qdframe.authoring import check_model
from qdframe.model import InclusionModel
from conftest import entry_point_groups

ROOT = Path(__file__).resolve().parents[1]
PAGES = ("README.md", "docs/guide.md", "docs/authoring.md")
FENCE = re.compile(r"(?:^<!-- not run: (?P<reason>.*?) -->\n)?^```python\n(?P<code>.*?)^```", re.S | re.M)
NOT_RUN_MARK = re.compile(r"<!-- not run:(.*?)-->\n```python")


def blocks(page: str) -> list[tuple[str, str | None]]:
    """The page's Python blocks in order: (code, the reason it is not run, or None)."""
    text = (ROOT / page).read_text()
    found = [(m.group("code"), m.group("reason")) for m in FENCE.finditer(text)]
    assert len(found) == text.count("```python"), f"{page}: a ```python fence the pattern missed"
    return found


def scale(result) -> float:
    return max(1.0, float(np.max(np.abs(result.x))))


def about(measured: float, stated: float, rel: float = 0.25) -> bool:
    """A count or an estimate the page gives as measured on its machine: such numbers move with
    the CPU's rounding (tests/authoring/test_qp_backend_seam.py), so they are held to a band; the
    statuses, switch times and values a page states are held to its digits."""
    return abs(measured - stated) <= rel * abs(stated)


# ------------------------------------------------------------------------------------ checks
# (page, a line that picks the block) → check(namespace, printed text); the page's words quoted
def readme_first_solve(ns, out):
    result, fixed = ns["result"], ns["fixed"]
    assert result.status == "solved" and result.error_estimate <= 1e-6 * scale(result)  # "refined until certified"
    assert out.split()[0] == "solved"
    assert np.allclose(result.switch_times, [1.0], atol=1e-6)  # block-stop-stick stops at t = 1 (its exact motion)
    import matplotlib.figure

    assert isinstance(result.plot(), matplotlib.figure.Figure)  # "a Matplotlib Figure"
    # "a fixed grid: `solved` only if its estimate meets 1e-6"
    assert fixed.nodes == 101
    assert fixed.solved == (fixed.error_estimate is not None and fixed.error_estimate <= 1e-6 * scale(fixed))


def readme_plugin(ns, out):
    result = ns["result"]
    assert result.status == "solved", result.message  # "solved, its stick-slip switches"
    assert out.split()[0] == "solved" and len(result.switch_times) >= 1
    # "the built-in `pivot-friction-pendulum` is the same model"
    builtin = qdframe.solve("pivot-friction-pendulum")
    assert builtin.nodes == result.nodes and np.allclose(builtin.x, result.x, rtol=0, atol=1e-12)
    # stuck at the end where friction holds it: ω = 0 and |9.81 sin θ| ≤ 2
    assert abs(result.x[-1, 1]) <= 1e-8 and abs(9.81 * np.sin(result.x[-1, 0])) <= 2.0


def guide_python(ns, out):
    result, precise = ns["result"], ns["precise"]
    # "refined until the error is ≤ 1e-6·max(1, |x|)"
    assert result.status == "solved" and result.error_estimate <= 1e-6 * scale(result)
    assert out.splitlines()[0].split()[0] == "solved"
    # "same fields as the CLI's --json"
    from qdframe.cli import main

    written = json.loads(Path("paper-7.1.json").read_text())
    assert main(["solve", "paper-7.1", "--json", "cli.json", "--quiet"]) == 0
    assert set(written) == set(json.loads(Path("cli.json").read_text())) and written["status"] == "solved"
    import matplotlib.figure

    assert isinstance(ns["fig"], matplotlib.figure.Figure)
    assert precise.status == "solved" and precise.error_estimate <= 1e-9 * scale(precise)  # "a tighter target"
    # "status, I and the residuals in a few lines"
    shown = repr(result)
    assert "solved" in shown and "I " in shown and "residuals" in shown and len(shown.splitlines()) <= 8
    # "indexed by t: columns x1, x2, x1', x2' (u, λ), μ_x1, μ_x2" (7.1 has a cost: its multipliers)
    df = ns["df"]
    assert df.index.name == "t" and list(df.columns) == ["x1", "x2", "x1'", "x2'", "μ_x1", "μ_x2"]
    # "x, z over (t, state), the status and residuals in attrs"
    ds = ns["ds"]
    assert ds["x"].dims == ds["z"].dims == ("t", "state") and ds.attrs["status"] == "solved"
    assert any(key.startswith("residual_") for key in ds.attrs)


def guide_unknowns(ns, out):
    stop, period, mu, guessed = ns["stop"], ns["period"], ns["mu"], ns["guessed"]
    first = out.splitlines()[0].split()
    assert float(first[0]) == pytest.approx(0.5, abs=1e-9) and float(first[1]) == pytest.approx(0.5, abs=1e-9)  # "0.5 0.5"
    assert stop.t[-1] == stop.T  # "t runs over [0, T found]"
    assert period.solved and period.T == pytest.approx(4 * np.sqrt(2), abs=1e-6)  # "4√2 from the guess 5"
    assert period.options["T_guess"] == 5
    assert set(mu.parameters) == {"mu"} and mu.parameters["mu"] == pytest.approx(2.0, abs=1e-9)  # {'mu': 2.000000000…}
    assert "{'mu': 2.0000000" in out or "{'mu': 1.9999999" in out
    assert guessed.solved and guessed.parameters["mu"] == pytest.approx(2.0, abs=1e-9)  # another guess, the same μ


def heated_room(ns, out):
    # section 3: `qdframe solve heated-room` ends "status solved, I ≤ 1e-10"
    result = qdframe.solve(ns["HeatedRoom"]())
    assert result.status == "solved" and result.I <= 1e-10
    assert result.x[-1, 0] == pytest.approx(17.0, abs=1e-8 * scale(result))  # default_xT = {"theta": 17.0}


def room_script(ns, out):
    result = ns["result"]
    assert out.split()[0] == "solved" and result.status == "solved" and result.I <= 1e-10  # "solved, I ≤ 1e-10"
    assert isinstance(ns["Room"], type) and not isinstance(ns["Room"], InclusionModel)  # "the class, not an instance"


def block_to_mark(ns, out):
    # "`qdframe.solve(BlockToMark()).parameters` is `{'mu': 2.0…}`": from (0, 2) the block stops
    # at p = v0²/(2μ) = 1 while it slides (v0/μ = 1 ≤ T = 1.5), so μ = 2
    result = qdframe.solve(ns["BlockToMark"]())
    assert result.solved and result.parameters["mu"] == pytest.approx(2.0, abs=1e-6)


def guide_optimal_control(ns, out):
    # "solved 2.0555555… (J* = 37/18)", "the last λ (≤ 1e6)", "1.5: the bound binds on [0, 1/2]"
    effort = ns["effort"]
    assert effort.solved and effort.cost == pytest.approx(37 / 18, abs=1e-6 * 37 / 18)
    assert effort.options["penalty"] <= 1e6
    u, t = np.asarray(effort.u)[1:, 0], effort.t[1:]
    assert float(np.max(np.abs(u))) == pytest.approx(1.5, abs=1e-7) and np.all(u[t < 0.45] >= 1.5 - 1e-7)


def docking(ns, out):
    # "solved 1.5625099…, x(T) = (1, 0.1016)", "0 and 0.1727: where the push stops binding"
    docked = ns["docked"]
    assert docked.solved and docked.cost == pytest.approx(1.5625099, abs=1e-6)
    assert docked.x[-1] == pytest.approx([1.0, 0.1016], abs=1e-4)
    assert [round(float(t), 4) for t in docked.switch_times] == [0.0, 0.1727]


def periodic_stick_slip(ns, out):
    # "solved 8191", "[0.2447 4.9322 9.6356 14.163]: slips and sticks on x1 = 0.2"; "in 1.9 s, an error
    # estimate of 3.4e-7 by replay" (tests/sets/test_modes.py holds it to an independent integration)
    cycle = ns["cycle"]
    assert cycle.solved and cycle.certificate == "replay" and about(cycle.nodes, 8191)
    assert [round(float(t), 4) for t in cycle.switch_times[:4]] == [0.2447, 4.9322, 9.6356, 14.163]
    assert about(cycle.error_estimate, 3.4e-7)


def hand_written_coefficient(ns, out):
    # "the same model by hand": the same μ = 2 (its bounds (0.5, 5) hold it)
    result = qdframe.solve(ns["HandWrittenCoefficient"]())
    assert result.solved and result.parameters["mu"] == pytest.approx(2.0, abs=1e-6)


def coulomb_pendulum(ns, out):
    # "ends `solved` on 647 points after 19 iterations: reverses at t = 1.056, stops at
    # t = 2.077 and sticks at θ = 0.0997, an error estimate of 1.0e-6 by replay"
    result = qdframe.solve(ns["CoulombPendulum"]())
    assert result.status == "solved" and result.certificate == "replay"
    assert about(result.nodes, 647) and about(result.iterations, 19)
    assert np.allclose(result.switch_times, [1.056, 2.077], atol=5e-4)
    assert result.x[-1, 0] == pytest.approx(0.0997, abs=5e-5) and abs(result.x[-1, 1]) <= 1e-9
    assert about(result.error_estimate, 1.0e-6, rel=0.5) and result.error_estimate <= 1e-6 * scale(result)
    # "a fixed grid of 1001 implicit-Euler points ends `uncertified` at θ(3) = 0.086, the true
    # motion 1.8e-2 from it by t = 1.056"
    fixed = qdframe.solve(ns["CoulombPendulum"](), nodes=1001)
    assert fixed.status == "uncertified" and fixed.x[-1, 0] == pytest.approx(0.086, abs=5e-4)
    distance, when = departure(fixed)
    assert distance == pytest.approx(1.8e-2, abs=5e-4) and when == pytest.approx(1.056, abs=5e-4)


def departure(result) -> tuple[float, float]:
    """How far the replayed true motion is from an uncertified trajectory, and when (its message)."""
    found = re.search(r"the true motion from its x\(0\) is ([0-9.e+-]+) from it by t = ([0-9.]+)", result.message)
    assert found, result.message
    return float(found.group(1)), float(found.group(2))


def puck(ns, out):
    # "ends `solved` on 409 points with an error estimate of 7.0e-8 (replay) and a true error of
    # 6.7e-8 against the model's independent reference; the stop at t = 1 and the break-away at
    # t = 2; while it sticks |v| ≤ 1e-12 and λ = (F/μ)·d"
    from qdframe.models.planar_friction import IsotropicPuck

    result = qdframe.solve(ns["Puck"]())
    assert result.status == "solved" and result.certificate == "replay" and about(result.nodes, 409)
    assert about(result.error_estimate, 7.0e-8, rel=0.5)
    true_error = float(np.max(np.abs(result.x - IsotropicPuck().exact_solution(result.t))))
    assert about(true_error, 6.7e-8, rel=0.5) and true_error <= 2 * result.error_estimate
    assert np.allclose(result.switch_times, [1.0, 2.0], rtol=0, atol=2e-10)
    stuck = (result.t > 1.01) & (result.t < 1.99)
    assert stuck.sum() >= 3 and np.max(np.abs(result.x[stuck, 2:4])) <= 1e-12
    F = result.x[stuck, 4]
    assert np.allclose(result.selections[stuck], np.outer(F / 0.5, [0.6, 0.8]), rtol=0, atol=1e-8)


def hand_puck(ns, out):
    # "slides on a curve, stops, sticks": under the pull 0.5·d from |v| = 1 ⊥ d it stops at t = 4/3
    # (qdframe.models.planar_friction.sled_phase, Cardano's closed form) and then holds λ = 0.5·d
    from qdframe.models.planar_friction import sled_phase

    result = qdframe.solve(ns["HandPuck"]())
    assert result.solved and result.switch_times[0] == pytest.approx(4 / 3, abs=1e-8)
    d, n = np.array([0.6, 0.8]), np.array([-0.8, 0.6])
    along, across, v_along, v_across = sled_phase(result.t)
    exact = np.concatenate([np.outer(along, d) + np.outer(across, n), np.outer(v_along, d) + np.outer(v_across, n)],
                           axis=1)
    assert np.max(np.abs(result.x - exact)) <= 1e-6 * scale(result)
    assert np.allclose(result.selections[result.t > 1.4], [0.3, 0.4], rtol=0, atol=1e-8)


def released(ns, out):
    # "`qdframe.solve(Released(), accuracy=1e-5)` ends `solved` on 623 points, switch times
    # 1.498, 2.625, 3.673, 4.691"
    solved = qdframe.solve(ns["Released"](), accuracy=1e-5)
    assert solved.status == "solved" and about(solved.nodes, 623)
    assert np.allclose(solved.switch_times, [1.498, 2.625, 3.673, 4.691], atol=5e-4)
    # "From the constant start ... 101 nodes with `max_iter=100` end `stationary` after 62
    # iterations with I = 6.9e-2, still near θ ≡ 2.5"
    constant = qdframe.solve(ns["Released"](), nodes=101, max_iter=100, simulate_start=False)
    assert constant.status == "stationary" and about(constant.iterations, 62)
    assert constant.I == pytest.approx(6.9e-2, abs=5e-4) and constant.options["start"] == "model"
    # "From that start ... 101 nodes end `uncertified` after 17 iterations: the discrete problem
    # is solved, its error not certified (the true motion is 0.89 from it by t = 1.498)"
    own = qdframe.solve(ns["ReleasedFromSimulation"](), nodes=101, simulate_start=False)
    assert own.status == "uncertified" and about(own.iterations, 17)
    distance, when = departure(own)
    assert distance == pytest.approx(0.89, abs=5e-3) and when == pytest.approx(1.498, abs=5e-4)


def shaken_block(ns, out):
    # "p' = v, v' ∈ sin(2t) − 0.5 Sgn(v), from rest": stuck until sin(2t) = 0.5, t = π/12
    result = qdframe.solve(ns["ShakenBlock"]())
    assert result.solved and result.switch_times[0] == pytest.approx(np.pi / 12, abs=1e-6)
    assert np.max(np.abs(result.x[result.t < np.pi / 12 - 1e-3, :2])) <= 1e-8  # at rest before it
    assert np.allclose(result.x[:, 2], result.t, rtol=0, atol=1e-9)  # the clock is t


def solvers(ns, out):
    from qdframe.directions.base import with_options

    assert ns["DampedGaussNewton"]().mu == 1.0 and ns["Shrinking"]().factor == 0.8
    # "`--direction damped-gauss-newton --option mu=0.1`": the option is a dataclass field
    assert with_options(ns["DampedGaussNewton"](), {"mu": "0.1"}).mu == 0.1


def options_from_python(ns, out):
    result = ns["result"]
    assert out.split()[0] == result.status == "solved" and result.line_search == "armijo"


def scipy_qp(ns, out):
    # "`qdframe.solve("paper-7.1", nodes=11, direction=ScipyQP())` ends as `native` does,
    # `stationary` after the same iterations with the same objective to 1e-12 (34 iterations and 2.29e-05 …)"
    from qdframe.errors import InputError

    result = qdframe.solve("paper-7.1", nodes=11, direction=ns["ScipyQP"]())
    native = qdframe.solve("paper-7.1", nodes=11, direction="native")
    assert result.status == native.status == "stationary" and result.iterations == native.iterations
    assert result.objective == pytest.approx(native.objective, rel=1e-12)
    assert about(result.iterations, 34) and result.objective == pytest.approx(2.29e-05, rel=5e-3)
    with pytest.raises(InputError):  # "`ScipyQP(ftol=0)` ... refused"
        ns["ScipyQP"](ftol=0)


def theta_method(ns, out):
    # "θ = 3/4": Z_k = Z_{k−1} + h·(z_{k−1}/4 + 3z_k/4), on the mesh h = 1/4
    layout = ns["ThetaMethod"]().layout(np.linspace(0.0, 1.0, 5))
    increments = layout.increments.toarray()
    assert np.allclose(increments[2, 1:3], [0.25 * 0.25, 0.75 * 0.25])


def my_models_tests(ns, out, tmp_path):
    """Section 6: the package the page lays out, installed (a .dist-info with its entry points
    on sys.path), and its tests run."""
    text = (ROOT / "docs/authoring.md").read_text()
    package = tmp_path / "pkg" / "my_models"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    for code, _ in blocks("docs/authoring.md"):
        match = re.match(r'"""my_models/(\w+\.py)', code)
        if match:
            (package / match.group(1)).write_text(code)
    tomls = re.findall(r"^```toml\n(.*?)^```", text, re.S | re.M)
    # "plus the scheme's section `[project.entry-points."qdframe.schemes"]` with `theta = …`"
    prose = re.search(r'plus the scheme\'s section `(\[project\.entry-points\."qdframe\.schemes"\])` with\s+`([^`]*)`',
                      text)
    assert prose, "section 6 names the scheme's entry point"
    # the whole pyproject.toml, then the scheme
    groups = entry_point_groups([tomls[-1], f"{prose.group(1)}\n{prose.group(2)}\n"])
    info = tmp_path / "pkg" / "my_models-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: my-models\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text(
        "".join(f"[{g}]\n" + "".join(f"{k} = {v}\n" for k, v in entries.items()) for g, entries in groups.items()))
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(tmp_path / "pkg"))
        registry.refresh()
        try:
            tests = [name for name in ns if name.startswith("test_") and callable(ns[name])]
            assert len(tests) == 3
            for name in tests:
                ns[name]()
        finally:
            patch.undo()
            for name in [m for m in sys.modules if m == "my_models" or m.startswith("my_models.")]:
                del sys.modules[name]
            registry.refresh()


CHECKS: dict[tuple[str, str], Callable] = {
    ("README.md", 'result = qdframe.solve("block-stop-stick")'): readme_first_solve,
    ("README.md", "class MyPendulum(SetModel):"): readme_plugin,
    ("docs/guide.md", 'model = qdframe.load_model("paper-7.1")'): guide_python,
    ("docs/guide.md", 'stop = qdframe.solve("block-stopping-time")'): guide_unknowns,
    ("docs/authoring.md", "class HeatedRoom(SetModel):"): heated_room,
    ("docs/authoring.md", "Room = define_model("): room_script,
    ("docs/authoring.md", "class BlockToMark(SetModel):"): block_to_mark,
    ("docs/guide.md", "class LeastEffort(SetModel):"): guide_optimal_control,
    ("docs/authoring.md", "class Docking(SetModel):"): docking,
    ("docs/authoring.md", "class PeriodicStickSlip(SetModel):"): periodic_stick_slip,
    ("docs/authoring.md", "class HandWrittenCoefficient(InclusionModel):"): hand_written_coefficient,
    ("docs/authoring.md", "class CoulombPendulum(SetModel):"): coulomb_pendulum,
    ("docs/authoring.md", "class Puck(SetModel):"): puck,
    ("docs/authoring.md", "class HandPuck(InclusionModel):"): hand_puck,
    ("docs/authoring.md", "class ReleasedFromSimulation(Released):"): released,
    ("docs/authoring.md", "class ShakenBlock(SetModel):"): shaken_block,
    ("docs/authoring.md", "class DampedGaussNewton(GaussNewton):"): solvers,
    ("docs/authoring.md", "direction=GaussNewton(mu=1e-8, mu_max=1e4)"): options_from_python,
    ("docs/authoring.md", "class ScipyQP(QPDirection):"): scipy_qp,
    ("docs/authoring.md", "class ThetaMethod(Scheme):"): theta_method,
    ("docs/authoring.md", "def test_heated_room_checks_and_solves():"): my_models_tests,
}


def test_every_check_picks_one_block_and_every_not_run_block_says_why():
    for (page, line), check in CHECKS.items():
        picked = [reason for code, reason in blocks(page) if line in code]
        assert len(picked) == 1, f"{page}: {len(picked)} blocks hold {line!r} ({check.__name__})"
        assert picked[0] is None, f"{page}: the block holding {line!r} is marked not run, but its check must run"
    for page in PAGES:
        for reason in NOT_RUN_MARK.findall((ROOT / page).read_text()):
            assert reason.strip(), f"{page}: a block marked not run without a reason"


@pytest.mark.parametrize("page", PAGES)
def test_the_pages_python_runs_and_says_what_it_does(page, tmp_path, monkeypatch):
    import matplotlib
    import matplotlib.pyplot as plt

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    module = types.ModuleType("docs_" + re.sub(r"\W", "_", page))
    monkeypatch.setitem(sys.modules, module.__name__, module)  # dataclasses look their module up
    ns = module.__dict__
    ran = 0
    try:
        for index, (code, reason) in enumerate(blocks(page)):
            if reason is not None:
                continue
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                exec(compile(code, f"{page}, python block {index + 1}", "exec"), ns)
            ran += 1
            for (where, line), check in CHECKS.items():
                if where == page and line in code:
                    if check is my_models_tests:
                        check(ns, printed.getvalue(), tmp_path)
                    else:
                        check(ns, printed.getvalue())
        defined = [value for value in ns.values() if isinstance(value, type) and issubclass(value, InclusionModel)
                   and value.__module__ == module.__name__ and not value.__name__.startswith("_")]
        for cls in defined:  # built, so that `sets` runs; its pieces' gradients checked
            report = check_model(cls(), samples=16, seed=0)
            assert report.ok, f"{page}: {cls.__name__}: {report.table()}"
    finally:
        plt.close("all")
    assert ran >= 2
