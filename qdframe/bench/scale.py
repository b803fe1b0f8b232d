"""`qdframe bench scale`: seconds per iteration against N, against the floor, and memory.

For each solver path (a direction with its own line search), model and grid size N, one
child process (so that its peak memory is its own):

* builds the model's functional on N nodes with the model's scheme, from the model's own
  start, and runs `iterations` iterations of the descent (no continuation, no error
  estimate): **s/iter** is the median of the iterations' wall times, an iteration being
  the direction, the line search and the new iterate's terms (the differences of the
  history's `time_s`; the start's evaluation, once per solve, is record 0's own);
* measures the **floor** at the same start, what any Newton-type iteration must at least
  do: one fresh sparse factorization and solve of the Gauss–Newton KKT system
  [[λJᵀJ + μW, Eᵀ], [E, 0]] (the fastest of SuperLU with its default panel, SuperLU with a
  one-column panel as gauss-newton runs it, and the LDLᵀ of qdldl) plus one
  vectorized evaluation of every piece of the model at all nodes (the sets' max- and
  min-groups, the sign terms' switching functions, the cost, the surface);
  **÷ floor** = s/iter ÷ floor;
* reports the process's **peak** resident memory above what it held once the model and
  its functional were built, next to the arrays that **must exist**: ξ, the Jacobian J and
  the KKT factors (the smaller of SuperLU's L + U and qdldl's L).

The fitted exponent k of s/iter ∝ N^k is the least-squares slope of log(s/iter) against
log N over the grids measured. The cells run one after another: timings on a shared
machine are only comparable within one run, which is why the floor is measured in it.
Single runs spread widely there (docs/benchmarks.md), so `repeat` measures each cell in
that many fresh processes and keeps the least s/iter and the least floor (each the least
disturbed of its measurements) and the largest peak.
"""

from __future__ import annotations

import concurrent.futures as futures
import multiprocessing
import os
import resource
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace

import numpy as np

from ..status import Status
from . import problems

PATHS = ("gauss-newton", "native")
MODELS = problems.tagged("scale")  # the paper's examples
NODES = (1001, 10001, 100001)
ITERATIONS = 3
FLOOR_REPEAT = 3
MU = 1e-10  # gauss-newton's initial damping: the floor's KKT is the first step's


@dataclass
class Cell:
    """One (path, model, N): what the harness measured there."""

    path: str
    model: str
    nodes: int
    iterations: int  # iterations actually run (fewer when the descent stopped earlier)
    status: str
    per_iteration_s: float
    floor_s: float
    factor_s: float  # the floor's factorization and solve
    model_s: float  # the floor's evaluation of the model
    peak_mb: float  # resident memory above the built functional, at its peak
    must_exist_mb: float  # ξ, J and the KKT factors
    factorizations: float = float("nan")  # KKT factorizations per iteration (gauss-newton; NaN for the others)
    error: str = ""
    repeats: int = 1  # processes that measured the cell (see `best`)

    @property
    def ratio(self) -> float:
        return self.per_iteration_s / self.floor_s if self.floor_s > 0 else float("nan")


def run(paths: Sequence[str] = PATHS, models: Sequence[str] = MODELS, nodes: Sequence[int] = NODES,
        iterations: int = ITERATIONS, progress: Callable[[str], None] | None = None, repeat: int = 1) -> list[Cell]:
    """Every cell, each measured in `repeat` fresh child processes (see `best`), one after another."""
    cells = []
    context = multiprocessing.get_context("spawn")
    for path in paths:
        for model in models:
            for count in nodes:
                if progress:
                    progress(f"{path} {model} N={count}")
                measured = []
                for _ in range(repeat):
                    with futures.ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
                        try:
                            measured.append(pool.submit(measure, path, model, count, iterations).result())
                        except Exception as exc:  # a crashed child (e.g. out of memory): a row that says so
                            measured.append(Cell(path, model, count, 0, Status.FAILED, *([float("nan")] * 6),
                                                 error=f"{type(exc).__name__}: {exc}"))
                cell = best(measured)
                cells.append(cell)
                if progress:
                    progress(f"  {cell.per_iteration_s:.3g} s/iter, floor {cell.floor_s:.3g} s, "
                             f"peak {cell.peak_mb:.0f} MB {cell.status}{' ' + cell.error if cell.error else ''}")
    return cells


