"""The summary of a sweep: qpbenchmark-style metrics, figures and report.md.

Metrics follow qpbenchmark (github.com/qpsolvers/qpbenchmark, ``results.py``/``shgeom.py``),
with a "solver" = a direction solver and its line search (or a peer) and a "problem" = a
model on a grid:

* success rate: the percentage of a solver's runs that (1) report success (`solved`) and
  (2) pass the residual check, ``residual_error`` ≤ the residual tolerance;
* correct rate: the percentage of runs whose own success report agrees with that check,
  i.e. found == (found and valid) — a run that does not claim success is counted correct,
  a `solved` that the residuals do not confirm is not;
* runtime: the shifted geometric mean shm(t) = exp(mean(log(t_i + sh))) − sh with sh = 10,
  over each solver's wall times in seconds, a run that did not report success counted at
  the time limit; then, as qpbenchmark reports it, divided by the smallest shm of all
  solvers (1.0 is the fastest, Y means Y times slower). The shm in seconds is shown too.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from .peers import PEER_MODELS

SHIFT = 10.0
FIGURES = {
    "speed_vs_error": "speed_vs_error.png",
    "error_vs_nodes": "error_vs_nodes.png",
    "history": "objective_history.png",
}


def shifted_geometric_mean(values: Sequence[float], shift: float = SHIFT) -> float:
    """exp(Σ log(v_i + shift) / n) − shift for values ≥ 0 and shift ≥ 1 (qpbenchmark's shgeom)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return float("nan")
    if np.any(v < 0) or not np.all(np.isfinite(v)):
        raise InputError("shifted geometric mean", "finite values ≥ 0", v.tolist())
    if shift < 1.0:
        raise InputError("shift", "a number ≥ 1", shift)
    return float(np.exp(np.sum(np.log(v + shift)) / v.size) - shift)


def solver_label(row: dict) -> str:
    return f"{row['direction']} / {row['line_search']}"


def valid(row: dict, tol: float) -> bool:
    """The residual check: residual_error is known and ≤ tol."""
    error = row.get("residual_error")
    return error is not None and error <= tol


def summarize(rows: Sequence[dict], residual_tol: float, time_limit: float | None = None) -> list[dict]:
    """Per solver: runs, success rate, correct rate, runtime shm (s and × best), median error."""
    limit = _time_limit(rows, time_limit)
    groups: dict[str, list[dict]] = defaultdict(list)
    for row in rows:
        groups[solver_label(row)].append(row)
    table = []
    for label, runs in groups.items():
        found = [bool(r.get("found")) for r in runs]
        ok = [valid(r, residual_tol) for r in runs]
        times = [
            float(r["wall_time_s"]) if f and r.get("wall_time_s") is not None else limit
            for r, f in zip(runs, found)
        ]
        errors = [r["error"] for r in runs if r.get("error") is not None]
        walls = [r["wall_time_s"] for r in runs if r.get("wall_time_s") is not None]
        table.append({
            "solver": label,
            "runs": len(runs),
            "claimed": sum(found),
            "confirmed": sum(f and v for f, v in zip(found, ok)),
            "success_rate": 100.0 * sum(f and v for f, v in zip(found, ok)) / len(runs),
            "correct_rate": 100.0 * sum(f == (f and v) for f, v in zip(found, ok)) / len(runs),
            "runtime_shm_s": shifted_geometric_mean(times),
            "median_error": float(np.median(errors)) if errors else None,
            "median_time_s": float(np.median(walls)) if walls else None,
        })
    best = min((t["runtime_shm_s"] for t in table if t["runtime_shm_s"] > 0), default=float("nan"))
    for entry in table:
        entry["runtime_shm"] = entry["runtime_shm_s"] / best if best == best else float("nan")
    return sorted(table, key=lambda t: (-t["success_rate"], t["runtime_shm"], t["solver"]))


def _time_limit(rows: Sequence[dict], time_limit: float | None) -> float:
    if time_limit is not None:
        return float(time_limit)
    limits = [r["time_limit_s"] for r in rows if r.get("time_limit_s") is not None]
    if limits:
        return float(max(limits))
    times = [r["wall_time_s"] for r in rows if r.get("wall_time_s") is not None]
    return float(max(times, default=1.0))


# ------------------------------------------------------------------------- figures


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


FLOOR = 1e-16  # errors of exactly 0 are drawn here on the log axes
STYLES = ("-", "--", ":", "-.")  # solvers with identical iterates (native and an exact QP backend) stay visible


def _style(i: int, colors: Sequence[str]) -> dict:
    return {"color": colors[i % len(colors)], "ls": STYLES[i % len(STYLES)], "marker": "os^Dv"[i % 5],
            "ms": max(3.0, 6.0 - i), "mfc": "none" if i % 2 else None}


def plot_speed_vs_error(rows: Sequence[dict], path: str | Path, residual_tol: float | None = None) -> None:
    """Wall time against error, log-log: one colour per solver (every other one hollow), one
    marker per model, peers outlined in black; a dashed line at the residual tolerance."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8.5, 5.5), constrained_layout=True)
    solvers = sorted({solver_label(r) for r in rows})
    models = sorted({r["model"] for r in rows})
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    markers = "osD^v<>pPX*h"
    for i, solver in enumerate(solvers):
        for j, model in enumerate(models):
            points = [(max(r["error"], FLOOR), r["wall_time_s"]) for r in rows
                      if solver_label(r) == solver and r["model"] == model
                      and r.get("error") is not None and r.get("wall_time_s")]
            if points:
                e, t = zip(*points)
                color = colors[i % len(colors)]
                hollow = i % 2 == 1  # so that solvers with the same iterates stay visible
                ax.scatter(e, t, marker=markers[j % len(markers)], s=40 if hollow else 30,
                           facecolors="none" if hollow else color,
                           edgecolors="black" if solver.split(" / ")[0] in PEER_MODELS else color,
                           linewidths=1.2 if hollow else 0.6)
    if residual_tol:
        ax.axvline(residual_tol, color="gray", ls="--", lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set(xlabel="error (solution error where known, else max residual)", ylabel="wall time (s)",
           title="speed against error (lower left is better)")
    ax.grid(True, which="major", alpha=0.3)
    handles = [plt.Line2D([], [], color=colors[i % len(colors)], marker="o", ls="", label=s,
                          mfc="none" if i % 2 else colors[i % len(colors)]) for i, s in enumerate(solvers)]
    handles += [plt.Line2D([], [], color="gray", marker=markers[j % len(markers)], ls="", label=m) for j, m in enumerate(models)]
    if residual_tol:
        handles.append(plt.Line2D([], [], color="gray", ls="--", lw=0.8, label=f"residual tolerance {residual_tol:g}"))
    ax.legend(handles=handles, fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _panels(rows: Sequence[dict]):
    """pyplot, a figure with one panel per model (up to 3 a line), the models, solvers and colors."""
    plt = _pyplot()
    models = sorted({r["model"] for r in rows})
    solvers = sorted({solver_label(r) for r in rows})
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    columns = min(3, max(1, len(models)))
    lines = math.ceil(len(models) / columns) if models else 1
    fig, axes = plt.subplots(lines, columns, figsize=(4.6 * columns, 3.6 * lines), squeeze=False, constrained_layout=True)
    return plt, fig, axes, models, solvers, colors


def plot_error_vs_nodes(rows: Sequence[dict], path: str | Path) -> None:
    """Error against N (log-log), one panel per model, one line per solver."""
    plt, fig, axes, models, solvers, colors = _panels(rows)
    for ax, model in zip(axes.flat, models):
        for i, solver in enumerate(solvers):
            points = sorted((r["nodes"], max(r["error"], FLOOR)) for r in rows
                            if r["model"] == model and solver_label(r) == solver and r.get("error") is not None)
            if points:
                n, e = zip(*points)
                ax.plot(n, e, label=solver, **_style(i, colors))
        kinds = {r.get("error_kind") for r in rows if r["model"] == model}
        ax.set(xscale="log", yscale="log", xlabel="nodes N", title=model,
               ylabel="solution error" if kinds == {"solution"} else "error (max residual)")
        grids = sorted({r["nodes"] for r in rows if r["model"] == model})
        ax.set_xticks(grids, [str(n) for n in grids])
        ax.minorticks_off()
        ax.grid(True, alpha=0.3)
    for ax in list(axes.flat)[len(models):]:
        ax.set_visible(False)
    handles = [plt.Line2D([], [], label=s, **_style(i, colors)) for i, s in enumerate(solvers)]
    fig.legend(handles=handles, fontsize=8, loc="outside lower center", ncols=min(4, len(solvers)))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_histories(rows: Sequence[dict], path: str | Path) -> None:
    """I against iteration (log scale) on each model's finest grid, one line per solver."""
    plt, fig, axes, models, solvers, colors = _panels(rows)
    for ax, model in zip(axes.flat, models):
        finest = max(r["nodes"] for r in rows if r["model"] == model)
        for i, solver in enumerate(solvers):
            for row in rows:
                if row["model"] == model and row["nodes"] == finest and solver_label(row) == solver:
                    history = row.get("history") or {}
                    its, values = history.get("iteration") or [], history.get("I") or []
                    pairs = [(k, max(v, 1e-300)) for k, v in zip(its, values) if v is not None]
                    if pairs:
                        k, v = zip(*pairs)
                        ax.semilogy(k, v, label=solver, **{**_style(i, colors), "marker": None})
        ax.set(xlabel="iteration (nosnoc: homotopy step)", ylabel="I", title=f"{model}, N = {finest}")
        ax.grid(True, alpha=0.3)
    for ax in list(axes.flat)[len(models):]:
        ax.set_visible(False)
    handles = [plt.Line2D([], [], label=s, **{**_style(i, colors), "marker": None}) for i, s in enumerate(solvers)]
    fig.legend(handles=handles, fontsize=8, loc="outside lower center", ncols=min(4, len(solvers)))
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------------- report.md


def _number(value, digits: int = 1, style: str = "e") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    return f"{value:.{digits}{style}}"


def summary_table(rows: Sequence[dict], residual_tol: float, time_limit: float | None = None) -> str:
    """The per-solver table as Markdown."""
    lines = [
        "| solver (direction / line search) | runs | success rate (%) | correct rate (%) | runtime (shm, × best) "
        "| runtime shm (s) | median wall time (s) | `solved` claims / confirmed | median error |",
        "|:---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for t in summarize(rows, residual_tol, time_limit):
        lines.append(
            f"| {t['solver']} | {t['runs']} | {t['success_rate']:.0f} | {t['correct_rate']:.0f} | "
            f"{_number(t['runtime_shm'], 2, 'f')} | {_number(t['runtime_shm_s'], 3, 'f')} | "
            f"{_number(t['median_time_s'], 3, 'f')} | {t['claimed']} / {t['confirmed']} | {_number(t['median_error'])} |"
        )
    return "\n".join(lines)


def runs_table(rows: Sequence[dict], residual_tol: float) -> str:
    lines = [
        "| model | N | solver | status | iterations | time (s) | I | boundary | inclusion | consistency "
        "| solution error | residual check |",
        "|:---|---:|:---|:---|---:|---:|---:|---:|---:|---:|---:|:---|",
    ]
    for r in sorted(rows, key=lambda r: (r["model"], r["nodes"], solver_label(r))):
        check = "pass" if valid(r, residual_tol) else "fail"
        lines.append(
            f"| {r['model']} | {r['nodes']} | {solver_label(r)} | {r['status']} | {r.get('iterations') or 0} | "
            f"{_number(r.get('wall_time_s'), 2, 'f')} | {_number(r.get('I'))} | {_number(r.get('boundary_error'))} | "
            f"{_number(r.get('inclusion_residual'))} | {_number(r.get('consistency_error'))} | "
            f"{_number(r.get('solution_error'))} | {check} |"
        )
    return "\n".join(lines)


def write_report(rows: Sequence[dict], meta: dict, out: str | Path, seconds: float | None = None) -> dict[str, Path]:
    """Write the three figures and report.md into `out`; returns their paths."""
    out = Path(out)
    settings = meta.get("settings", {})
    tol = float(settings.get("residual_tol", 5e-3))
    limit = settings.get("time_limit_s")
    paths = {name: out / filename for name, filename in FIGURES.items()}
    if rows:
        plot_speed_vs_error(rows, paths["speed_vs_error"], tol)
        plot_error_vs_nodes(rows, paths["error_vs_nodes"])
        plot_histories(rows, paths["history"])
    peers = sorted({r["direction"] for r in rows if r["direction"] in PEER_MODELS})
    peer_keys = {(r["model"], r["nodes"]) for r in rows if r["direction"] in peers}
    shared = [r for r in rows if (r["model"], r["nodes"]) in peer_keys]
    machines = sorted({r["machine"] for r in rows if r.get("machine")})
    loads = [r["load_average"] for r in rows if r.get("load_average") is not None]
    total = sum(r["wall_time_s"] for r in rows if r.get("wall_time_s"))
    text = [
        f"# qdframe bench run — suite `{settings.get('suite', '?')}`",
        "",
        "| | |",
        "|:---|:---|",
        f"| runs | {len(rows)} ({len({r['model'] for r in rows})} models, "
        f"{len({solver_label(r) for r in rows})} solvers, grids {sorted({r['nodes'] for r in rows})}) |",
        f"| command | `{meta.get('command') or '—'}` |",
        f"| executor | {meta.get('executor', 'local')} |",
        f"| machine | {'; '.join(machines) or '—'} |",
        f"| load average (1 min) at run start | {_range(loads)} |",
        f"| sum of run wall times | {total:.1f} s" + (f"; sweep wall time {seconds:.1f} s |" if seconds else " |"),
        f"| budget per run | {settings.get('max_iter', '—')} iterations, time limit {limit} s |",
        f"| residual tolerance | {tol:g} |",
        f"| qdframe | {meta.get('qdframe_version', '?')}, updated {meta.get('updated_at', '?')} |",
        "",
        "## Definitions",
        "",
        "- **error** — the error against the model's exact solution, max over nodes and states of |x − x*|, "
        "where the model knows one (paper-7.1); otherwise the **residual error** = max(boundary error, inclusion "
        "residual, consistency error, surface error), qdframe's own checks (`Functional.residuals`) on the run's "
        "grid. Peers are judged by the same checks on the same grid.",
        f"- **success rate** — runs that report success (status `solved`) *and* pass the residual check "
        f"(residual error ≤ {tol:g}), in % of the solver's runs (qpbenchmark's definition).",
        "- **correct rate** — runs whose own success report agrees with the residual check: found == (found and "
        "valid), in %. Runs that do not claim success count as correct; only an unconfirmed `solved` lowers it "
        "(qpbenchmark's definition).",
        f"- **runtime (shm)** — qpbenchmark's shifted geometric mean of wall times in seconds, shift sh = {SHIFT:g}: "
        "exp(mean(log(t + sh))) − sh, a run that did not report success counted at the time limit, then divided "
        "by the smallest such mean over the solvers (1.0 = fastest; Y = Y times slower). Solvers that ran "
        "different problems are not comparable by it: see the table on the shared problems.",
        "- **status** — qdframe's (`solved`: I ≤ tol, `stationary`, `max_iter`, `failed`) plus `time_limit`; "
        "for a peer, `solved` is the peer's own success report (nosnoc: IPOPT converged at the last homotopy step).",
        "",
        "## Results by solver (all runs)",
        "",
        summary_table(rows, tol, limit),
        "",
    ]
    if peers and shared:
        text += [
            f"## On the problems {', '.join(peers)} also ran",
            "",
            f"Models {', '.join(sorted({m for m, _ in peer_keys}))} on grids {sorted({n for _, n in peer_keys})}:",
            "",
            summary_table(shared, tol, limit),
            "",
        ]
    text += [
        "## Figures",
        "",
        "![speed against error](speed_vs_error.png)",
        "",
        "![error against N](error_vs_nodes.png)",
        "",
        "![I against iteration](objective_history.png)",
        "",
        "## Runs",
        "",
        runs_table(rows, tol),
        "",
    ]
    if peers:
        text += ["## Peers", "", PEER_NOTE, ""]
        for r in rows:
            if r["direction"] in peers:
                text.append(f"- {r['model']}, N = {r['nodes']}: {r['status']} — {r.get('message') or ''}")
        text.append("")
    skipped = meta.get("skipped_directions") or {}
    failed = [r for r in rows if r["status"] == "failed" and r["direction"] not in peers]
    if skipped or failed:
        text += ["## Not run or failed", ""]
        text += [f"- direction `{name}` skipped: {why}" for name, why in sorted(skipped.items())]
        text += [f"- {r['model']} {solver_label(r)} N = {r['nodes']}: {r.get('message')}" for r in failed]
        text.append("")
    paths["report"] = out / "report.md"
    paths["report"].write_text("\n".join(text))
    return paths


PEER_NOTE = (
    "nosnoc (FESD + homotopy + IPOPT through CasADi) solves each problem as an optimal-control problem: "
    "the bounded input is a control with box bounds, its cost is nosnoc's example cost, the end state a terminal "
    "constraint; 10 control stages × ⌈(N − 1)/10⌉ finite elements, Radau IIA with 2 stage points. Its trajectory "
    "is read as nosnoc's collocation polynomials: x(t_k) and z(t_k) = x'(t_k) at qdframe's N uniform nodes "
    "(at an element boundary, the mean of the two one-sided slopes), and ξ = (x, z) is judged by "
    "`Functional.terms`/`Functional.residuals` like any qdframe run. Its iterations are IPOPT iterations summed "
    "over the homotopy; its wall time includes building the CasADi problem and IPOPT solver (shown in the message)."
)


def _range(values: Sequence[float]) -> str:
    if not values:
        return "—"
    return f"{min(values):.2f} – {max(values):.2f}" if min(values) != max(values) else f"{values[0]:.2f}"
