"""Filippov initial-value simulation of a model's inclusion (`qdframe simulate`).

Implicit Euler: x_{k+1} = x_k + Δt·z_{k+1} with z_{k+1} ∈ F(x_{k+1}). A sign term
a·Sgn(s) enters F as the point a·λ of Filippov's set, its selection λ an unknown tied by
the natural map λ = clip(λ + c·s(x_{k+1}), −1, 1) (as `Functional.selection_residual`):
λ = sign s off the surface, and on it s = 0 exactly with λ ∈ [−1, 1] the equivalent
control. Sliding and sticking are exact roots, without a band or event location; terms
with the same switch share one λ. A vector sign Sgn(s), s ∈ R^k (isotropic friction), has
one selection vector λ ∈ B tied by λ = P_B(λ + c·s), the projection onto the unit ball: λ =
s/|s| while it slides, |λ| ≤ 1 and s = 0 while it sticks. c = 1/|∂s/∂λ| through the step
(Alart–Curnier's scaling; one c per vector sign, the largest of its components'), so that
the result does not depend on how s is scaled. Of an interval
[lo_i, hi_i] the simulator takes the velocity nearest the previous one,
z_i = clip(z_i^prev, lo_i, hi_i), so a singleton set is followed exactly and an interval
only as far as it must.

The steps are solved a window of up to `WINDOW_MAX` steps at a time, by semismooth Newton
on all of the window's equations at once (the model evaluated at all its nodes, one banded
solve per iteration); the leading steps that converged are kept, and a step the window
cannot settle is solved alone by damped Newton. One-coordinate blocks only (ψ ∈ {−1, +1}).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.linalg import solve_banded

from .errors import InputError, QdframeError
from .functional import Functional
from .functional.terms import _ball_projection_jacobian
from .schemes.grid import Grid
from .model import InclusionModel

SCALE_FLOOR = 1e-12  # c ≤ 1e12 where a selection hardly moves its own switch
TOL = 1e-12  # a step is solved when |z − target| ≤ TOL·(1 + |z_prev|) and |λ − clip(λ + c·s)| ≤ TOL,
ROUNDING = 8 * np.finfo(float).eps  # or within what x_j's rounding moves them by
WINDOW_MIN, WINDOW_MAX = 16, 4096  # steps per window: doubled after a window that converged whole
WINDOW_ITERATIONS = 8  # Newton iterations per window before its converged leading steps are kept


@dataclass
class Simulation:
    """A simulated trajectory: t (K,), x (K, n), z (K, n) and the controls used."""

    model: str
    t: np.ndarray
    x: np.ndarray
    z: np.ndarray
    u: np.ndarray | None
    dt: float  # the largest step
    state_names: tuple[str, ...]
    selections: np.ndarray | None = None  # λ of each selection, with z: of the step from t_k (the last: repeated)

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
) -> Simulation:
    """Simulate x' ∈ F(x) (controls u(t), default 0) from x(t_start) = x_start to t_end; a model
    with unknown parameters at their values (`model(parameters={...})`, else its guesses)."""
    if not (np.isfinite(t_start) and np.isfinite(t_end) and t_end > t_start):
        raise InputError("--to", f"a time after --from = {t_start}", t_end)
    if not (np.isfinite(dt) and dt > 0):
        raise InputError("dt", "a positive number", dt)
    if model.parameter_names:  # simulated with its parameters' values (guesses: `parameters=` of the model)
        from .unknowns import Unknowns, restated

        model = Unknowns(restated(model, False, None), fixed=True)
    x = np.asarray(x_start, dtype=float).reshape(-1)
    if x.size != model.n_states or not np.all(np.isfinite(x)):
        raise InputError("x0", f"{model.n_states} finite comma-separated numbers", ",".join(map(str, x)))
    if any(block.size != 1 for block in model.blocks()):
        raise InputError("model", f"a model of one-coordinate blocks for simulation ({model.name} has a ψ ∈ S_k block)")
    steps = int(np.ceil((t_end - t_start) / dt - 1e-9))
    dt = (t_end - t_start) / steps
    return simulate_on(model, t_start + dt * np.arange(steps + 1), x, controls)


def simulate_on(model: InclusionModel, t: np.ndarray, x_start: Sequence[float],
                controls: Sequence[float] | Callable[[float], np.ndarray] | None = None) -> Simulation:
    """The same implicit Euler steps on the given times t (increasing, any spacing): the
    discrete solution a solve's implicit-Euler grid has, where the model leaves no choice."""
    t = np.asarray(t, dtype=float)
    steps = t.size - 1
    x = np.asarray(x_start, dtype=float).reshape(-1)
    us = _control_values(model, controls, t)
    widths = np.diff(t)
    stepper = _Stepper(model, float(np.max(widths)))

    xs = np.empty((steps + 1, model.n_states))
    zs = np.empty_like(xs)
    xs[0] = x
    lam = stepper.first_selections(stepper.switches(np.concatenate([x, us[0]])[None, :])[0][0])
    lo, hi, _, _ = stepper.bounds(np.concatenate([x, us[0]])[None, :], lam[None, :])
    z = np.clip(0.5 * (lo[0] + hi[0]), lo[0], hi[0])
    lams = np.empty((steps + 1, lam.size))
    k, window = 0, WINDOW_MIN
    while k < steps:
        size = min(window, steps - k)
        stepper.steps(widths[k : k + size], widths[k - 1] if k else widths[0])
        count, z_new, lam_new = stepper.window(xs[k], z, lam, us[k + 1 : k + 1 + size])
        if count == 0:
            stepper.steps(widths[k : k + 1], widths[k - 1] if k else widths[0])
            count, z_new, lam_new = 1, *stepper.single(xs[k], z, lam, us[k + 1])
        xs[k + 1 : k + 1 + count] = xs[k] + np.cumsum(widths[k : k + count, None] * z_new[:count], axis=0)
        zs[k : k + count] = z_new[:count]  # z[k]: the velocity of the step from t_k (x[k+1] = x[k] + Δt·z[k])
        lams[k : k + count] = lam_new[:count]
        z, lam = z_new[count - 1], lam_new[count - 1]
        k += count
        window = min(2 * window, WINDOW_MAX) if count == size else max(count, WINDOW_MIN)
    zs[-1], lams[-1] = z, lam
    return Simulation(model.name, t, xs, zs, us if model.n_controls else None, float(np.max(widths)),
                      tuple(model.state_names), lams)


