"""Figures of a result, like the paper's Figure 1: the trajectories, x' = z against the set
F(x(t)), and the functional per iteration on a log scale.

:func:`plot_result` (and :meth:`SolveResult.plot <qdframe.result.SolveResult.plot>`)
returns the Matplotlib Figure and saves it only when given a path:

* left: x(t) by state name, with the error estimate e in the title and as a band x ± e
  (not drawn, and the title says so, when it is below a line's width at the panel's
  scale) and the switch times;
  the unknown controls u(t) on their own axes below (their scale is not the states': on
  paper-7.3 u peaks at 62 while the states stay within ±3);
* middle: z(t) = x'(t), labelled x₁′, x₂′, …, with the interval [lo_i, hi_i] of every
  one-coordinate set F_i(x(t)) shaded in its coordinate's color; for a block of k ≥ 2
  coordinates (a ball, an intersection: ψ ∈ S_k) the norm |z_b(t)| against the model's
  support value c(F_b(x(t)), z_b/|z_b|), which z_b ∈ F_b(x) keeps above |z_b|;
* right: I (and the objective when the model has a cost) per iteration, a new stage
  (the next grid of a continuation, or the exact-sign solve after its band start) marked
  by a vertical line labelled along it with its grid.

Labels are mathtext (x₁, F₁(x(t)), ½(z_{k−1} + z_k)); every legend sits below its panel,
outside the data, and the figure's layout makes room for it.

The trapezoid rule integrates the interval means (z_{k−1} + z_k)/2, x_k = x_{k−1} +
h·(z_{k−1} + z_k)/2, and leaves the alternating mode z_k = (−1)^k·c of the nodal
values free: so for a trapezoid result the middle panel shows the means at the interval
midpoints (and the means of the bounds, which contain them), not the nodal zig-zag.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

if TYPE_CHECKING:  # types only
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .model import InclusionModel

# a qdframe.result.SolveResult, read by its attributes: a result draws itself through this
# module (SolveResult.plot), which therefore does not import it
SolveResult = Any

VELOCITY_MODES = ("auto", "nodes", "means")
POINT_WIDTH = 1e-12  # relative: an interval [lo, hi] no wider than this is drawn as a point
BAND_VISIBLE = 5e-3  # the error band x ± e is drawn when 2e is at least this fraction of the states' range
LEGEND_GAP = 34.0  # points from the bottom of a panel to its legend: below the tick labels and the axis label
LEGEND_WIDTH = 44  # characters a legend line may take under a panel (wider labels wrap, or take one column)
STAGES_NAMED = 4  # the history legend names the grid and first iteration of this many stages
GREEK = {"alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "iota", "kappa", "lambda", "mu",
         "nu", "xi", "pi", "rho", "sigma", "tau", "upsilon", "phi", "chi", "psi", "omega", "Gamma", "Delta",
         "Theta", "Lambda", "Xi", "Pi", "Sigma", "Phi", "Psi", "Omega"}


def plot_result(
    result: SolveResult,
    path: str | Path | None = None,
    *,
    model: InclusionModel | None = None,
    velocities: Literal["auto", "nodes", "means"] = "auto",
    figsize: tuple[float, float] = (14.0, 5.6),
    dpi: float = 100.0,
) -> Figure:
    """The three-panel figure of `result`; written to `path` when given (format from the
    suffix: PNG, PDF, SVG, …, at `dpi`).

    `model` gives the sets F_b of blocks of k ≥ 2 coordinates, whose support the middle
    panel draws; by default the registered model of the result's name is loaded (only
    for such blocks). Pass the model when it was built by hand or with other parameters.
    `velocities`: "nodes" plots z_k at the nodes, "means" the interval means
    (z_{k−1} + z_k)/2 at the midpoints, "auto" the means for the trapezoid rule (the
    values it integrates) and the nodes otherwise.

    With a path the figure is saved and not registered with pyplot (no window opens,
    nothing to close). Without one it is a pyplot figure, shown by `plt.show()`; in a
    notebook (the inline backend) it is a plain Figure, displayed once as the cell's value.
    """
    if velocities not in VELOCITY_MODES:
        from .errors import InputError

        raise InputError("velocities", " or ".join(f'"{mode}"' for mode in VELOCITY_MODES), velocities)
    if _use_pyplot(path):
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=figsize, layout="constrained")
    else:
        from matplotlib.figure import Figure

        fig = Figure(figsize=figsize, layout="constrained")
    if result.u is None:
        trajectories, velocity_axes, history = fig.subplots(1, 3)
        inputs = None
    else:  # the controls on their own axes under the states: another scale
        grid = fig.add_gridspec(2, 3, height_ratios=(3, 2))
        trajectories = fig.add_subplot(grid[0, 0])
        velocity_axes, history = fig.add_subplot(grid[:, 1]), fig.add_subplot(grid[:, 2])
        inputs = fig.add_subplot(grid[1, 0], sharex=trajectories)
    _trajectories(trajectories, result)
    if inputs is not None:
        _inputs(inputs, result)
    scheme = result.descent.scheme
    means = velocities == "means" or (velocities == "auto" and scheme == "trapezoid")
    _velocities(velocity_axes, result, means, model)
    _history(history, result)
    grid = f"{result.nodes} nodes" + (f", {scheme}" if scheme else "")
    count = f"{result.iterations} iteration" + ("" if result.iterations == 1 else "s")
    found = ([f"T = {result.T:.8g}"] if result.T_found else []) + [
        f"{name} = {value:.8g}" for name, value in result.parameters.items()]
    fig.suptitle(f"{result.model}: {result.status} after {count} ({grid})" + (f"; found {', '.join(found)}" if found else ""))
    if path is not None:
        fig.savefig(path, dpi=dpi)
    return fig


def _use_pyplot(path: str | Path | None) -> bool:
    """Register the figure with pyplot only when it is not saved and the backend is not a
    notebook's inline one: there the returned Figure is displayed as the cell's value, and
    a pyplot figure would be displayed a second time at the end of the cell."""
    if path is not None:
        return False
    import matplotlib
    import matplotlib.pyplot  # noqa: F401  (loads the backend: in a notebook, its display hooks)

    return "inline" not in str(matplotlib.get_backend()).lower()


def _colors() -> list[str]:
    import matplotlib as mpl

    return mpl.rcParams["axes.prop_cycle"].by_key()["color"]


def math_label(name: str, prime: bool = False) -> str:
    """A state or control name as mathtext: x1 → $x_{1}$, theta → $\\theta$, omega2′ → $\\omega_{2}'$,
    position → $\\mathrm{position}$; a name mathtext cannot take stays text (with ′)."""
    import re

    match = re.fullmatch(r"([A-Za-z]+?)_?(\d*)", name)
    if match is None:
        return name + ("′" if prime else "")
    letters, digits = match.groups()
    base = f"\\{letters}" if letters in GREEK else letters if len(letters) == 1 else f"\\mathrm{{{letters}}}"
    return f"${base}" + (f"_{{{digits}}}" if digits else "") + ("'" if prime else "") + "$"


def _legend_below(ax: Axes, handles: list | None = None, labels: list | None = None, *, columns: int = 2,
                  title: str | None = None) -> None:
    """The panel's legend under it, LEGEND_GAP points below its frame (clear of the tick labels and
    the axis label): never over the data; the figure's constrained layout makes room."""
    from matplotlib.transforms import offset_copy

    import re

    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    # no wider than its panel: the layout would squeeze the panels, and a legend wider than the
    # figure would be cut. Plain labels are wrapped; a long label (mathtext counted as shown) gets one column
    labels = [label if "$" in label else textwrap.fill(label, LEGEND_WIDTH) for label in labels]
    widest = max(len(line) for label in labels for line in re.sub(r"\$[^$]*\$", "xx", label).splitlines())
    columns = max(1, min(columns, len(handles), LEGEND_WIDTH // max(widest, 1)))
    below = offset_copy(ax.transAxes, fig=ax.figure, y=-LEGEND_GAP, units="points")
    ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), bbox_transform=below,
              ncol=columns, fontsize="small", title=title, title_fontsize="x-small")