def best(measured: Sequence[Cell]) -> Cell:
    """One cell from repeated measurements of it: the least s/iter, the least floor (with its
    factorization and model parts), the largest peak, over the measurements without an
    error (the first measurement if every one failed)."""
    ok = [cell for cell in measured if not cell.error]
    if not ok:
        return measured[0]
    fastest = min(ok, key=lambda cell: cell.per_iteration_s)
    lowest = min(ok, key=lambda cell: cell.floor_s)
    return replace(fastest, floor_s=lowest.floor_s, factor_s=lowest.factor_s, model_s=lowest.model_s,
                   peak_mb=max(cell.peak_mb for cell in ok), repeats=len(ok))


def measure(path: str, model_name: str, nodes: int, iterations: int = ITERATIONS) -> Cell:
    """One cell, in this process (run() calls it in a child)."""
    from ..descent.loop import DescentOptions, descend
    from ..registry import load_model, make_direction, make_line_search
    from ..functional import Functional
    from ..schemes.grid import Grid

    model = load_model(model_name)
    functional = Functional(model, Grid(model.T, nodes, model.default_scheme))
    start = functional.initial_point()
    base = _resident_mb()
    solver = make_direction(path)
    search = make_line_search(solver.default_line_search)
    result = descend(functional, solver, search, DescentOptions(max_iter=iterations, tol=model.default_tol), None, start)
    peak = _peak_mb() - base
    times = np.diff([record.time_s for record in result.history])
    per_iteration = float(np.median(times)) if times.size else float("nan")
    factorizations = solver.factorizations / times.size if hasattr(solver, "factorizations") and times.size else float("nan")
    factor_s, factor_bytes, jacobian_bytes = _factor_floor(functional, start)
    model_s = _model_floor(functional, start)
    must_exist = (start.nbytes + jacobian_bytes + factor_bytes) / 2**20
    return Cell(path, model_name, nodes, int(times.size), result.status, per_iteration, factor_s + model_s, factor_s,
                model_s, peak, must_exist, factorizations)


