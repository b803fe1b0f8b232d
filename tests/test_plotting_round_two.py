"""Issue 35, item 9: figures that read like a paper — mathtext labels, legends outside the
data and inside the figure, no legend entry for a band no one can see, states and
controls on separate axes, stage labels inside the figure, the bench's history figure
labelled by run."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402

from qdframe.solve.solving import solve  # noqa: E402
from qdframe.plotting import math_label, plot_result  # noqa: E402


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def result71():
    return solve("paper-7.1", nodes=101)  # trapezoid, error estimate ~1e-10


@pytest.fixture(scope="module")
def result73():
    return solve("paper-7.3", nodes=21)  # a control u that peaks far above the states


@pytest.fixture(scope="module")
def stick():
    # a visible error band (bisection: both ends given), a switch, and (from the model's own start) a band start
    return solve("block-stop-stick-bvp", nodes=101, simulate_start=False)


def _drawn(result):
    fig = plot_result(result)
    fig.canvas.draw()
    return fig


def _texts(ax):
    legend = ax.get_legend()
    return [t.get_text() for t in legend.get_texts()] if legend is not None else []


@pytest.mark.parametrize("name, text", [
    ("x1", "$x_{1}$"), ("theta", "$\\theta$"), ("omega2", "$\\omega_{2}$"), ("position", "$\\mathrm{position}$"),
    ("x-dot", "x-dot"),
])
def test_state_names_become_mathtext(name, text):
    assert math_label(name) == text
    assert math_label(name, prime=True) == (text[:-1] + "'$" if text.endswith("$") else text + "′")


def test_labels_are_mathtext(result71):
    fig = _drawn(result71)
    trajectories, velocities, history = fig.axes
    assert "$x_{1}$" in _texts(trajectories) and "$x_{1}'$" in _texts(velocities)
    assert any(label.startswith("$F_{1}(x(t))$ bounds") for label in _texts(velocities))
    assert "$\\frac{1}{2}(z_{k-1} + z_k)$" in velocities.get_title()  # the trapezoid's interval means
    assert history.get_ylabel() == "objective, $I$" and velocities.get_ylabel() == "$z(t) = x'(t)$"
    assert "$F_i(x(t))$ a single point for $x_{2}'$" in velocities.get_legend().get_title().get_text()


@pytest.mark.parametrize("which", ["result71", "result73", "stick"])
def test_legends_lie_outside_the_data_and_every_text_inside_the_figure(request, which):
    fig = _drawn(request.getfixturevalue(which))
    renderer = fig.canvas.get_renderer()
    page = fig.bbox
    for ax in fig.axes:
        legend = ax.get_legend()
        assert legend is not None
        box = legend.get_window_extent(renderer)
        assert not box.overlaps(ax.get_window_extent(renderer)), f"{ax.get_title()}: legend over the data"
        assert page.x0 - 1 <= box.x0 and box.x1 <= page.x1 + 1 and page.y0 - 1 <= box.y0, "legend cut off"
        for text in [ax.title, ax.xaxis.label, ax.yaxis.label, *ax.texts]:
            if text.get_text() and text.get_visible():
                extent = text.get_window_extent(renderer)
                assert page.x0 - 1 <= extent.x0 and extent.x1 <= page.x1 + 1, f"{text.get_text()!r} cut off"


def test_a_band_thinner_than_a_line_is_not_in_the_legend_but_said(result71):
    assert result71.error_estimate < 1e-8
    trajectories = _drawn(result71).axes[0]
    assert not [c for c in trajectories.collections if isinstance(c, PolyCollection)]
    assert trajectories.get_title().endswith(f"error estimate e = {result71.error_estimate:.1e} (below line width)")
    assert not any("\\pm" in label for label in _texts(trajectories))


def test_a_visible_band_is_drawn_and_named(stick):
    assert stick.error_estimate > 1e-3
    trajectories = _drawn(stick).axes[0]
    assert [c for c in trajectories.collections if isinstance(c, PolyCollection)]
    assert "$x \\pm e$" in _texts(trajectories) and trajectories.get_title().endswith(f"e = {stick.error_estimate:.1e}")


def test_states_and_controls_have_separate_axes(result73):
    fig = _drawn(result73)
    trajectories, velocities, history, inputs = fig.axes
    assert inputs.get_ylabel() == "control $u(t)$" and "$u$" in _texts(inputs)
    assert not any(np.allclose(line.get_ydata(), result73.u[:, 0]) for line in trajectories.get_lines()
                   if len(line.get_ydata()) == len(result73.t))
    low, high = trajectories.get_ylim()
    assert high - low < np.ptp(result73.u) / 3  # the states keep their own scale


def test_new_stages_are_named_in_the_legend_not_over_the_data(stick):
    history = _drawn(stick).axes[2]
    assert not history.texts  # no label written over the curves
    (stage,) = [label for label in _texts(history) if label.startswith("new stage")]
    restarts = [h.iteration for h, g in zip(stick.history[1:], stick.history) if h.iteration <= g.iteration]
    assert restarts and stage.replace("\n", " ").endswith(f"101 at {restarts[0]}")  # the exact solve after the band start


def test_the_bench_history_figure_names_each_run(tmp_path):
    from qdframe.bench.report import plot_histories

    def row(model, direction, knob, status, values):
        return {"model": model, "direction": direction, "line_search": "armijo", "knob": knob, "nodes": 41,
                "status": status, "history": {"iteration": list(range(len(values))), "I": values}}

    rows = [row("paper-7.1", "gauss-newton", "N=41", "solved", [1.0, 1e-3, 1e-12]),
            row("paper-7.1", "native", "N=41", "stationary", [1.0, 0.5, 0.2]),
            {**row("paper-7.1", "solve_bvp", "tol=0.001", "solved", []), "history": None}]
    captured = {}
    real = plt.Figure.savefig

    def keep(fig, path, **kwargs):
        captured["fig"] = fig
        return real(fig, path, **kwargs)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(plt.Figure, "savefig", keep)
        plot_histories(rows, tmp_path / "history.png")
    fig = captured["fig"]
    (ax,) = [a for a in fig.axes if a.get_visible()]
    labels = _texts(ax)
    assert any(label.startswith("gauss-newton") and "N=41" in label and "solved" in label for label in labels)
    assert any(label.startswith("native") and "stationary" in label for label in labels)
    assert not any("solve_bvp" in label for label in labels)  # no line, no legend entry
    assert "no iteration history, not drawn: solve_bvp" in fig.get_supxlabel()
