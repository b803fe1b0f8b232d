"""`qdframe bench unknowns`: what an unknown T or parameter costs per Newton iteration.

For each model with unknowns and each N, the CPU seconds of one gauss-newton iteration (its
direction, then the objective at the new iterate) on the model as the solver sees it
(:class:`qdframe.unknowns.Unknowns`: T and p as constant states) against the same model
with T and p fixed at their guesses (``Unknowns(…, fixed=True)``: the same pieces, the
parameters inserted as numbers). Both start from the model's own start x ≡ x0 with full
steps; after WARMUP iterations (the first includes the KKT solver's analysis) each of the
next ITERATIONS iterations is taken REPEATS times from the same iterate and solver state,
the two forms in turn (CPU time, so that other work on a shared machine counts against
neither), and the least of its repeats is kept: the same work each time, so what varies
from repeat to repeat is the machine (another process, the allocator), which only adds.
The figure per form is the mean of those least times over the iterations.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..registry import load_model, make_direction
from ..functional import Functional
from ..schemes.grid import Grid
from ..unknowns import Unknowns, restated
from . import problems

MODELS = problems.tagged("unknowns")  # T or a coefficient found with x
NODES = (10001, 100001)
WARMUP = 2
ITERATIONS = 3
REPEATS = 5


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


class _Iterates:
    """gauss-newton's iterates on `model` from its start, with full steps: :meth:`timed` the CPU
    seconds of the next iteration (direction + objective) from the current iterate and solver
    state, repeatable; :meth:`advance` takes it."""

    def __init__(self, model, nodes: int) -> None:
        self.functional = Functional(model, Grid(model.T, nodes, model.default_scheme))
        self.xi = self.functional.initial_point()
        self.solver = make_direction("gauss-newton")
        self.solver.start(self.functional)

    def _trial(self):
        """A copy of the solver from the same state (its KKT analysis and skeleton shared; the
        state is replaced, never changed, by a step: an iteration can be taken again)."""
        return copy.copy(self.solver)

    def timed(self) -> float:
        trial = self._trial()
        clock = time.process_time()
        step = trial.compute(self.functional, self.xi, 1e-3).step
        self.functional.objective(self.xi + step)
        return time.process_time() - clock

    def advance(self) -> None:
        self.xi = self.xi + self.solver.compute(self.functional, self.xi, 1e-3).step


def per_iteration(fixed_model, unknown_model, nodes: int, iterations: int = ITERATIONS, repeats: int = REPEATS,
                  warmup: int = WARMUP) -> tuple[float, float]:
    """CPU seconds of one iteration of each model (module docstring): the mean over
    `iterations` iterates, after `warmup`, of the least of `repeats` timings of each, the two
    forms in turn."""
    runs = _Iterates(fixed_model, nodes), _Iterates(unknown_model, nodes)
    for _ in range(warmup):
        for run in runs:
            run.advance()
    least = np.zeros((iterations, 2))
    for k in range(iterations):
        least[k] = np.min([[run.timed() for run in runs] for _ in range(repeats)], axis=0)
        for run in runs:
            run.advance()
    fixed, unknown = least.mean(axis=0)
    return float(fixed), float(unknown)


def run(models: Sequence[str] = MODELS, nodes: Sequence[int] = NODES, iterations: int = ITERATIONS,
        progress: Callable[[str], None] | None = None, repeats: int = REPEATS) -> list[Cell]:
    cells = []
    for name in models:
        model = load_model(name)
        for count in nodes:
            fixed_model, unknown_model = Unknowns(restated(model, False, None), fixed=True), Unknowns(model)
            fixed, unknown = per_iteration(fixed_model, unknown_model, count, iterations, repeats)
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
