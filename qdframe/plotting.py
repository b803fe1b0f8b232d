"""Figures of a result, like the paper's Figure 1: trajectories, z_i(t) against the
bounds of F_i(x(t)), and the functional per iteration on a log scale."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .result import SolveResult


def plot_result(result: SolveResult, path: str | Path) -> None:
    """Write the figure of `result` to `path` (format from the suffix)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(result.state_names)
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2), constrained_layout=True)
    trajectories, velocities, history = axes

    for i, name in enumerate(result.state_names):
        trajectories.plot(result.t, result.x[:, i], label=name)
    title = "trajectories x(t)"
    if result.u is not None:  # the unknown controls (paper Figure 4 shows u(t))
        for j in range(result.u.shape[1]):
            trajectories.plot(result.t, result.u[:, j], "k--", lw=1.2, label=f"u{j + 1}" if result.u.shape[1] > 1 else "u")
        title = "trajectories x(t) and controls u(t)"
    trajectories.set(title=title, xlabel="t")
    trajectories.legend(ncol=2 if len(result.state_names) > 3 else 1, fontsize="small")

    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i in range(n):
        color = colors[i % len(colors)]
        velocities.plot(result.t, result.z[:, i], color=color, label=f"z{i + 1}")
    # bounds of the one-coordinate sets F_i(x(t)), colored as their coordinate
    for bounds in result.set_bounds:
        if bounds is None:
            continue
        lower, upper = np.asarray(bounds["lower"]), np.asarray(bounds["upper"])
        color = colors[bounds["coordinate"] % len(colors)]
        velocities.fill_between(result.t, lower, upper, color=color, alpha=0.15, lw=0)
        velocities.plot(result.t, lower, color=color, ls="--", lw=0.8)
        velocities.plot(result.t, upper, color=color, ls=":", lw=0.8)
    velocities.set(title="z(t) and the bounds of F(x(t))", xlabel="t")
    velocities.legend()

    iterations = [h.iteration for h in result.history]
    history.semilogy(iterations, [max(h.I, 1e-300) for h in result.history], marker=".", label="I")
    if result.cost is not None:
        history.semilogy(iterations, [max(h.objective, 1e-300) for h in result.history], marker=".", label="objective")
    history.set(title=f"{result.model}: {result.status} after {result.iterations} iterations", xlabel="iteration")
    history.legend()
    fig.savefig(path, dpi=110)
    plt.close(fig)