def _trajectories(ax: Axes, result: SolveResult) -> None:
    """x(t) by state name with its error estimate as a band x ± error_estimate (a legend
    line instead when the band is thinner than a line at this scale) and the switch times
    as dotted verticals (paper Figure 4)."""
    colors = _colors()
    estimate = getattr(result, "error_estimate", None)
    x = np.asarray(result.x, float)
    span = float(np.ptp(x)) if x.size else 0.0
    visible = estimate is not None and 2.0 * estimate >= BAND_VISIBLE * max(span, 1e-300)
    for i, name in enumerate(result.state_names):
        color = colors[i % len(colors)]
        ax.plot(result.t, x[:, i], color=color, label=math_label(name))
        if visible:
            ax.fill_between(result.t, x[:, i] - estimate, x[:, i] + estimate, color=color, alpha=0.25,
                            lw=0, label="$x \\pm e$" if i == 0 else None)
    handles, labels = ax.get_legend_handles_labels()
    _switch_lines(ax, result, handles, labels)
    title = "trajectories"
    if estimate is not None:  # the value in the title; a band no one could see is not drawn, and said so
        title += f"\nerror estimate e = {estimate:.1e}" + ("" if visible else " (below line width)")
    ax.set(title=title, xlabel="t", ylabel="state $x(t)$")
    _legend_below(ax, handles, labels, columns=3 if len(labels) > 4 else 2)


