"""The summary of a sweep: work-precision diagrams, times to an error, qpbenchmark-style
metrics and report.md.

Every measure here is judged by a row's ``error``: the max over the run's own time grid of
|x − x_ref| against the model's reference (:mod:`.references`), the same yardstick for
qdframe and the peers. A "solver" is one line of a work-precision diagram: a direction and
line search on a ladder of grids, gauss-newton with ``accuracy=`` targets, nosnoc on a ladder
of finite elements, solve_bvp on a ladder of ``tol``. Metrics follow qpbenchmark
(github.com/qpsolvers/qpbenchmark, ``results.py``/``shgeom.py``), with a "problem" = a model
at one knob setting:

* success rate: the percentage of a solver's runs that report success (`solved`) and whose
  reference error is ≤ the claim tolerance (5e-3, an ``accuracy=`` run's own target);
* correct rate: the percentage of runs whose success report the reference error does not
  contradict — a run that does not claim success is correct, a `solved` with a larger error
  is not (a "false success", listed in report.md);
* runtime: the shifted geometric mean shm(t) = exp(mean(log(t_i + sh))) − sh with sh = 10
  over the wall times in seconds, a run without a confirmed success counted at the time
  limit, divided by the smallest shm of all solvers (1.0 is the fastest);
* time to an error ε: the wall time of the fastest run of a solver whose error is ≤ ε
  (every run counts: the error is the judge, not the solver's report), and its ratio to the
  fastest run of any other tool on the same model.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..status import TIME_LIMIT, Status
from ..errors import InputError, QdframeError
from ..registry import available, make_peer

SHIFT = 10.0
TARGETS = (1e-3, 1e-6)  # the errors whose time to reach report.md gives
FIGURES = {
    "work_precision": "work_precision.png",
    "history": "objective_history.png",
}
FAILED = {Status.FAILED, TIME_LIMIT}  # drawn with a cross: the run did not end normally


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
    return row.get("solver") or f"{row['direction']} / {row['line_search']}"


def tool(row: dict) -> str:
    """qdframe, or the peer's name: times to an error are compared between tools."""
    return row["direction"] if row["direction"] in available("peers") else "qdframe"


