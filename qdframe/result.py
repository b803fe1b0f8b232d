"""The result of a solve and its JSON form (README, "The command line")."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

STATUSES = ("solved", "stationary", "max_iter", "failed")


@dataclass(frozen=True)
class IterationRecord:
    """One row of the history: the state after `iteration` accepted steps."""

    iteration: int
    objective: float
    I: float
    step: float  # γ of the step that led here (0 for the first iterate)
    direction_norm: float  # L² norm of the direction G that led here
    deviation: float  # max_k ‖v̄_k + w̄_k‖ of that direction
    boundary_error: float  # max_j |x0_j + ∫z_j − xT_j| after the step
    time_s: float  # seconds since the solve started
    nodes: int  # the grid of this iterate (grids change under continuation)


@dataclass
class SolveResult:
    """Everything a solve produced; `status` says honestly how it ended."""

    model: str
    direction: str
    line_search: str
    nodes: int
    T: float
    status: str
    message: str
    iterations: int
    wall_time_s: float
    objective: float
    I: float
    terms: dict[str, float]
    cost: float | None
    boundary_error: float
    inclusion_residual: float
    surface_error: float | None
    consistency_error: float
    selection_residual: float | None  # max |λ − clip(λ + s, −1, 1)|: how far λ is from Sgn(s) (None: no selections)
    solution_error: float | None
    t: np.ndarray
    x: np.ndarray
    z: np.ndarray
    u: np.ndarray | None
    selections: np.ndarray | None  # (N, p) λ of each sign term a·Sgn(s), or None
    selection_names: list[str]
    state_names: tuple[str, ...]
    set_bounds: list[Any]
    options: dict[str, Any]
    history: list[IterationRecord] = field(default_factory=list)

    @property
    def solved(self) -> bool:
        return self.status == "solved"

    def to_dict(self) -> dict[str, Any]:
        data = {k: v for k, v in self.__dict__.items() if k != "history"}
        data["history"] = [asdict(record) for record in self.history]
        return _plain(data)

    def to_json(self, path: str | Path | None = None, indent: int | None = 1) -> str:
        """The JSON text; also written to `path` if given."""
        text = json.dumps(self.to_dict(), indent=indent, allow_nan=False)
        if path is not None:
            Path(path).write_text(text + "\n")
        return text

    def summary(self) -> str:
        """A short human-readable table."""
        rows = [
            ("model", self.model),
            ("status", f"{self.status}" + (f" ({self.message})" if self.message else "")),
            ("direction / line search", f"{self.direction} / {self.line_search}"),
            ("nodes, T", f"{self.nodes}, {self.T:g}" + _grids(self.options.get("grids", []), self.nodes)),
            ("iterations", str(self.iterations)),
            ("wall time", f"{self.wall_time_s:.3f} s"),
            ("objective", f"{self.objective:.3e}"),
            ("I = φ+χ+ω+υ+σ", f"{self.I:.3e}  (" + ", ".join(f"{k} {v:.1e}" for k, v in self.terms.items()) + ")"),
            ("boundary error", f"{self.boundary_error:.3e}"),
            ("inclusion residual", f"{self.inclusion_residual:.3e}"),
            ("consistency error", f"{self.consistency_error:.3e}"),
        ]
        if self.selection_residual is not None:
            rows.append(("selection residual", f"{self.selection_residual:.3e}"))
        if self.cost is not None:
            rows.insert(7, ("cost", f"{self.cost:.3e}"))
        if self.surface_error is not None:
            rows.append(("surface error", f"{self.surface_error:.3e}"))
        if self.solution_error is not None:
            rows.append(("error vs known solution", f"{self.solution_error:.3e}"))
        width = max(len(k) for k, _ in rows)
        return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)

    def plot(self, path: str | Path | None = None, **kwargs: Any) -> matplotlib.figure.Figure:
        """The figure of this result (trajectories, z against F(x(t)), I per iteration),
        saved to `path` only when given; `kwargs` as :func:`qdframe.plotting.plot_result`."""
        from .plotting import plot_result

        return plot_result(self, path, **kwargs)


def _grids(grids: list[int], nodes: int) -> str:
    if grids and grids[-1] != nodes:  # ended on a coarser grid (a failure there)
        return f"  (ended on this grid; {grids[-1]} requested)"
    return f"  (continued from {', '.join(map(str, grids[:-1]))})" if len(grids) > 1 else ""


def _plain(value: Any) -> Any:
    """NumPy arrays and scalars to JSON-ready lists and floats (non-finite to None)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (np.floating, float)):
        number = float(value)
        return number if np.isfinite(number) else None
    if isinstance(value, np.integer):
        return int(value)
    return value