def _switch_lines(ax: Axes, result: SolveResult, handles: list, labels: list) -> None:
    """The switch times as dotted verticals, one legend entry."""
    for k, time in enumerate(getattr(result, "switch_times", ())):
        line = ax.axvline(time, color="0.4", ls=":", lw=1.0)
        if k == 0:
            handles.append(line)
            labels.append("switch times")


def _inputs(ax: Axes, result: SolveResult) -> None:
    """The unknown controls u(t) on their own axes (another scale than the states')."""
    u = np.asarray(result.u, float)
    names = list(result.control_names) or [f"u{j + 1}" for j in range(u.shape[1])]
    styles = ["-", "--", "-.", ":"]
    for j, name in enumerate(names):
        ax.plot(result.t, u[:, j], color="k", ls=styles[j % len(styles)], lw=1.2, label=math_label(name))
    handles, labels = ax.get_legend_handles_labels()
    _switch_lines(ax, result, handles, labels)
    ax.set(xlabel="t", ylabel="control $u(t)$")
    _legend_below(ax, handles, labels, columns=4)


def _velocities(ax: Axes, result: SolveResult, means: bool, model: InclusionModel | None) -> None:
    """z = x' by state name against F(x(t)): intervals shaded, k-blocks by norm and support."""
    from matplotlib.patches import Patch

    colors = _colors()
    names = result.state_names
    t, z = np.asarray(result.t, float), np.asarray(result.z, float)
    average = (lambda v: 0.5 * (v[1:] + v[:-1])) if means else (lambda v: v)
    tt = average(t)
    for i, name in enumerate(names):
        ax.plot(tt, average(z[:, i]), color=colors[i % len(colors)], label=math_label(name, prime=True))
    handles: list[Any] = []
    points: list[str] = []  # coordinates whose F_i(x(t)) is a single point (an equation, a selection)
    for bounds in result.set_bounds:
        if bounds is None:
            continue
        lower, upper = average(np.asarray(bounds["lower"], float)), average(np.asarray(bounds["upper"], float))
        i = bounds["coordinate"]
        if np.all(upper - lower <= POINT_WIDTH * (1.0 + np.abs(upper))):
            points.append(math_label(names[i], prime=True))
            continue
        color = colors[i % len(colors)]
        ax.fill_between(tt, lower, upper, color=color, alpha=0.18, lw=0)
        ax.plot(tt, lower, color=color, ls="--", lw=0.8)
        ax.plot(tt, upper, color=color, ls=":", lw=0.8)
        handles.append(Patch(facecolor=color, alpha=0.35, edgecolor=color, ls="--",
                             label=f"$F_{{{i + 1}}}(x(t))$ bounds of {math_label(names[i], prime=True)} "
                                   "(-- lower, ·· upper)"))
    notes = _block_supports(ax, result, means, model, colors)
    if points:
        notes.append(f"$F_i(x(t))$ a single point for {', '.join(points)}")
    title = "velocities $x' = z$"
    if means:
        title += ": interval means $\\frac{1}{2}(z_{k-1} + z_k)$ (trapezoid)"
    ax.set(title=title, xlabel="t" + (" (interval midpoints)" if means else ""), ylabel="$z(t) = x'(t)$")
    lines, labels = ax.get_legend_handles_labels()
    _legend_below(ax, lines + handles, labels + [h.get_label() for h in handles],
                  columns=3 if len(lines) + len(handles) > 4 else 2, title="\n".join(notes) or None)


