"""Filippov initial-value simulation of a model's inclusion (`qdframe simulate`).

Implicit Euler: x_{k+1} = x_k + Δt·z_{k+1} with z_{k+1} ∈ F(x_{k+1}). Among the
admissible velocities the simulator takes the one nearest to the previous velocity
(per coordinate z_i = clip(z_i^prev, lo_i(x_{k+1}), hi_i(x_{k+1}))), so a singleton set
is followed exactly and an interval only as far as it must. Sign terms a·Sgn(s) use
Filippov's set with a tiny band (default 1e-9): on a discontinuity surface the only
consistent implicit step keeps s = 0, so sliding modes come out of the scheme without
event location. Each step solves R(z) = 0 by semismooth Newton with backtracking.
One-coordinate blocks only (ψ ∈ {−1, +1}).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError, QdframeError
from .functional import Functional
from .grid import Grid
from .model import InclusionModel


@dataclass
class Simulation:
    """A simulated trajectory: t (K,), x (K, n), z (K, n) and the controls used."""

    model: str
    t: np.ndarray
    x: np.ndarray
    z: np.ndarray
    u: np.ndarray | None
    dt: float
    state_names: tuple[str, ...]

    def to_dict(self) -> dict:
        return {
            "model": self.model,
            "t0": float(self.t[0]),
            "t1": float(self.t[-1]),
            "dt": self.dt,
            "state_names": list(self.state_names),
            "x_end": self.x[-1].tolist(),
            "t": self.t.tolist(),
            "x": self.x.tolist(),
            "z": self.z.tolist(),
            "u": None if self.u is None else self.u.tolist(),
        }

    def to_json(self, path: str | Path | None = None) -> str:
        text = json.dumps(self.to_dict(), indent=1)
        if path is not None:
            Path(path).write_text(text + "\n")
        return text


def simulate(
    model: InclusionModel,
    t_start: float,
    t_end: float,
    x_start: Sequence[float],
    dt: float = 1e-4,
    controls: Sequence[float] | Callable[[float], np.ndarray] | None = None,
    band: float = 1e-9,
) -> Simulation:
    """Simulate x' ∈ F(x) (controls u(t), default 0) from x(t_start) = x_start to t_end."""
    if not (np.isfinite(t_start) and np.isfinite(t_end) and t_end > t_start):
        raise InputError("--to", f"a time after --from = {t_start}", t_end)
    if not (np.isfinite(dt) and dt > 0):
        raise InputError("dt", "a positive number", dt)
    x = np.asarray(x_start, dtype=float).reshape(-1)
    if x.size != model.n_states or not np.all(np.isfinite(x)):
        raise InputError("x0", f"{model.n_states} finite comma-separated numbers", ",".join(map(str, x)))
    if any(block.size != 1 for block in model.blocks()):
        raise InputError("model", f"a model of one-coordinate blocks for simulation ({model.name} has a ψ ∈ S_k block)")
    steps = int(np.ceil((t_end - t_start) / dt - 1e-9))
    dt = (t_end - t_start) / steps
    t = t_start + dt * np.arange(steps + 1)
    u_of_t = _controls(model, controls)
    evaluator = _Evaluator(model, band)

    xs = np.empty((steps + 1, model.n_states))
    zs = np.empty_like(xs)
    us = np.array([u_of_t(tk) for tk in t]) if model.n_controls else None
    xs[0] = x
    lo, hi, _, _ = evaluator.bounds(x, u_of_t(t[0]))
    z = np.clip(0.5 * (lo + hi), lo, hi)
    for k in range(steps):
        z = _implicit_step(evaluator, xs[k], z, dt, u_of_t(t[k + 1]))
        xs[k + 1] = xs[k] + dt * z
        zs[k] = z
    zs[-1] = z
    return Simulation(model.name, t, xs, zs, us, dt, tuple(model.state_names))


def _controls(model: InclusionModel, controls) -> Callable[[float], np.ndarray]:
    m = model.n_controls
    if controls is None:
        return lambda _t: np.zeros(m)
    if callable(controls):
        return lambda tk: np.asarray(controls(tk), dtype=float).reshape(m)
    fixed = np.asarray(controls, dtype=float).reshape(-1)
    if fixed.size != m:
        raise InputError("controls", f"{m} values", controls)
    return lambda _t: fixed


class _Evaluator:
    """The interval [lo_i(x), hi_i(x)] of every coordinate and their x-gradients."""

    def __init__(self, model: InclusionModel, band: float) -> None:
        self.functional = Functional(model, Grid(1.0, 2), signs="band")
        self.functional.blocks = tuple(
            dataclasses.replace(block, signs=tuple(dataclasses.replace(s, band=band) for s in block.signs))
            for block in self.functional.blocks
        )
        self.n = model.n_states
        self.coords = [block.coords[0] for block in self.functional.blocks]

    def bounds(self, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        f = self.functional
        y = np.concatenate([x, u])[None, :]
        zero = np.zeros((1, self.n))
        lo, hi = np.empty(self.n), np.empty(self.n)
        dlo, dhi = np.empty((self.n, self.n)), np.empty((self.n, self.n))
        for coord, block in zip(self.coords, f.blocks):
            plus, minus = f._sides_1d(block, y, zero)  # ℓ(±1) at z = 0 is ∓(the interval's ends)
            hi[coord], lo[coord] = -plus.ell[0], minus.ell[0]
            dhi[coord] = -plus.gradient(f.args)[0, : self.n]
            dlo[coord] = minus.gradient(f.args)[0, : self.n]
        return lo, hi, dlo, dhi


def _implicit_step(evaluator: _Evaluator, x: np.ndarray, z_prev: np.ndarray, dt: float, u: np.ndarray) -> np.ndarray:
    """Solve z = clip(z_prev, lo(x + dt·z), hi(x + dt·z)) by semismooth Newton."""

    def residual(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lo, hi, dlo, dhi = evaluator.bounds(x + dt * z, u)
        target = np.clip(z_prev, lo, hi)
        slope = np.where((z_prev > hi)[:, None], dhi, np.where((z_prev < lo)[:, None], dlo, 0.0))
        return z - target, np.eye(z.size) - dt * slope

    z = z_prev.copy()
    r, jac = residual(z)
    scale = 1.0 + np.max(np.abs(z_prev))
    for _ in range(60):
        if np.max(np.abs(r)) <= 1e-12 * scale:
            return z
        try:
            step = np.linalg.solve(jac, -r)
        except np.linalg.LinAlgError:
            step = -r
        norm = np.linalg.norm(r)
        length = 1.0
        while length > 1e-8:
            trial = z + length * step
            r_trial, jac_trial = residual(trial)
            if np.linalg.norm(r_trial) < (1 - 1e-4 * length) * norm:
                break
            length *= 0.5
        z, r, jac = trial, r_trial, jac_trial
    if np.max(np.abs(r)) > 1e-8 * scale:
        raise QdframeError(f"simulate: the implicit step did not converge (residual {np.max(np.abs(r)):.2e})")
    return z
