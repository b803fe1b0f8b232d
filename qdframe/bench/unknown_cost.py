"""`qdframe bench unknowns`: what an unknown T or parameter costs per Newton iteration.

For each model with unknowns and each N, the seconds of one gauss-newton iteration (its
direction, then the objective at the new iterate) on the model as the solver sees it
(:class:`qdframe.unknowns.Unknowns`: T and p as constant states) against the same model
with T and p fixed at their guesses (``Unknowns(…, fixed=True)``: the same pieces, the
parameters inserted as numbers). Both start from the model's own start x ≡ x0 and take
full steps; the median over the iterations after the first is kept (the first includes
the KKT solver's set-up).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..registry import load_model, make_direction
from ..functional import Functional
from ..grid import Grid
from ..unknowns import Unknowns, restated
from . import problems

MODELS = problems.tagged("unknowns")  # T or a coefficient found with x
NODES = (10001, 100001)
ITERATIONS = 6


@dataclass
class Cell:
    model: str
    nodes: int
    fixed: float  # s per iteration with T and p fixed
    unknown: float  # s per iteration with them unknown
    columns: tuple[int, int]  # unknowns per node of each functional

    @property
    def ratio(self) -> float:
        return self.unknown / self.fixed


def per_iteration(model, nodes: int, iterations: int = ITERATIONS) -> tuple[float, int]:
    """Median seconds of one gauss-newton iteration (direction + objective) and ξ's width."""
    functional = Functional(model, Grid(model.T, nodes, model.default_scheme))
    xi = functional.initial_point()
    solver = make_direction("gauss-newton")
    solver.start(functional)
    times = []
    for _ in range(iterations):
        clock = time.perf_counter()
        step = solver.compute(functional, xi, 1e-3).step
        functional.objective(xi + step)
        times.append(time.perf_counter() - clock)
        xi = xi + step
    return float(np.median(times[1:])), functional.dim


def run(models: Sequence[str] = MODELS, nodes: Sequence[int] = NODES, iterations: int = ITERATIONS,
        progress: Callable[[str], None] | None = None) -> list[Cell]:
    cells = []
    for name in models:
        model = load_model(name)
        for count in nodes:
            fixed, fixed_dim = per_iteration(Unknowns(restated(model, False, None), fixed=True), count, iterations)
            unknown, unknown_dim = per_iteration(Unknowns(model), count, iterations)
            cells.append(Cell(name, count, fixed, unknown, (fixed_dim, unknown_dim)))
            if progress is not None:
                progress(f"{name} N = {count}: {fixed:.3g} s fixed, {unknown:.3g} s unknown")
    return cells


def table(cells: Sequence[Cell]) -> str:
    lines = ["| model | N | s/iteration, fixed | s/iteration, unknown | ratio | unknowns per node |",
             "|:---|---:|---:|---:|---:|---:|"]
    for cell in cells:
        lines.append(f"| {cell.model} | {cell.nodes} | {cell.fixed:.4f} | {cell.unknown:.4f} | {cell.ratio:.2f} | "
                     f"{cell.columns[0]} → {cell.columns[1]} |")
    return "\n".join(lines)