def _block_supports(ax: Axes, result: SolveResult, means: bool, model: InclusionModel | None,
                    colors: list[str]) -> list[str]:
    """For each block of k ≥ 2 coordinates: |z_b(t)| and, with the model, its support
    c(F_b(x(t)), z_b/|z_b|) (≥ |z_b| when z_b ∈ F_b). Returns notes for the panel."""
    missing = [b for b, bounds in enumerate(result.set_bounds) if bounds is None]
    if not missing:
        return []
    model, why = _resolve_model(result, model)
    blocks = list(model.blocks()) if model is not None else None
    if blocks is not None and len(blocks) != len(result.set_bounds):
        model, blocks, why = None, None, f"the model {result.model!r} loaded has other blocks than the result's"
    t, x, z = (np.asarray(a, float) for a in (result.t, result.x, result.z))
    y = x if result.u is None else np.concatenate([x, np.asarray(result.u, float)], axis=1)
    notes = []
    for b in missing:
        coords = list(blocks[b].coords) if blocks is not None else _unbounded_coords(result)
        label = "(" + ", ".join(math_label(result.state_names[i], prime=True) for i in coords) + ")"
        color = colors[(len(result.state_names) + b) % len(colors)]  # apart from the coordinates' colors
        zb = z[:, coords]
        if means:
            zb = 0.5 * (zb[1:] + zb[:-1])
        norm = np.linalg.norm(zb, axis=1)
        tt = 0.5 * (t[1:] + t[:-1]) if means else t
        ax.plot(tt, norm, color=color, lw=2.2, alpha=0.8, label=f"|{label}|")
        if blocks is None:
            notes.append(f"F on {label}: a set in R^{len(coords)}, its support not drawn\n({why}; pass model=)")
            continue
        support = _support(model, blocks[b], y, zb, means)
        ax.plot(tt, support, color=color, ls="--", lw=1.4, label="$c(F(x(t)),\\, z/|z|)$")
        notes.append(f"F on {label} = {_set_name(blocks[b])}\n$z \\in F$ gives $|z| \\leq c(F, z/|z|)$, "
                     "its support along z")
    return notes


def _resolve_model(result: SolveResult, model: InclusionModel | None) -> tuple[InclusionModel | None, str]:
    """The given model, else the registered one of the result's name (with a reason if none)."""
    if model is not None:
        return model, ""
    from .registry import load_model
    from .errors import QdframeError

    try:
        loaded = load_model(result.model)
    except QdframeError as exc:
        return None, f"no registered model {result.model!r}: {exc}"
    if tuple(loaded.state_names) != tuple(result.state_names):
        return None, f"the registered {result.model!r} has other states"
    if loaded.parameter_names:  # its sets at the values found
        from .unknowns import Unknowns, restated

        loaded = Unknowns(restated(loaded, False, result.parameters or None), fixed=True)
    return loaded, ""


