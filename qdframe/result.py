"""The result of a solve and its JSON form (README, "The command line")."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # optional extras (`pip install 'qdframe[frames]'`), imported by the methods that need them
    import pandas
    import xarray

from .status import STATUSES, Status  # noqa: F401  (the statuses, in one place)


@dataclass(frozen=True)
class IterationRecord:
    """One row of the history: the state after `iteration` accepted steps."""

    iteration: int
    objective: float
    I: float
    step: float  # γ of the step that led here (0 for the first iterate)
    direction_norm: float  # L² norm of the direction G that led here
    deviation: float  # max_k ‖v̄_k + w̄_k‖ of that direction
    boundary_error: float  # max_j |x_j(T) − xT_j| (and periodic gaps) after the step
    time_s: float  # seconds since the solve started, when this iterate's terms were known
    nodes: int  # the grid of this iterate (grids change under continuation)


# ------------------------------------------------------------------ the solve's records
# What a solve records of how it ran, one frozen record per part (the README's "The command
# line" and docs/guide.md show them through `SolveResult.options`, their fields in one dict):
#
# ================  =============================================  ===============================
# record            fields                                         made by
# ================  =============================================  ===============================
# DescentRecord     scheme, max_iter, tol, delta, eps, gamma_max,  each descent (qdframe.descent);
#                   residual_tol, stationary_point                 the solve: ε, δ the least reached
# VerdictRecord     estimate_time_s, accuracy, max_nodes           the verdict (qdframe.solve.verdict)
# PenaltyRecord     penalty, optimality_gap, penalty_rounds        a cost's rounds (qdframe.solve.optimum)
# GridsRecord       start, grids, iterations_per_grid, signs,      the solve (qdframe.solve.solving)
#                   selection_scale, inputs, uniform
# UnknownsRecord    free_T, T_guess, T_start, parameters_start     T or p unknown (qdframe.solve.unwrap)
# ================  =============================================  ===============================


@dataclass(frozen=True)
class DescentRecord:
    """How the descents ran: the scheme and the options of the last (ε and δ, over a whole
    solve, the smallest any descent reached; max_iter the solve's budget), and whether its stop
    is a stationary point of the objective (a higher penalty can move it: qdframe.solve.optimum)."""

    scheme: str
    max_iter: int
    tol: float
    delta: float
    eps: float
    gamma_max: float
    residual_tol: float
    stationary_point: bool = False


@dataclass(frozen=True)
class VerdictRecord:
    """The verdict's own cost and target: seconds spent making estimates (their solves and
    replays), and under refinement the accuracy asked and the cap on points."""

    estimate_time_s: float
    accuracy: float | None = None
    max_nodes: int | None = None


@dataclass(frozen=True)
class PenaltyRecord:
    """A cost: the last penalty λ, the optimality gap (the multipliers' |yᵀr|, or 2λ·I where the
    penalty is raised), and (λ, iterations) of each round (of the multipliers, or of the penalty)."""

    penalty: float
    optimality_gap: float
    penalty_rounds: tuple[tuple[float, int], ...]
    newton_step: float = 0.0  # max |x-part| of the Newton step where a descent stopped short of its optimum, or of a restoration's move
    tolerance_share: float = 0.0  # Σ|y|·tol: how far the least cost moves within the checks' tolerances (multipliers)


@dataclass(frozen=True)
class GridsRecord:
    """The grids of the whole solve: the first start ("model", "simulated", "line"), each grid's
    points and iterations (continuation, then refinement), and how the last was discretized."""

    start: str
    grids: tuple[int, ...]
    iterations_per_grid: tuple[int, ...]
    signs: str
    selection_scale: float
    inputs: str  # "held", "free", or "none" (the model has no fixed set of inputs to hold)
    uniform: bool


@dataclass(frozen=True)
class UnknownsRecord:
    """T or parameters found with x: whether T was free, the user's guess of T and the one the
    solve started from (its sweep), and the parameters' starting guesses."""

    free_T: bool
    T_guess: float
    T_start: float
    parameters_start: dict[str, float]


RECORDS = ("descent", "verdict", "penalty", "grids", "unknowns")  # SolveResult's records, in options' order


