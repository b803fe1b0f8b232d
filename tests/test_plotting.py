"""The --plot figure and SolveResult.plot(): labels, legend, integer iterations, the
support panel of a ball-like set, saving only with a path, trapezoid interval means."""

from __future__ import annotations

import dataclasses

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from qdframe.solve.solving import solve  # noqa: E402
from qdframe.registry import load_model
from qdframe.errors import InputError  # noqa: E402
from qdframe.plotting import math_label, plot_result  # noqa: E402


@pytest.fixture(scope="module")
def result71():
    return solve("paper-7.1", nodes=11)


@pytest.fixture(scope="module")
def result72():
    return solve("paper-7.2", nodes=11)


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def _labels(ax) -> list[str]:
    legend = ax.get_legend()
    return [text.get_text() for text in legend.get_texts()] if legend is not None else []


def test_plot_returns_a_figure_of_three_labelled_panels(result71):
    fig = result71.plot()
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 3
    for ax in fig.axes:
        assert ax.get_ylabel().strip() and ax.get_xlabel().strip()
    assert result71.status in fig.get_suptitle() and result71.model in fig.get_suptitle()


def test_the_iteration_axis_has_integer_ticks(result71):
    fig = result71.plot()
    history = fig.axes[2]
    locator = history.xaxis.get_major_locator()
    assert isinstance(locator, MaxNLocator) and locator._integer
    fig.canvas.draw()
    ticks = history.get_xticks()
    assert len(ticks) >= 2 and all(float(tick).is_integer() for tick in ticks)


def test_velocities_are_labelled_by_state_names_and_the_band_is_in_the_legend(result71):
    labels = _labels(result71.plot().axes[1])
    assert {math_label(name, prime=True) for name in result71.state_names} <= set(labels)
    assert not any(label.startswith("z1") for label in labels)
    banded = [b for b in result71.set_bounds if b is not None and np.ptp(np.subtract(b["upper"], b["lower"])) > 0]
    assert banded, "paper-7.1 has a one-coordinate set of positive width"
    for bounds in banded:
        i = bounds["coordinate"]
        assert any(label.startswith(f"$F_{{{i + 1}}}(x(t))$ bounds") for label in labels), labels


def test_a_ball_set_shows_the_norm_of_z_against_its_support(result72):
    assert all(bounds is None for bounds in result72.set_bounds)  # no one-coordinate bounds in 7.2
    middle = result72.plot().axes[1]
    lines = {line.get_label(): line for line in middle.get_lines()}
    norm = lines["|($x_{1}'$, $x_{2}'$)|"].get_ydata()
    support = lines["$c(F(x(t)),\\, z/|z|)$"].get_ydata()
    assert len(norm) == len(support) > 1
    # z ∈ F(x) means <z, ψ> ≤ c(F, ψ) for every ψ, so along ψ = z/|z|: |z| ≤ c (solved run)
    assert result72.solved and np.all(norm <= support + 1e-9)
    assert "B2 ∩ E2(x)" in middle.get_legend().get_title().get_text()  # the set as the model names it
    mean_z = 0.5 * (result72.z[1:] + result72.z[:-1])  # the trapezoid's means (7.2 uses it)
    np.testing.assert_allclose(norm, np.linalg.norm(mean_z, axis=1))


def test_without_a_registered_model_the_norm_is_still_drawn_with_a_note(result72):
    renamed = dataclasses.replace(result72, model="no-such-model")
    middle = renamed.plot().axes[1]
    labels = [line.get_label() for line in middle.get_lines()]
    assert "|($x_{1}'$, $x_{2}'$)|" in labels and not any(label.startswith("$c(") for label in labels)
    assert "pass model=" in middle.get_legend().get_title().get_text()
    # the model given by hand brings the support back
    middle = renamed.plot(model=load_model("paper-7.2")).axes[1]
    assert any(line.get_label().startswith("$c(") for line in middle.get_lines())


def test_trapezoid_results_show_interval_means_so_the_null_mode_is_gone(result71):
    assert result71.options["scheme"] == "trapezoid"
    k = np.arange(result71.z.shape[0])
    # z_k + (−1)^k·c leaves every x_k of the trapezoid rule unchanged: the scheme's null mode
    zigzag = dataclasses.replace(result71, z=result71.z + 0.1 * (-1.0) ** k[:, None])
    clean = result71.plot().axes[1].get_lines()[0].get_ydata()
    shown = zigzag.plot().axes[1].get_lines()[0].get_ydata()
    np.testing.assert_allclose(shown, clean, atol=1e-12)
    assert len(shown) == len(k) - 1
    nodal = zigzag.plot(velocities="nodes").axes[1].get_lines()[0].get_ydata()
    np.testing.assert_array_equal(nodal, zigzag.z[:, 0])


def test_saving_writes_the_file_only_when_a_path_is_given(result71, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    before = plt.get_fignums()
    fig = result71.plot()
    assert list(tmp_path.iterdir()) == []
    assert fig.number in plt.get_fignums()  # a pyplot figure: plt.show() or a notebook shows it
    path = tmp_path / "figure.png"
    saved = result71.plot(path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert isinstance(saved, Figure) and plt.get_fignums() == before + [fig.number]  # not kept by pyplot
    plot_result(result71, tmp_path / "figure.svg")  # the CLI's call
    assert (tmp_path / "figure.svg").stat().st_size > 0


def test_in_a_notebook_the_figure_is_not_kept_by_pyplot(result71, monkeypatch):
    """The inline backend displays pyplot's figures at the end of a cell: a returned pyplot
    figure would appear twice, so there the figure is a plain one, shown as the value."""
    monkeypatch.setattr(matplotlib, "get_backend", lambda: "module://matplotlib_inline.backend_inline")
    before = plt.get_fignums()
    fig = result71.plot()
    assert isinstance(fig, Figure) and plt.get_fignums() == before


def test_an_unknown_velocity_mode_is_an_input_error(result71):
    with pytest.raises(InputError, match="velocities"):
        result71.plot(velocities="smooth")
