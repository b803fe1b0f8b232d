"""`qdframe bench unknowns`: what an unknown T or parameter costs per Newton iteration.

For each model with unknowns and each N, the CPU seconds of one gauss-newton iteration (its
direction, then the objective at the new iterate) on the model as the solver sees it
(:class:`qdframe.unknowns.Unknowns`: T and p as constant states) against the same model
with T and p fixed at their guesses (``Unknowns(…, fixed=True)``: the same pieces, the
parameters inserted as numbers). Both start from the model's own start x ≡ x0 and take
full steps, an iteration of each in turn (CPU time, so that other work on a shared machine
counts against neither); the median over the iterations after the first is kept (the first
includes the KKT solver's set-up).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
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


def _timed_steps(model, nodes: int) -> Iterator[float]:
    """The CPU seconds of each gauss-newton iteration (direction + objective) on `model`, one per
    `next`, from the model's start with full steps."""
    functional = Functional(model, Grid(model.T, nodes, model.default_scheme))
    xi = functional.initial_point()
    solver = make_direction("gauss-newton")
    solver.start(functional)
    while True:
        clock = time.process_time()
        step = solver.compute(functional, xi, 1e-3).step
        functional.objective(xi + step)
        yield time.process_time() - clock
        xi = xi + step


def per_iteration(fixed_model, unknown_model, nodes: int, iterations: int = ITERATIONS) -> tuple[float, float]:
    """Median CPU seconds of one iteration of each model, their iterations taken in turn (a
    load on the machine falls on both alike), the first of each left out (the KKT solver's
    set-up)."""
    fixed, unknown = _timed_steps(fixed_model, nodes), _timed_steps(unknown_model, nodes)
    pairs = [(next(fixed), next(unknown)) for _ in range(iterations)][1:]
    return float(np.median([a for a, _ in pairs])), float(np.median([b for _, b in pairs]))


def run(models: Sequence[str] = MODELS, nodes: Sequence[int] = NODES, iterations: int = ITERATIONS,
        progress: Callable[[str], None] | None = None) -> list[Cell]:
    cells = []
    for name in models:
        model = load_model(name)
        for count in nodes:
            fixed_model, unknown_model = Unknowns(restated(model, False, None), fixed=True), Unknowns(model)
            fixed, unknown = per_iteration(fixed_model, unknown_model, count, iterations)
            width = tuple(Functional(m, Grid(m.T, 3)).dim for m in (fixed_model, unknown_model))
            cells.append(Cell(name, count, fixed, unknown, width))
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
