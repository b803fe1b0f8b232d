"""The stick/slide/switch suite: every problem with an exact Filippov solution, solved per
scheme and grid, judged by the strict Filippov residual and the error against the exact
solution (`qdframe bench friction`).

Each row: status, iterations, wall time, the strict residual max(dist(z, F(y)) with the
selections, |λ − clip(λ + s, −1, 1)|), max |x − x*| over the nodes, and the observed order
log(e_coarse / e_fine) / log(N_fine / N_coarse) against the previous N.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

from ..solve.solving import solve
from ..registry import load_model
from ..progress import bar
from . import problems

SUITE = problems.tagged("friction-suite")  # the catalogue's stick/slide/switch problems (T or a coefficient found too)


@dataclass(frozen=True)
class SuiteRow:
    model: str
    scheme: str
    nodes: int
    status: str
    iterations: int
    seconds: float
    residual: float  # strict Filippov residual
    error: float | None  # max |x − x*| over the nodes, if the model has an exact solution
    order: float | None  # observed order against the previous row of the same model and scheme


def run_suite(models: Sequence[str] = SUITE, nodes: Sequence[int] = (101, 1001, 10001),
              schemes: Sequence[str | None] = (None,), direction: str = "gauss-newton",
              progress: bool = False) -> list[SuiteRow]:
    """Solve every model on every grid with every scheme (None: the model's own), from the default
    start; `progress`: a bar on stderr (on a terminal)."""
    rows: list[SuiteRow] = []
    runs = bar(len(models) * len(schemes) * len(nodes), "bench friction", enabled=progress)
    for name in models:
        for scheme in schemes:
            previous: SuiteRow | None = None
            for count in nodes:
                runs.set_postfix_str(f"{name} N={count}")
                model = load_model(name)
                start = time.perf_counter()
                result = solve(model, nodes=count, scheme=scheme, direction=direction, estimate=False)  # the solve alone is timed
                seconds = time.perf_counter() - start
                residual = max(result.inclusion_residual, result.selection_residual or 0.0)
                order = None
                if previous is not None and previous.error and result.solution_error:
                    order = math.log(previous.error / result.solution_error) / math.log(count / previous.nodes)
                row = SuiteRow(name, result.options["scheme"], count, result.status, result.iterations, seconds,
                               residual, result.solution_error, order)
                rows.append(row)
                previous = row
                runs.update(1)
    runs.close()
    return rows


def table(rows: Sequence[SuiteRow]) -> str:
    """A Markdown table of the rows."""
    lines = ["| model | scheme | N | status | iterations | time (s) | strict residual | error vs exact | order |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        error = "—" if r.error is None else f"{r.error:.2e}"
        order = "—" if r.order is None else f"{r.order:.2f}"
        lines.append(f"| {r.model} | {r.scheme} | {r.nodes} | {r.status} | {r.iterations} | {r.seconds:.2f} "
                     f"| {r.residual:.1e} | {error} | {order} |")
    return "\n".join(lines)