def _factor_floor(functional, xi: np.ndarray) -> tuple[float, int, int]:
    """The fastest fresh factorization + solve of the first Gauss–Newton KKT system at ξ
    (median of FLOOR_REPEAT), the bytes of the smaller factors, and the bytes of J."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from ..directions.linearized_system import LinearizedSystem

    system = LinearizedSystem(functional, xi, 1e-3)
    J, E = system.jacobian, system.constraints
    damping = np.zeros((system.nodes, system.width))
    damping[:, : 2 * system.n + system.m] = functional.weights[:, None]
    hessian = system.penalty * (J.T @ J) + MU * sp.diags(damping.ravel())
    kkt = sp.bmat([[hessian, E.T], [E, None]], format="csc")
    rhs = np.ones(kkt.shape[0])
    jacobian_bytes = J.data.nbytes + J.indices.nbytes + J.indptr.nbytes

    def superlu(panel_size: int | None = None) -> int:
        lu = spla.splu(kkt, panel_size=panel_size)  # None: SuperLU's default
        lu.solve(rhs)
        return 12 * lu.nnz  # L + U

    def ldl() -> int:
        import qdldl

        regularized = sp.bmat([[hessian, E.T], [E, -1e-12 * sp.eye(E.shape[0])]], format="csc")
        factor = qdldl.Solver(regularized)
        factor.solve(rhs)
        return 12 * factor.factors()[0].nnz

    best, factor_bytes = float("inf"), None
    for method in (superlu, lambda: superlu(panel_size=1), ldl):  # SuperLU's default panel and the one gauss-newton uses
        try:
            seconds, used = _median_time(method)
        except Exception:  # noqa: BLE001 — a factorization this system does not admit: the other one counts
            continue
        best = min(best, seconds)
        factor_bytes = used if factor_bytes is None else min(factor_bytes, used)
    return best, factor_bytes or 0, jacobian_bytes


def _model_floor(functional, xi: np.ndarray) -> float:
    """One evaluation of every piece of the model at all nodes (median of FLOOR_REPEAT)."""
    y = functional.arguments(xi)
    e1 = np.zeros((y.shape[0], 1))

    def evaluate() -> None:
        for block in functional.blocks:
            psi = np.broadcast_to(np.eye(block.size)[:1], (y.shape[0], block.size)) if block.size > 1 else e1 + 1.0
            for group in block.max_groups:
                group.pieces(y)
            for group in block.min_groups:
                group.pieces(y, psi)
            for term in block.signs:
                term.switch(y)
        if functional.cost is not None:
            for fn in (*functional.cost.max_groups, *functional.cost.min_groups):
                fn(y)
        if functional.surface is not None:
            functional.surface.function(y[:, : functional.n])

    return _median_time(evaluate)[0]


def _median_time(fn: Callable[[], object]) -> tuple[float, object]:
    times, out = [], None
    for _ in range(FLOOR_REPEAT):
        clock = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - clock)
    return float(np.median(times)), out


def _resident_mb() -> float:
    """This process's resident memory now."""
    with open("/proc/self/statm") as statm:
        pages = int(statm.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def _peak_mb() -> float:
    """This process's peak resident memory so far (Linux reports ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def exponents(cells: Sequence[Cell]) -> dict[tuple[str, str], float]:
    """k in s/iter ∝ N^k per (path, model), by least squares on the logs (NaN with < 2 grids)."""
    out = {}
    for key in dict.fromkeys((cell.path, cell.model) for cell in cells):
        rows = [c for c in cells if (c.path, c.model) == key and np.isfinite(c.per_iteration_s) and c.per_iteration_s > 0]
        out[key] = (float(np.polyfit(np.log([c.nodes for c in rows]), np.log([c.per_iteration_s for c in rows]), 1)[0])
                    if len({c.nodes for c in rows}) >= 2 else float("nan"))
    return out


def table(cells: Sequence[Cell]) -> str:
    """A Markdown table: one row per cell, the exponent on each (path, model)'s last row."""
    k = exponents(cells)
    lines = ["| path | model | N | iterations | status | s/iter | KKT/iter | floor s | ÷ floor | peak MB | must exist MB | k |",
             "|---|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for i, cell in enumerate(cells):
        last = i + 1 == len(cells) or (cells[i + 1].path, cells[i + 1].model) != (cell.path, cell.model)
        exponent = f"{k[(cell.path, cell.model)]:.2f}" if last and np.isfinite(k[(cell.path, cell.model)]) else ""
        status = cell.status + (f" ({cell.error})" if cell.error else "")
        lines.append(f"| {cell.path} | {cell.model} | {cell.nodes} | {cell.iterations} | {status} | "
                     f"{cell.per_iteration_s:.3g} | {_count(cell.factorizations)} | {cell.floor_s:.3g} | {cell.ratio:.1f} | {cell.peak_mb:.1f} | "
                     f"{cell.must_exist_mb:.1f} | {exponent} |")
    return "\n".join(lines)


def _count(value: float) -> str:
    return "—" if not np.isfinite(value) else f"{value:.3g}"


def to_json(cells: Sequence[Cell]) -> dict:
    return {"format": "qdframe-bench-scale/1", "threads": _threads(),
            "cells": [asdict(cell) | {"ratio": cell.ratio} for cell in cells],
            "exponents": [{"path": p, "model": m, "k": k} for (p, m), k in exponents(cells).items()]}


def _threads() -> dict[str, str | None]:
    return {name: os.environ.get(name) for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