def _unbounded_coords(result: SolveResult) -> list[int]:
    """Without the model: the coordinates no one-coordinate bound covers."""
    covered = {bounds["coordinate"] for bounds in result.set_bounds if bounds is not None}
    return [i for i in range(len(result.state_names)) if i not in covered]


def _set_name(block: Any, width: int = 48) -> str:
    """The set as the model names it: its groups' names (a sum of them), or the block's
    name when those are missing or too long for a legend."""
    named = [group.name for group in (*block.max_groups, *block.min_groups) if group.name not in ("max", "min")]
    text = " + ".join(f"({g})" if len(named) > 1 and " " in g else g for g in named)
    return text if named and len(text) <= width else (block.name or "F")


def _support(model: InclusionModel, block: Any, y: np.ndarray, zb: np.ndarray, means: bool) -> np.ndarray:
    """c(F_b(y), ψ) at ψ = zb/|zb| (ψ = e_1 where z_b = 0), per node; with `means` the
    mean of the two end nodes' values per interval, which bounds <z̄_b, ψ> = |z̄_b|."""
    from .functional import Functional
    from .schemes.grid import Grid

    functional = Functional(model, Grid(float(model.T), 2))
    norm = np.linalg.norm(zb, axis=1, keepdims=True)
    psi = np.where(norm > 0, zb / np.where(norm > 0, norm, 1.0), np.eye(zb.shape[1])[0])

    def value(rows: np.ndarray) -> np.ndarray:
        zero = np.zeros((rows.shape[0], model.n_states))
        return -functional.pieces.side(block, rows, zero, psi).ell

    if means:
        return 0.5 * (value(y[:-1]) + value(y[1:]))
    return value(y)


def _history(ax: Axes, result: SolveResult) -> None:
    """I (and the objective) per iteration, log scale, integer ticks; each stage its own
    line (a stage starts where the iteration number repeats), zeros marked at the bottom."""
    from matplotlib.ticker import MaxNLocator

    records = result.history
    series = [("I", lambda h: h.I, "C0")]
    if result.cost is not None:
        series.insert(0, ("objective", lambda h: h.objective, "C1"))
    starts = [0] + [k for k in range(1, len(records)) if records[k].iteration <= records[k - 1].iteration]
    stages = [records[a:b] for a, b in zip(starts, starts[1:] + [len(records)])]
    zeros: list[int] = []
    for label, get, color in series:
        for s, stage in enumerate(stages):
            values = np.array([get(h) for h in stage], float)
            zeros += [h.iteration for h, v in zip(stage, values) if v == 0]
            ax.semilogy([h.iteration for h in stage], np.where(values > 0, values, np.nan), marker=".",
                        color=color, label=label if s == 0 else None)
    starts = [f"{stage[0].nodes} at {stage[0].iteration}" for stage in stages[1:]]
    shown = ", ".join(starts[:STAGES_NAMED]) + (f", … ({len(starts)} in all)" if len(starts) > STAGES_NAMED else "")
    for s, stage in enumerate(stages[1:]):
        # each new stage a dotted line; which grid starts where is said in the legend, not over the data
        ax.axvline(stage[0].iteration, color="0.5", ls=":", lw=1,
                   label=f"new stage{'s' if len(starts) > 1 else ''} (grid N at iteration): {shown}" if s == 0 else None)
    if zeros:
        ax.plot(sorted(set(zeros)), [0.0] * len(set(zeros)), "v", color="k", transform=ax.get_xaxis_transform(),
                clip_on=False, label="value 0 (off the log scale)")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set(title="functional per iteration", xlabel="iteration",
           ylabel="objective, $I$" if result.cost is not None else "$I = \\varphi + \\chi + \\omega + \\upsilon + \\sigma$")
    _legend_below(ax, columns=2)