def _control_values(model: InclusionModel, controls, t: np.ndarray) -> np.ndarray:
    """u(t_k) for every time, (K, m)."""
    m = model.n_controls
    if controls is None:
        return np.zeros((t.size, m))
    if callable(controls):
        return np.array([np.asarray(controls(tk), dtype=float).reshape(m) for tk in t]).reshape(t.size, m)
    fixed = np.asarray(controls, dtype=float).reshape(-1)
    if fixed.size != m:
        raise InputError("controls", f"{m} values", controls)
    return np.broadcast_to(fixed, (t.size, m)).copy()


class _Stepper:
    """The implicit Euler steps of x' ∈ F(x): their residuals and semismooth Newton on them.

    Unknowns per step j: z_j (n) and the selections λ_j (p); x_j = x_{j−1} + Δt·z_j. The
    residual is z_j − clip(z_{j−1}, lo(y_j, λ_j), hi(y_j, λ_j)) and λ_j − clip(λ_j + c·s(y_j), −1, 1),
    y_j = (x_j, u_j). Newton solves for the change of x (banded: step j meets x_j, x_{j−1}, x_{j−2})
    and λ, then z_j = (x_j − x_{j−1})/Δt.
    """

    def __init__(self, model: InclusionModel, dt: float) -> None:
        self.functional = Functional(model, Grid(1.0, 2), signs="exact")
        self.n, self.p = model.n_states, self.functional.p
        self.steps(np.array([dt]), dt)

    def steps(self, widths: np.ndarray, before: float) -> None:
        """The step widths Δt_j (W,) of the next window and the width of the step before it."""
        self.dt = np.asarray(widths, dtype=float)[:, None]  # (W, 1)
        self.dt_before = np.concatenate([[before], widths[:-1]])[:, None]  # Δt_{j−1}
        self.coords = [block.coords[0] for block in self.functional.blocks]
        self.size = self.n + self.p  # unknowns per step: x_j, then λ_j

    def switches(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """s (N, p) of every selection's switch (a vector sign's components in its columns) and ∂s/∂x (N, p, n)."""
        s, ds = self.functional.switch_values(y)
        return s, ds[:, :, : self.n]

    def first_selections(self, s: np.ndarray) -> np.ndarray:
        """λ (p,) at the start: sign(s), a vector sign's s/|s| (0 where s = 0)."""
        lam = np.sign(s)
        for first, width in self.functional.balls:
            part = s[first : first + width]
            radius = np.linalg.norm(part)
            lam[first : first + width] = part / radius if radius > 0 else 0.0
        return lam

    def bounds(self, y: np.ndarray, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """lo, hi (N, n) of F(x) with the sign terms at a·λ, and their gradients (N, n, n + p) in (x, λ)."""
        f, n, nodes = self.functional, self.n, y.shape[0]
        lo, hi = np.empty((nodes, n)), np.empty((nodes, n))
        dlo, dhi = np.empty((nodes, n, f.width)), np.empty((nodes, n, f.width))
        zero = np.zeros((nodes, n))
        for b, (coord, block) in enumerate(zip(self.coords, f.blocks)):
            plus, minus = f.pieces.sides_1d(block, y, zero, f.block_selections(b, lam))  # ℓ(±1) at z = 0: ∓(the ends)
            hi[:, coord], lo[:, coord] = -plus.ell, minus.ell
            dhi[:, coord], dlo[:, coord] = -plus.gradient(f.width), minus.gradient(f.width)
        for i, j in f.resolved.items():  # z_i ≡ x_j: no block
            hi[:, i], dhi[:, i] = y[:, j], 0.0
            dhi[:, i, j] = 1.0
            lo[:, i], dlo[:, i] = hi[:, i], dhi[:, i]
        columns = np.r_[:n, f.args : f.width]  # x and λ (u is given)
        return lo, hi, dlo[:, :, columns], dhi[:, :, columns]

    def residual(self, x0: np.ndarray, z0: np.ndarray, z: np.ndarray, lam: np.ndarray, u: np.ndarray,
                 scale: np.ndarray | None = None):
        """The residual (W, n + p) of the steps z (W, n), λ (W, p) after x0 with velocity z0; whether
        each step is solved (W,); the Jacobian's blocks: on step j's own unknowns (W, n + p, n + p)
        and the diagonals on x_{j−1} and x_{j−2} (W, n); and c (W, p), the natural map's scale
        (given, or 1/|∂s/∂λ| through the step at this iterate: :meth:`scales`)."""
        n, dt, before = self.n, self.dt[: z.shape[0]], self.dt_before[: z.shape[0]]
        x = x0 + np.cumsum(dt * z, axis=0)  # x_j = x_0 + Σ_{i≤j} Δt_i·z_i, x_0 the window's start
        y = np.concatenate([x, u], axis=1)
        lo, hi, dlo, dhi = self.bounds(y, lam)
        s, ds = self.switches(y)
        previous = np.concatenate([z0[None, :], z[:-1]])
        upper = previous >= hi
        lower = ~upper & (previous <= lo)
        keep = ~upper & ~lower  # z_j = z_{j−1}, strictly inside the interval
        r_z = z - np.where(upper, hi, np.where(lower, lo, previous))
        slope = np.where(upper[:, :, None], dhi, np.where(lower[:, :, None], dlo, 0.0))  # ∂target/∂(x, λ)
        own = np.zeros((z.shape[0], self.size, self.size))
        own[:, :n] = -slope
        own[:, :n, :n] += np.eye(n)[None, :, :] / dt[:, :, None]
        if scale is None:
            scale = self.scales(own, ds)
        moved = lam + scale * s
        inside = np.abs(moved) < 1.0  # the clip is the identity there
        r_lam = lam - self.functional.project(moved)
        # solved to TOL, or to the rounding of x_j (ε|x_j| moves the target and c·s by as much)
        noise = ROUNDING * np.abs(x)[:, None, :]
        solved = np.all(np.abs(r_z) <= TOL * (1.0 + np.max(np.abs(previous), axis=1))[:, None]
                        + np.sum(np.abs(slope[:, :, :n]) * noise, axis=2), axis=1)
        solved &= np.all(np.abs(r_lam) <= TOL + scale * np.sum(np.abs(ds) * noise, axis=2), axis=1)
        own[:, n:, :n] = -(scale * inside)[:, :, None] * ds
        own[:, n:, n:] = np.eye(self.p) * (1.0 - inside[:, None, :])
        for first, width in self.functional.balls:  # P_B's Jacobian D: −c·D·∇s on x, I − D on λ
            block = slice(first, first + width)
            derivative = _ball_projection_jacobian(moved[:, block])
            own[:, n + first : n + first + width, :n] = -scale[:, first, None, None] * (derivative @ ds[:, block])
            own[:, n + first : n + first + width, n + first : n + first + width] = np.eye(width) - derivative
        back1 = -1.0 / dt - keep / before  # z_j − z_{j−1}·keep with z_j = (x_j − x_{j−1})/Δt_j
        back1[0] = 0.0
        back2 = keep / before
        back2[:2] = 0.0
        return np.concatenate([r_z, r_lam], axis=1), solved, own, back1, back2, scale

    def scales(self, own: np.ndarray, ds: np.ndarray) -> np.ndarray:
        """c = 1/|∂s_k/∂λ_k| (W, p), s's response to its selection through the step
        (Alart–Curnier's scaling): then λ + c·s is the selection that puts s near 0, so a step
        onto a surface lands inside (−1, 1) and slides rather than bouncing between ±1."""
        n = self.n
        try:
            response = ds @ np.linalg.solve(own[:, :n, :n], -own[:, :n, n:])  # ∂s/∂λ (W, p, p)
        except np.linalg.LinAlgError:
            return np.ones((own.shape[0], self.p))
        diagonal = np.abs(np.diagonal(response, axis1=1, axis2=2))
        for first, width in self.functional.balls:  # one c per vector sign: P_B(λ + c·s) needs c scalar
            diagonal[:, first : first + width] = np.max(diagonal[:, first : first + width], axis=1, keepdims=True)
        return 1.0 / np.maximum(diagonal, SCALE_FLOOR)

    def newton_step(self, own: np.ndarray, back1: np.ndarray, back2: np.ndarray, r: np.ndarray) -> np.ndarray:
        """The Newton change (W, n + p) of (x, λ) per step: the banded system solved once."""
        steps, m = r.shape
        if steps == 1:
            return np.linalg.solve(own[0], -r[0])[None, :]
        lower, upper = 3 * m - 1, m - 1
        bands = np.zeros((lower + upper + 1, steps * m))
        a, b = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
        columns = (m * np.arange(steps))[:, None, None] + b
        bands[upper + a - b, columns] = own
        diagonal = m * np.arange(steps)[:, None] + np.arange(self.n)  # the x-columns of every step
        bands[upper + m, diagonal[:-1]] = back1[1:]
        bands[upper + 2 * m, diagonal[:-2]] = back2[2:]
        return solve_banded((lower, upper), bands, -r.reshape(-1), check_finite=False).reshape(steps, m)

    def velocities(self, z: np.ndarray, change: np.ndarray) -> np.ndarray:
        """z after a Newton change of x: z_j + (Δx_j − Δx_{j−1})/Δt."""
        dx = change[:, : self.n]
        return z + np.diff(dx, axis=0, prepend=np.zeros((1, self.n))) / self.dt[: z.shape[0]]

    def window(self, x0: np.ndarray, z0: np.ndarray, lam0: np.ndarray,
               u: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """Semismooth Newton on the next W steps at once, from z and λ held: the number of
        leading steps solved, and the last iterate's z (W, n) and λ (W, p)."""
        z, lam = np.tile(z0, (u.shape[0], 1)), np.tile(lam0, (u.shape[0], 1))
        best, scale = (0, z, lam), None
        for iteration in range(WINDOW_ITERATIONS + 1):
            try:
                with np.errstate(all="ignore"):  # a wild iterate's overflow: its steps are not kept
                    r, solved, own, back1, back2, scale = self.residual(x0, z0, z, lam, u, scale)
            except (QdframeError, ArithmeticError):  # the model undefined there: keep what was solved
                break
            best = (solved.size if solved.all() else int(np.argmin(solved))), z, lam
            if best[0] == solved.size or iteration == WINDOW_ITERATIONS:
                break
            try:
                change = self.newton_step(own, back1, back2, r)
            except (np.linalg.LinAlgError, ValueError):
                break
            if not np.all(np.isfinite(change)):
                break
            z, lam = self.velocities(z, change), lam + change[:, self.n :]
        return best

    def single(self, x0: np.ndarray, z0: np.ndarray, lam0: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One step by damped semismooth Newton (backtracking on |r|): z (1, n), λ (1, p)."""
        z, lam, u = z0[None, :].copy(), lam0[None, :].copy(), u[None, :]
        r, solved, own, back1, back2, scale = self.residual(x0, z0, z, lam, u)
        for _ in range(60):
            if solved[0]:
                return z, lam
            try:
                change = self.newton_step(own, back1, back2, r)
            except np.linalg.LinAlgError:
                change = np.linalg.lstsq(own[0], -r[0], rcond=None)[0][None, :]
            norm, length = np.linalg.norm(r), 1.0
            while length > 1e-8:
                trial = self.velocities(z, length * change), lam + length * change[:, self.n :]
                state = self.residual(x0, z0, *trial, u, scale)
                if np.linalg.norm(state[0]) < (1 - 1e-4 * length) * norm:
                    break
                length *= 0.5
            (z, lam), (r, solved, own, back1, back2, _) = trial, state
        scale = 1.0 + np.max(np.abs(z0))
        if np.max(np.abs(r)) > 1e-8 * scale:
            raise QdframeError(f"simulate: the implicit step did not converge (residual {np.max(np.abs(r)):.2e})")
        return z, lam