def summarize(rows: Sequence[dict], time_limit: float | None = None) -> list[dict]:
    """Per solver: runs, success rate, correct rate, runtime shm (s and × best), median error."""
    limit = _time_limit(rows, time_limit)
    groups: dict[str, list[dict]] = defaultdict(list)
    for row in rows:
        groups[solver_label(row)].append(row)
    table = []
    for label, runs in groups.items():
        claims = [r.get("claim") for r in runs]
        confirmed = [c == "confirmed" for c in claims]
        times = [float(r["wall_time_s"]) if ok and r.get("wall_time_s") is not None else limit
                 for r, ok in zip(runs, confirmed)]
        errors = [r["error"] for r in runs if r.get("error") is not None]
        walls = [r["wall_time_s"] for r in runs if r.get("wall_time_s") is not None]
        table.append({
            "solver": label,
            "runs": len(runs),
            "claimed": sum(bool(r.get("found")) for r in runs),
            "confirmed": sum(confirmed),
            "false": sum(c == "false" for c in claims),
            "success_rate": 100.0 * sum(confirmed) / len(runs),
            "correct_rate": 100.0 * sum(c != "false" for c in claims) / len(runs),
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


def time_to(rows: Sequence[dict], target: float) -> dict[tuple[str, str], dict]:
    """{(model, solver): the fastest row whose error is ≤ target}."""
    best: dict[tuple[str, str], dict] = {}
    for row in rows:
        error, wall = row.get("error"), row.get("wall_time_s")
        if error is None or wall is None or error > target:
            continue
        key = (row["model"], solver_label(row))
        if key not in best or wall < best[key]["wall_time_s"]:
            best[key] = row
    return best


def ratios(rows: Sequence[dict], target: float) -> list[dict]:
    """Per model and tool pair: the fastest qdframe run to `target` against the fastest run
    of each peer, {model, peer, qdframe_s, qdframe_solver, peer_s, peer_solver, ratio =
    peer_s / qdframe_s} (None where one side never reached the target)."""
    reached = time_to(rows, target)
    out = []
    for model in sorted({r["model"] for r in rows}):
        by_tool: dict[str, list[dict]] = defaultdict(list)
        for r in rows:
            if r["model"] == model:
                by_tool[tool(r)].append(r)
        for peer in sorted(t for t in by_tool if t != "qdframe"):
            ours = _fastest([reached[(model, s)] for s in {solver_label(r) for r in by_tool["qdframe"]}
                             if (model, s) in reached])
            theirs = _fastest([reached[(model, s)] for s in {solver_label(r) for r in by_tool[peer]}
                               if (model, s) in reached])
            out.append({
                "model": model, "peer": peer,
                "qdframe_s": ours["wall_time_s"] if ours else None, "qdframe_solver": solver_label(ours) if ours else None,
                "qdframe_knob": ours["knob"] if ours else None,
                "peer_s": theirs["wall_time_s"] if theirs else None, "peer_knob": theirs["knob"] if theirs else None,
                "ratio": theirs["wall_time_s"] / ours["wall_time_s"] if ours and theirs and ours["wall_time_s"] > 0 else None,
            })
    return out


def _fastest(rows: Sequence[dict]) -> dict | None:
    return min(rows, key=lambda r: r["wall_time_s"]) if rows else None


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


def _knob_order(row: dict) -> float:
    """Coarse to fine along a solver's line: N ascending, targets and tolerances descending."""
    knob = str(row.get("knob") or f"N={row['nodes']}")
    name, _, value = knob.partition("=")
    if not value:  # the default call: one point of its own, after the knobs
        return math.inf
    return float(value) if name == "N" else -math.log10(float(value))


def plot_work_precision(rows: Sequence[dict], path: str | Path, models: Sequence[str] | None = None,
                        targets: Sequence[float] = TARGETS) -> None:
    """Wall time against reference error, log-log, one panel per model, one line per solver
    (coarse to fine), a cross where a run failed or hit the time limit, a hollow marker where
    it did not report success; dotted verticals at the `targets`."""
    every = sorted({solver_label(r) for r in rows})  # one style per solver in every figure
    rows = [r for r in rows if models is None or r["model"] in models]
    plt, fig, axes, models, solvers, colors = _panels(rows)
    for ax, model in zip(axes.flat, models):
        for solver in solvers:
            i = every.index(solver)
            line = sorted((r for r in rows if r["model"] == model and solver_label(r) == solver
                           and r.get("error") is not None and r.get("wall_time_s")), key=_knob_order)
            if not line:
                continue
            style = _style(i, colors)
            errors = [max(r["error"], FLOOR) for r in line]
            times = [r["wall_time_s"] for r in line]
            ax.plot(errors, times, color=style["color"], ls=style["ls"], lw=1.2)
            for r, e, t in zip(line, errors, times):
                marker = "x" if r["status"] in FAILED else style["marker"]
                solved = r["status"] == Status.SOLVED
                ax.plot([e], [t], marker=marker, color=style["color"], ms=style["ms"] + 1,
                        mfc=style["color"] if solved and marker != "x" else "none", ls="")
        for target in targets:
            ax.axvline(target, color="gray", ls=":", lw=0.8)
        ax.set(xscale="log", yscale="log", xlabel="error max|x − x_ref| on the run's grid", ylabel="wall time (s)",
               title=model)
        ax.grid(True, which="major", alpha=0.3)
    for ax in list(axes.flat)[len(models):]:
        ax.set_visible(False)
    handles = [plt.Line2D([], [], label=s, color=_style(every.index(s), colors)["color"],
                          ls=_style(every.index(s), colors)["ls"], marker=_style(every.index(s), colors)["marker"])
               for s in solvers]
    handles += [plt.Line2D([], [], color="gray", marker="o", mfc="none", ls="", label="not solved"),
                plt.Line2D([], [], color="gray", marker="x", ls="", label="failed / time limit")]
    fig.legend(handles=handles, fontsize=8, loc="outside lower center",
               ncols=min(4 if len(models) > 1 else 2, len(handles)))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _panels(rows: Sequence[dict], height: float = 3.6):
    """pyplot, a figure with one panel per model (up to 3 a line), the models, solvers and colors;
    `height` inches per line of panels."""
    plt = _pyplot()
    models = sorted({r["model"] for r in rows})
    solvers = sorted({solver_label(r) for r in rows})
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    columns = min(3, max(1, len(models)))
    lines = math.ceil(len(models) / columns) if models else 1
    size = (4.6 * columns, height * lines) if columns > 1 else (6.4, height + 1.2)
    fig, axes = plt.subplots(lines, columns, figsize=size, squeeze=False, constrained_layout=True)
    return plt, fig, axes, models, solvers, colors


def plot_histories(rows: Sequence[dict], path: str | Path) -> None:
    """I against iteration (log scale), one panel per model, one line per solver: its run
    with the most points, named in the panel's legend by solver and knob (which run it
    is). Solvers that report no iteration history (solve_bvp) draw no line and are named
    once under the figure instead."""
    from matplotlib.transforms import offset_copy

    every = sorted({solver_label(r) for r in rows})  # one style per solver, as in the work-precision figure
    plt, fig, axes, models, solvers, colors = _panels(rows, height=5.0)
    without = set(solvers)
    for ax, model in zip(axes.flat, models):
        for solver in solvers:
            runs = [r for r in rows if r["model"] == model and solver_label(r) == solver]
            if not runs:
                continue
            row = max(runs, key=lambda r: r.get("nodes") or 0)
            history = row.get("history") or {}
            its, values = history.get("iteration") or [], history.get("I") or []
            pairs = [(k, max(v, 1e-300)) for k, v in zip(its, values) if v is not None]
            if pairs:
                k, v = zip(*pairs)
                knob = row.get("knob") or f"N={row.get('nodes')}"
                ax.semilogy(k, v, label=f"{solver}: {knob}, {row['status']}",
                            **{**_style(every.index(solver), colors), "marker": None})
                without.discard(solver)
        ax.set(xlabel="iteration (nosnoc: homotopy step)", ylabel="I", title=model)
        ax.grid(True, alpha=0.3)
        if ax.get_lines():  # under the panel: which run each line is, off the data
            below = offset_copy(ax.transAxes, fig=fig, y=-30, units="points")
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, 0.0), bbox_transform=below, ncols=1)
    for ax in list(axes.flat)[len(models):]:
        ax.set_visible(False)
    if without:
        fig.supxlabel(f"no iteration history, not drawn: {', '.join(sorted(without))}", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ------------------------------------------------------------------------- report.md


def _number(value, digits: int = 1, style: str = "e") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    return f"{value:.{digits}{style}}"


def common_models(rows: Sequence[dict]) -> list[str]:
    """The models that every solver of `rows` ran: the set a ranking compares them on."""
    ran: dict[str, set[str]] = defaultdict(set)
    for row in rows:
        ran[solver_label(row)].add(row["model"])
    return sorted(set.intersection(*ran.values())) if ran else []


def ranking(rows: Sequence[dict], time_limit: float | None = None) -> str:
    """The per-solver table over :func:`common_models` only, with a line that names them."""
    models = common_models(rows)
    if not models:
        return "No model was run by every solver: see the per-model tables and the table below."
    same = [r for r in rows if r["model"] in models]
    return (f"Over the {len(models)} model{'s' if len(models) > 1 else ''} every solver ran ({', '.join(models)}; "
            f"{len(same)} runs):\n\n" + summary_table(same, time_limit))


def summary_table(rows: Sequence[dict], time_limit: float | None = None) -> str:
    """The per-solver table as Markdown (over whatever models the rows hold: see :func:`ranking`)."""
    lines = [
        "| solver | runs | success rate (%) | correct rate (%) | runtime (shm, × best) | runtime shm (s) "
        "| median wall time (s) | `solved` claims / confirmed / false | median error |",
        "|:---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for t in summarize(rows, time_limit):
        lines.append(
            f"| {t['solver']} | {t['runs']} | {t['success_rate']:.0f} | {t['correct_rate']:.0f} | "
            f"{_number(t['runtime_shm'], 2, 'f')} | {_number(t['runtime_shm_s'], 3, 'f')} | "
            f"{_number(t['median_time_s'], 3, 'f')} | {t['claimed']} / {t['confirmed']} / {t['false']} | "
            f"{_number(t['median_error'])} |"
        )
    return "\n".join(lines)


def time_table(rows: Sequence[dict], targets: Sequence[float] = TARGETS) -> str:
    """Per model and solver: the time (and knob) of the fastest run with error ≤ each target."""
    reached = {target: time_to(rows, target) for target in targets}
    head = "| model | solver | " + " | ".join(f"time to {t:g} (s) | at" for t in targets) + " |"
    lines = [head, "|:---|:---|" + "---:|:---|" * len(targets)]
    for model in sorted({r["model"] for r in rows}):
        for solver in sorted({solver_label(r) for r in rows if r["model"] == model}):
            cells = []
            for target in targets:
                row = reached[target].get((model, solver))
                cells += [_number(row["wall_time_s"], 3, "f"), row["knob"]] if row else ["not reached", "—"]
            lines.append(f"| {model} | {solver} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def solver_times(rows: Sequence[dict], targets: Sequence[float] = TARGETS) -> str:
    """Per solver (a direction × its QP backend, a peer): on how many of the sweep's models it
    reached each target error (the fastest such run of each model, whatever its status) and
    the median and largest of those times; the solvers sorted by the models they reached at
    the last target, then by their median time to it."""
    reached = {target: time_to(rows, target) for target in targets}
    models = sorted({r["model"] for r in rows})
    lines = ["| solver | " + " | ".join(f"reached {t:g} | median time to {t:g} (s) | slowest (s)" for t in targets) + " |",
             "|:---|" + "---:|---:|---:|" * len(targets)]

    def times(solver: str, target: float) -> list[float]:
        return [reached[target][(m, solver)]["wall_time_s"] for m in models if (m, solver) in reached[target]]

    def order(solver: str):
        last = times(solver, targets[-1]) if targets else []
        return (-len(last), float(np.median(last)) if last else math.inf, solver)

    for solver in sorted({solver_label(r) for r in rows}, key=order):
        cells = []
        for target in targets:
            found = times(solver, target)
            cells += [f"{len(found)}/{len(models)}", _number(float(np.median(found)), 3, "f") if found else "—",
                      _number(max(found), 3, "f") if found else "—"]
        lines.append(f"| {solver} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def ratio_table(rows: Sequence[dict], targets: Sequence[float] = TARGETS) -> str:
    """Per model and peer: qdframe's fastest time to each target against the peer's."""
    lines = ["| model | peer | " + " | ".join(f"to {t:g}: qdframe (s) | peer (s) | peer ÷ qdframe" for t in targets) + " |",
             "|:---|:---|" + "---:|---:|---:|" * len(targets)]
    table = {target: {(r["model"], r["peer"]): r for r in ratios(rows, target)} for target in targets}
    for key in sorted(table[targets[0]]) if targets else []:
        cells = []
        for target in targets:
            entry = table[target][key]
            cells += [_number(entry["qdframe_s"], 3, "f"), _number(entry["peer_s"], 3, "f"),
                      _number(entry["ratio"], 1, "f")]
        lines.append(f"| {key[0]} | {key[1]} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def runs_table(rows: Sequence[dict]) -> str:
    lines = [
        "| model | solver | knob | points | status | claim | iterations | time (s) | of it, estimate (s) "
        "| error estimate | error | end error | switch error | reference | ref. uncertainty | residual error |",
        "|:---|:---|:---|---:|:---|:---|---:|---:|---:|---:|---:|---:|---:|:---|---:|---:|",
    ]
    for r in sorted(rows, key=lambda r: (r["model"], solver_label(r), _knob_order(r))):
        lines.append(
            f"| {r['model']} | {solver_label(r)} | {r.get('knob')} | {r.get('nodes') or '—'} | {r['status']} | "
            f"{r.get('claim')} | {r.get('iterations') or 0} | {_number(r.get('wall_time_s'), 2, 'f')} | "
            f"{_number(r.get('estimate_time_s'), 2, 'f')} | {_number(r.get('error_estimate'))} | "
            f"{_number(r.get('error'))} | {_number(r.get('end_error'))} | {_number(r.get('switch_error'))} | "
            f"{r.get('reference_kind') or '—'} | {_number(r.get('reference_uncertainty'))} | "
            f"{_number(r.get('residual_error'))} |"
        )
    return "\n".join(lines)


def write_report(rows: Sequence[dict], meta: dict, out: str | Path, seconds: float | None = None,
                 references: dict[str, str] | None = None) -> dict[str, Path]:
    """Write the figures and report.md into `out`; returns their paths. `references`:
    {model: how its reference was made} (:func:`~.references.cross_check`)."""
    out = Path(out)
    settings = meta.get("settings", {})
    claim_tol = float(settings.get("claim_tol", 5e-3))
    limit = settings.get("time_limit_s")
    paths = {name: out / filename for name, filename in FIGURES.items()}
    models = sorted({r["model"] for r in rows})
    if rows:
        plot_work_precision(rows, paths["work_precision"])
        (out / "work_precision").mkdir(exist_ok=True)
        for model in models:
            paths[f"work_precision:{model}"] = out / "work_precision" / f"{model}.png"
            plot_work_precision(rows, paths[f"work_precision:{model}"], models=[model])
        plot_histories(rows, paths["history"])
    peers = sorted({r["direction"] for r in rows if r["direction"] in available("peers")})
    machines = sorted({r["machine"] for r in rows if r.get("machine")})
    loads = [r["load_average"] for r in rows if r.get("load_average") is not None]
    total = sum(r["wall_time_s"] for r in rows if r.get("wall_time_s"))
    false = [r for r in rows if r.get("claim") == "false"]
    missed = [r for r in rows if r.get("claim") == "missed"]
    text = [
        f"# qdframe bench run — suite `{settings.get('suite', '?')}`",
        "",
        "| | |",
        "|:---|:---|",
        f"| runs | {len(rows)} ({len(models)} models, {len({solver_label(r) for r in rows})} solvers) |",
        f"| command | `{meta.get('command') or '—'}` |",
        f"| executor | {meta.get('executor', 'local')} |",
        f"| machine | {'; '.join(machines) or '—'} |",
        f"| load average (1 min) at run start | {_range(loads)} |",
        f"| sum of run wall times | {total:.1f} s" + (f"; sweep wall time {seconds:.1f} s |" if seconds else " |"),
        f"| budget per run | {settings.get('max_iter', '—')} iterations, time limit {limit} s |",
        f"| claim tolerance | a `solved` promises error ≤ {claim_tol:g} (an accuracy= run: its target) |",
        f"| qdframe | {meta.get('qdframe_version', '?')}, commit {', then '.join(meta.get('commits') or []) or '—'}"
        f" (`git log -1 COMMIT`); updated {meta.get('updated_at', '?')} |",
        "",
        "## Definitions",
        "",
        "- **error** — max over the run's own time grid and the states of |x − x_ref|, against the model's "
        "reference (below: how each was made). For a problem without a unique solution the reference is the "
        "true motion replayed from the run's own trajectory, and the error is the larger of that distance and "
        "how far the replayed motion misses the boundary conditions. **end error**: at t = T (replays: the "
        "miss); **switch error**: the largest distance from a known switch time to the nearest one the solver "
        "reported. qdframe's own residuals (**residual error**) are shown beside, never used to judge.",
        f"- **success rate** — runs that report success (status `solved`) *and* have error ≤ the claim "
        f"tolerance ({claim_tol:g}; an accuracy= run: its target), in % of the solver's runs.",
        "- **correct rate** — runs whose success report the error does not contradict, in % (qpbenchmark's "
        "definition): a `solved` with a larger error is a **false success** (listed below); a run that does not "
        "claim success counts as correct.",
        f"- **runtime (shm)** — qpbenchmark's shifted geometric mean of wall times, shift {SHIFT:g} s, a run "
        "without a confirmed success counted at the time limit, ÷ the smallest over the solvers.",
        "- **time to ε** — the wall time of a solver's fastest run with error ≤ ε, whatever its status; "
        "**peer ÷ qdframe** — the peer's fastest such time over qdframe's fastest (any qdframe line), on the "
        "same model: above 1, qdframe is faster.",
        "",
        "## References",
        "",
    ]
    text += [f"- **{m}** — {(references or {}).get(m, '—')}" for m in models]
    text += [
        "",
        "## Work-precision",
        "",
        "![work-precision diagrams](work_precision.png)",
        "",
        "One diagram per model is in `work_precision/`. Filled markers: runs that reported success; hollow: "
        "runs that did not; crosses: failed or stopped by the time limit.",
        "",
        "## Time to an error",
        "",
        "By solver, over the models of the sweep:",
        "",
        solver_times(rows),
        "",
        "By model:",
        "",
        time_table(rows),
        "",
    ]
    if peers:
        text += ["## Against the peers", "", ratio_table(rows), ""]
    text += [
        "## Results by solver on the same models",
        "",
        ranking(rows, limit),
        "",
        "## Each solver on every model it ran",
        "",
        "Not a ranking where the solvers ran different models: each line averages over its own.",
        "",
        summary_table(rows, limit),
        "",
        "## Success reports the error contradicts",
        "",
    ]
    text += ([f"- false success: {r['model']} {solver_label(r)} {r['knob']}: error {_number(r.get('error'))} > "
              f"{r['claim_tol']:g}" for r in false] or ["- none: every `solved` has error ≤ its claim tolerance"])
    text += [f"- not claimed, within tolerance: {r['model']} {solver_label(r)} {r['knob']} ({r['status']}, error "
             f"{_number(r.get('error'))})" for r in missed]
    text += ["", "![I against iteration](objective_history.png)", "", "## Runs", "", runs_table(rows), ""]
    if peers:
        text += ["## Peers", "", PEER_NOTE, ""] + [f"- {name}: {_peer_description(name)}" for name in peers] + [""]
        for r in rows:
            if r["direction"] in peers:
                text.append(f"- {r['model']}, {r['direction']} {r['knob']}: {r['status']} — {r.get('message') or ''}")
        text.append("")
    skipped = meta.get("skipped_directions") or {}
    failed = [r for r in rows if r["status"] == Status.FAILED and r["direction"] not in peers]
    unjudged = [r for r in rows if r.get("error") is None and r["status"] != Status.FAILED]
    if skipped or failed or unjudged:
        text += ["## Not run, failed or not judged", ""]
        text += [f"- direction `{name}` skipped: {why}" for name, why in sorted(skipped.items())]
        text += [f"- {r['model']} {solver_label(r)} {r['knob']}: {r.get('message')}" for r in failed + unjudged]
        text.append("")
    paths["report"] = out / "report.md"
    paths["report"].write_text("\n".join(text))
    return paths


PEER_NOTE = (
    "nosnoc (FESD + homotopy + IPOPT through CasADi) states each problem in Stewart's form, one subsystem per "
    "sign term. A friction or sliding model is an OCP without control or cost, its end conditions terminal "
    "constraints (a free start value a global variable), on one stage of N − 1 finite elements; a problem with a "
    "bounded input an optimal-control problem with nosnoc's example cost, 10 control stages × ⌈(N − 1)/10⌉ finite "
    "elements; Radau IIA with 2 stage points. Its trajectory is read from its collocation polynomials at N "
    "uniform times and at all its own points (nodes: their count), and its own piecewise-constant control drives "
    "the replay that judges an input problem. A peer run is not interrupted: past the time limit it is marked "
    "`time_limit`. solve_bvp (scipy) solves the models it can state as ODE "
    "boundary-value problems with Sgn(s) regularized as clip(s/ε, −1, 1), ε = its tol, from 11 uniform nodes; "
    "it is judged on its own final mesh. nosnoc's iterations are IPOPT iterations summed over the homotopy; "
    "its wall time includes building the CasADi problem and IPOPT solver."
)


def _peer_description(name: str) -> str:
    """A peer's one-line description, from its registered class."""
    try:
        return make_peer(name).description or "(no description)"
    except QdframeError as exc:  # no longer installed: the rows still say what it did
        return f"(not installed here: {exc})"


def _range(values: Sequence[float]) -> str:
    if not values:
        return "—"
    return f"{min(values):.2f} – {max(values):.2f}" if min(values) != max(values) else f"{values[0]:.2f}"