@dataclass
class SolveResult:
    """Everything a solve produced; `status` says honestly how it ended."""

    model: str
    direction: str
    line_search: str
    nodes: int
    T: float
    status: str
    reason: str  # how the run ended, in words ("" when solved): the message's first part
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
    descent: DescentRecord
    history: list[IterationRecord] = field(default_factory=list)
    control_names: tuple[str, ...] = ()  # the model's names of the columns of u
    selection_written: tuple[float, ...] = ()  # per selection column: ±1 from λ ∈ Sgn(s) to its name's Sgn as written
    checks: dict[str, dict[str, float]] = field(default_factory=dict)  # name -> {"value", "tol"}: qdframe.descent.checks
    binding_check: str = ""  # the check with the largest value/tol
    error_estimate: float | None = None  # estimate of max_k |x(t_k) − x*(t_k)| (qdframe.certificates.estimates); None: none made
    cost_estimate: float | None = None  # a cost's: estimate of |cost − 𝒥*| (qdframe.certificates.estimates.cost_estimate)
    multipliers: np.ndarray | None = None  # a cost's: (N, n) the costates μ of x' = f (qdframe.descent.multipliers.costates)
    binding: dict[str, list[list[float]]] = field(default_factory=dict)  # bound side -> [[t_a, t_b], …] where it binds
    certificate: str | None = None  # what made the estimate: "bisection" or "replay" (qdframe.certificates.estimates)
    accuracy: float | None = None  # the target: solved promises error_estimate ≤ accuracy·max(1, max|x|)
    switch_times: np.ndarray = field(default_factory=lambda: np.zeros(0))  # where a selection changes regime
    parameters: dict[str, float] = field(default_factory=dict)  # the unknown parameters found (qdframe.unknowns)
    remarks: list[str] = field(default_factory=list)  # what is said of the run after its reason: checks, diagnosis, estimate
    verdict: VerdictRecord | None = None  # the records of the solve (module comment): None where a part did not run
    penalty: PenaltyRecord | None = None
    grids: GridsRecord | None = None
    unknowns: UnknownsRecord | None = None

    @property
    def options(self) -> dict[str, Any]:
        """Every record's fields in one dict (a copy: the records are the result's own), in the
        order descent, verdict, penalty, grids, unknowns; sequences as lists."""
        out: dict[str, Any] = {}
        for name in RECORDS:
            record = getattr(self, name)
            if record is not None:
                out.update({key: list(value) if isinstance(value, tuple) else value
                            for key, value in asdict(record).items()})
        return out

    @property
    def message(self) -> str:
        """The reason and the remarks in one line, joined by "; "."""
        return "; ".join(part for part in (self.reason, *self.remarks) if part)

    @property
    def T_found(self) -> bool:
        """Whether T was free and found with x."""
        return bool(self.unknowns is not None and self.unknowns.free_T)

    @property
    def solved(self) -> bool:
        """Certified: the pointwise checks pass and the error estimate meets the target."""
        return self.status == Status.SOLVED

    @property
    def converged(self) -> bool:
        """The discrete problem is solved: every pointwise check passes (`solved`, or
        `uncertified` where the error is not certified within the target)."""
        return self.status in (Status.SOLVED, Status.UNCERTIFIED)

    def residuals(self) -> dict[str, float]:
        """The pointwise residuals this result has, by short name (boundary, inclusion,
        consistency, then selection and surface where the model has them)."""
        values = {"boundary": self.boundary_error, "inclusion": self.inclusion_residual,
                  "consistency": self.consistency_error, "selection": self.selection_residual,
                  "surface": self.surface_error}
        return {name: float(value) for name, value in values.items() if value is not None}

    def __repr__(self) -> str:
        """A few lines for a notebook: how it ended, on what grid, I and the residuals."""
        lines = [
            f"SolveResult {self.model}: {self.status}, {self.iterations} iterations, {self.nodes} nodes "
            f"(T = {self.T:.10g}{', found' if self.T_found else ''}), {self.direction} / "
            f"{self.line_search}, {self.wall_time_s:.3g} s",
            f"  I {self.I:.3e}, objective {self.objective:.3e}" + (f", cost {self.cost:.3e}" if self.cost is not None else "")
            + (f" (estimate of |cost − 𝒥*| {self.cost_estimate:.2e})" if self.cost_estimate is not None else ""),
            "  residuals: " + ", ".join(f"{name} {value:.2e}" for name, value in self.residuals().items()),
        ]
        if self.error_estimate is not None:
            lines.append(f"  error estimate {self.error_estimate:.2e} ({self.certificate})"
                         + (f", switch times {', '.join(f'{t:.6g}' for t in self.switch_times)}" if len(self.switch_times) else ""))
        if self.parameters:
            lines.append("  parameters: " + _named(self.parameters))
        if self.solution_error is not None:
            lines.append(f"  error vs the known solution {self.solution_error:.2e}")
        if self.message:
            lines.append(f"  message: {self.message}")
        return "\n".join(lines)

    def _columns(self) -> dict[str, list[str]]:
        """The column names of :meth:`to_dataframe` by part: x (the state names), z (x1' …),
        u (the control names) and selections (the sign terms' names); a repeated name gets
        its number ("sgn [2]")."""
        m = 0 if self.u is None else self.u.shape[1]
        controls = list(self.control_names) if len(self.control_names) == m else (
            ["u"] if m == 1 else [f"u{j + 1}" for j in range(m)])
        parts = {"x": list(self.state_names), "z": [f"{name}'" for name in self.state_names], "u": controls,
                 "selections": list(self.selection_names) if self.selections is not None else []}
        taken: set[str] = set()
        for names in parts.values():
            original = list(names)
            for k, name in enumerate(original):
                if name in taken or original.count(name) > 1:
                    names[k] = f"{name} [{k + 1}]"
                taken.add(names[k])
        return parts

    def _written_selections(self) -> np.ndarray | None:
        """The selections as the frames show them: each column the λ of the Sgn(s) its name writes
        (`selections` holds the λ of the switch a term is stored on: u − 0.3·Sgn(v) is kept as
        0.3·Sgn(−v), whose λ is −1 where v > 0; its column "-0.3·Sgn(v)" reads +1 there)."""
        if self.selections is None:
            return None
        lam = np.asarray(self.selections, dtype=float)
        written = np.asarray(self.selection_written, dtype=float)
        return lam * written if written.size == lam.shape[1] else lam

    def to_dataframe(self) -> "pandas.DataFrame":
        """x, z, u and the selections λ per node as a pandas DataFrame indexed by t: a column
        per state (the model's state names), z as x1' …, then u and λ where the model has them
        named as the model names them), then a cost's multipliers μ_x1 … (`multipliers`) and, per
        bound side that binds somewhere, "binds u ≤ 1.5" (True on the points of `binding`), with attrs model, status, T, free_T,
        ``parameter_<name>`` and a cost's ``cost`` and ``cost_estimate``. Needs pandas: ``pip install 'qdframe[frames]'``."""
        pd = _optional("pandas", "to_dataframe")
        names = self._columns()
        blocks = [self.x, self.z] + [part for part in (self.u, self._written_selections()) if part is not None]
        labels = names["x"] + names["z"] + names["u"] + names["selections"]
        if self.multipliers is not None:  # a cost's: the multipliers μ of x' = f, "μ_x1", …
            blocks.append(np.asarray(self.multipliers, dtype=float))
            labels = labels + [f"μ_{name}" for name in names["x"]]
        index = pd.Index(np.asarray(self.t, dtype=float), name="t")
        frame = pd.DataFrame(np.concatenate(blocks, axis=1), index=index, columns=labels)
        t = np.asarray(self.t, dtype=float)
        for side, runs in self.binding.items():  # a bound side that binds somewhere: True on its runs of points
            frame[f"binds {side}"] = np.any([(t >= a) & (t <= b) for a, b in runs], axis=0)
        frame.attrs.update({"model": self.model, "status": str(Status(self.status).value), "T": float(self.T),
                            "free_T": int(self.T_found),
                            **{f"parameter_{name}": float(value) for name, value in self.parameters.items()},
                            **{name: float(value) for name, value in (("cost", self.cost),
                                                                      ("cost_estimate", self.cost_estimate))
                               if value is not None}})
        return frame

    def to_xarray(self) -> "xarray.Dataset":
        """The trajectory as an xarray Dataset: coordinate t, data variables x and z (t, state)
        with the state names as the `state` coordinate, u (t, control) and selections
        (t, selection) where the model has them, and attrs model, direction, status, message,
        nodes, T, iterations, I, objective, the residuals (``residual_<name>``, those that
        exist) and a cost's ``cost`` and ``cost_estimate``. The models declare no units, so none are attached. Needs xarray:
        ``pip install 'qdframe[frames]'``."""
        xr = _optional("xarray", "to_xarray")
        names = self._columns()
        t = np.asarray(self.t, dtype=float)
        variables: dict[str, Any] = {"x": (("t", "state"), np.asarray(self.x)), "z": (("t", "state"), np.asarray(self.z))}
        coords: dict[str, Any] = {"t": t, "state": list(self.state_names)}
        if self.u is not None:
            variables["u"] = (("t", "control"), np.asarray(self.u))
            coords["control"] = names["u"]
        if self.selections is not None:
            variables["selections"] = (("t", "selection"), self._written_selections())
            coords["selection"] = names["selections"]
        attrs: dict[str, Any] = {"model": self.model, "direction": self.direction, "line_search": self.line_search,
                                 "status": str(Status(self.status).value), "message": self.message, "nodes": int(self.nodes),
                                 "T": float(self.T), "iterations": int(self.iterations), "I": float(self.I),
                                 "objective": float(self.objective), "free_T": int(self.T_found)}
        attrs.update({f"parameter_{name}": float(value) for name, value in self.parameters.items()})
        attrs.update({f"residual_{name}": value for name, value in self.residuals().items()})
        if self.solution_error is not None:
            attrs["solution_error"] = float(self.solution_error)
        if self.error_estimate is not None:
            attrs["error_estimate"] = float(self.error_estimate)
        if self.cost is not None:
            attrs["cost"] = float(self.cost)
        if self.cost_estimate is not None:
            attrs["cost_estimate"] = float(self.cost_estimate)
        return xr.Dataset(variables, coords=coords, attrs=attrs)

    def to_dict(self) -> dict[str, Any]:
        data = {}
        for key, value in self.__dict__.items():  # the records as one `options` dict, where it always stood
            if key == "descent":
                data["options"] = self.options
            elif key not in RECORDS and key != "history":
                data[key] = value
        data["converged"] = self.converged  # a property: the discrete problem solved
        data["message"] = self.message  # a property: the reason and the remarks
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
            ("nodes, T", f"{self.nodes}, {self.T:.10g}" + (" (found)" if self.T_found else "")
             + _grids(list(self.grids.grids) if self.grids else [], self.nodes)
             + ("  (nonuniform mesh)" if self.grids and self.grids.uniform is False else "")),
            ("scheme, signs, inputs", f"{self.descent.scheme}, {self.grids.signs if self.grids else '—'}, "
                                      f"{self.grids.inputs if self.grids else '—'}"),
            ("iterations", str(self.iterations)),
            ("wall time", f"{self.wall_time_s:.3f} s"),
            ("objective", f"{self.objective:.3e}"),
            ("I = φ+χ+ω+υ+σ", f"{self.I:.3e}  (" + ", ".join(f"{k} {v:.1e}" for k, v in self.terms.items()) + ")"),
        ]
        if self.cost is not None:
            estimate = [] if self.cost_estimate is None else [f"estimate of |cost − 𝒥*| {self.cost_estimate:.1e}"]
            gap = [] if self.penalty is None else [f"optimality gap {self.penalty.optimality_gap:.1e}",
                                                   f"λ = {self.penalty.penalty:.0e}"]
            optimum = f"  ({', '.join(estimate + gap)})" if estimate or gap else ""
            rows.insert(7, ("cost", f"{self.cost:.10g}" + optimum))
        if self.parameters:
            rows.insert(4, ("parameters", _named(self.parameters)))
        labels = {"boundary": "boundary error", "inclusion": "inclusion residual", "selection": "selection residual",
                  "consistency": "consistency error", "surface": "surface error"}
        for name, value in self.residuals().items():
            check = self.checks.get(name)
            text = f"{value:.3e}"
            if check is not None:
                text += f"  (tol {check['tol']:.1e}{', binds' if name == self.binding_check else ''})"
            rows.append((labels[name], text))
        if "bounds" in self.checks:  # state_bounds, control_bounds: the largest violation, and where they bind
            check = self.checks["bounds"]
            rows.append(("bound violation", f"{check['value']:.3e}  (tol {check['tol']:.1e}"
                         + (", binds)" if self.binding_check == "bounds" else ")")))
            rows.append(("bounds binding", "; ".join(
                f"{name} on " + ", ".join(f"[{a:.6g}, {b:.6g}]" for a, b in runs) for name, runs in self.binding.items())
                or "none"))
        bound = None if self.accuracy is None else self.accuracy * max(1.0, float(np.max(np.abs(self.x))))
        how = {"bisection": "from the bisected mesh", "replay": "against the true motion its choices drive"}
        rows.append(("error estimate", "—" if self.error_estimate is None else
                     f"{self.error_estimate:.3e}  (max |x − x*| over the points, {how.get(self.certificate or '', '')})"
                     + ("" if bound is None else f"; target {bound:.1e}")))
        if len(self.switch_times):
            rows.append(("switch times", ", ".join(f"{t:.10g}" for t in self.switch_times)))
        if self.solution_error is not None:
            rows.append(("error vs known solution", f"{self.solution_error:.3e}"))
        width = max(len(k) for k, _ in rows)
        return "\n".join(f"{k:<{width}}  {v}" for k, v in rows)

    def plot(self, path: str | Path | None = None, **kwargs: Any) -> matplotlib.figure.Figure:
        """The figure of this result (trajectories, z against F(x(t)), I per iteration),
        saved to `path` only when given; `kwargs` as :func:`qdframe.plotting.plot_result`."""
        from .plotting import plot_result

        return plot_result(self, path, **kwargs)


def _optional(module: str, method: str) -> Any:
    """An optional extra's module, or an ImportError saying how to install it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise ImportError(f"SolveResult.{method}() needs {module}: pip install 'qdframe[frames]'") from None


def _named(values: dict[str, float]) -> str:
    return ", ".join(f"{name} = {value:.10g}" for name, value in values.items())


def _grids(grids: list[int], nodes: int) -> str:
    grids = [count for k, count in enumerate(grids) if k == 0 or count != grids[k - 1]]  # re-solves on one size: once
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
