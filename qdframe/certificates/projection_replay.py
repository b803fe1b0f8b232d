"""The replay: the reference Filippov's theorem builds from a solver's own trajectory.

A boundary-value problem for an inclusion x' ∈ F(x, u) has a whole set of solutions, so a
fixed reference solution cannot judge a solver. The replay can: from the solver's nodes
t_k, states x_k, velocities z_k and controls u_k it integrates the TRUE motion

    x_ref(0) = x0,    x_ref'(t) = P_{F(x_ref(t), u(t))}(z(t)),

P_F(z) the point of the convex set F nearest to z, z(t) and u(t) the solver's velocities
and controls interpolated linearly in t (x0 the model's start where given, the solver's
x_0 where free). x_ref is a genuine solution of the inclusion (its velocity is in F at
every time) and, by Filippov's estimate, |x_k − x_ref(t_k)| is bounded by the solver's
defects (dist(z, F) and the consistency x − x0 − ∫z) propagated with e^{Lt}. Reported:
the error max_k |x_k − x_ref(t_k)|_∞ and the end miss of x_ref itself (the boundary error
of :meth:`~qdframe.functional.Functional.boundary_error`).

P comes from qdframe's own support-function machinery (:func:`nearest_velocity`):
:meth:`~qdframe.functional.Functional.distance_sides` gives per block its sides
ℓ(ψ) = ⟨z_b, ψ⟩ − c(F_b, ψ); with dist(z, F_b) = max_ψ ℓ(ψ) the nearest point is
z_b − dist·ψ*, i.e. z_b − Σ_sides max(0, ℓ)·ψ, and z_b − ℓ for an equation block.
Sign terms are judged by the band (signs="band", Filippov's set widened within the
model's band β, as the peers are judged).

The caveat of intersections. For a block of k ≥ 2 coordinates whose set is an
intersection (a min-group, c̃ = min of support functions, Remark 5.1), max_ψ ℓ̃ is
max(dist(z, A), dist(z, B)), not dist(z, A ∩ B): where z lies in the normal cone of a
corner of A ∩ B the one-pass point z − h·ψ* is the projection onto the farther set only
and lies outside the other. :func:`nearest_velocity` therefore checks the moved points
(h > 1e-10) and repeats the step from there (alternating projections onto the farther
set) until the point is in F to 1e-13: a point of F within a constant times dist(z, F)
(the constant depends on the corner's angle), but not always the nearest one.

Integration (:func:`replay`). Every solver interval is split into s equal sub-intervals,
each with the three Lobatto points (ends and midpoint); z and u are linear inside a
solver interval, so the integrand is smooth between the projection's own switches. The
replay is the collocation solution (Lobatto IIIA, the cumulative Simpson rule, order 4)
at all those points at once: the fixed point of X = x0 + C·P(X, z), C the cumulative
quadrature, found by Newton–Picard sweeps — one vectorized evaluation of P (and its
x-Jacobian from the sides' gradients) per sweep at every point, the correction δ
solving the linearized equation by backward Euler (the recursion for all steps at once,
one block-bidiagonal banded solve: no Python loop over time). s is chosen so that there are at least
`min_substeps` sub-intervals in all; the replay is then repeated with 2s, 4s, …
sub-intervals per interval (each run started from the one before) until the replay at
the solver's nodes changes by ≤ `target` or the next run would exceed `max_points`
points. The last run is reported and `uncertainty` is its change from the one before
(plus its last sweep's correction). The projection's switches (kinks of the integrand
inside a sub-interval) limit the order to 2 there, so that change is what is trusted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_banded

from ..errors import InputError
from ..functional import Functional
from ..functional.nearest import nearest as _nearest, nearest_velocity  # noqa: F401  (nearest_velocity: re-exported)
from ..schemes.grid import Grid
from ..model import InclusionModel



@dataclass(frozen=True)
class Replay:
    """The replay of one trajectory (see the module's docstring)."""

    x: np.ndarray  # x_ref at the solver's times, (N, n)
    error: float  # max_k |x_k − x_ref(t_k)|_∞
    end_miss: float  # max_j |x_ref,j(T) − xT_j| (and periodic gaps) of x_ref itself
    uncertainty: float  # max_k |x_ref(t_k)| change between s and 2s sub-intervals, + last correction
    seconds: float
    recipe: str
    sweeps: tuple[int, ...] = ()  # Newton–Picard sweeps of each run (sub-steps doubling)
    corners: int = 0  # evaluations where the one-pass projection left F (intersections) and was repeated

    def __repr__(self) -> str:
        return (f"Replay(error={self.error:.3e}, end_miss={self.end_miss:.3e}, "
                f"uncertainty={self.uncertainty:.1e}, seconds={self.seconds:.3g}; {self.recipe})")


# ------------------------------------------------------------------ the replay
def replay(model: InclusionModel | str, t, x, z, u=None, *, min_substeps: int = 2000, tol: float = 1e-12,
           max_sweeps: int = 40, psi_samples: int = 32, target: float = 1e-9,
           max_points: int = 400_001, continuation=None) -> Replay:
    """The replay of a solver's trajectory (t (N,), x and z (N, n), u (N, m) if the model has
    controls): x_ref at the solver's times, its error against x, its end miss and its own
    uncertainty. See the module's docstring. `continuation(values, times)` continues z and u
    between the points t (right-continuous where it jumps); default: linear."""
    start = time.perf_counter()
    if isinstance(model, str):
        from ..registry import lookup

        model = lookup("models", model).obj()
    n, m = model.n_states, model.n_controls
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise InputError("t", "a 1-D array of at least 2 times", f"shape {t.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise InputError("t", "increasing finite times", f"[{t[0]:g}, …, {t[-1]:g}]")
    N = t.size
    x = _array("x", x, (N, n))
    z = _array("z", z, (N, n))
    if m:
        if u is None:
            raise InputError("u", f"the controls of model {model.name!r}, shape {(N, m)}", None)
        u = _array("u", u, (N, m))
    elif u is not None and np.size(u):
        raise InputError("u", f"None (model {model.name!r} has no controls)", f"shape {np.shape(u)}")
    else:
        u = np.zeros((N, 0))
    x0 = np.where(np.isfinite(model.x0), model.x0, x[0])

    s = max(1, int(np.ceil(min_substeps / (N - 1))))
    run = _Run(model, t, z, u, s, psi_samples, continuation)
    X, sweeps, last, corners = run.solve(x0, run.start_from(x), tol, max_sweeps)
    history = [(s, sweeps)]
    while True:  # double the sub-steps until the replay at the solver's nodes moves by ≤ target
        finer = _Run(model, t, z, u, 2 * s, psi_samples, continuation)
        X2, sweeps2, last2, corners2 = finer.solve(x0, finer.refine(X), tol, max_sweeps)
        history.append((2 * s, sweeps2))
        corners = max(corners, corners2)
        change = float(np.max(np.abs(X2[:: 4 * s] - X[:: 2 * s])))
        X, s, last = X2, 2 * s, last2
        if change <= target or 4 * s * (N - 1) + 1 > max_points:
            break
    fine = X[:: 2 * s]
    uncertainty = change + last
    error = float(np.max(np.abs(x - fine)))
    judge = Functional(model, Grid(model.T, 2), signs="band")
    end_miss = judge.boundary_error(np.concatenate([fine[[0, -1]], np.zeros((2, n))], axis=1))
    seconds = time.perf_counter() - start
    steps = ", ".join(f"{k} ({k * (N - 1)} in all, {w} sweeps)" for k, w in history)
    recipe = (f"replay: Lobatto IIIA (cumulative Simpson) collocation, Newton–Picard sweeps, on {steps} sub-steps "
              f"per solver interval, the last reported, uncertainty = its change from the one before; "
              f"P by distance_sides (band signs, ψ* from {psi_samples} samples)"
              + (f"; {corners} intersection-corner points re-projected" if corners else ""))
    return Replay(fine, error, float(end_miss), uncertainty, seconds, recipe, tuple(w for _, w in history), corners)


def _array(name: str, value, shape: tuple[int, int]) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != shape:
        raise InputError(name, f"shape {shape} (nodes of t × {'states' if name != 'u' else 'controls'})",
                         f"shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InputError(name, "finite values", "NaN or inf")
    return array


class _Run:
    """The collocation problem on s sub-intervals per solver interval."""

    def __init__(self, model: InclusionModel, t: np.ndarray, z: np.ndarray, u: np.ndarray, s: int,
                 psi_samples: int, continuation=None) -> None:
        self.s = s
        N = t.size
        # 2s + 1 points per solver interval: θ = j/(2s), the Lobatto points of the s sub-intervals
        theta = np.arange(2 * s) / (2 * s)
        self.tau = np.concatenate([(t[:-1, None] + theta[None, :] * np.diff(t)[:, None]).ravel(), t[-1:]])
        left = np.minimum(np.arange(self.tau.size) // (2 * s), N - 2)
        frac = np.concatenate([np.tile(theta, N - 1), [1.0]])[:, None]
        if continuation is None:
            self.z = z[left] + frac * (z[left + 1] - z[left])
            self.u = u[left] + frac * (u[left + 1] - u[left])
        else:  # right-continuous at its jumps; the left limits at the solver's points are kept apart
            self.z = continuation(z, self.tau)
            self.u = continuation(u, self.tau) if u.shape[1] else np.zeros((self.tau.size, 0))
            ends = np.arange(2 * s, self.tau.size, 2 * s)  # the solver's points after the first
            before = np.nextafter(self.tau[ends], -np.inf)
            z_left = continuation(z, before)
            u_left = continuation(u, before) if u.shape[1] else np.zeros((ends.size, 0))
            jumps = np.any(z_left != self.z[ends], axis=1) | np.any(u_left != self.u[ends], axis=1)
            self.jumps, self.z_left, self.u_left = ends[jumps], z_left[jumps], u_left[jumps]
        self.H = np.repeat(np.diff(t) / s, s)  # width of each sub-interval
        n = model.n_states
        self.n = n
        grid = Grid.from_mesh(self.tau - self.tau[0])
        self.functional = Functional(model, grid, psi_samples=psi_samples, signs="band")
        self.xi = np.zeros((self.tau.size, self.functional.dim))
        self.xi[:, n: 2 * n] = self.z
        self.xi[:, 2 * n: 2 * n + self.u.shape[1]] = self.u
        if continuation is None:
            self.jumps = np.zeros(0, dtype=int)
        self.left = np.zeros((self.jumps.size, self.functional.dim))
        if self.jumps.size:
            self.left[:, n: 2 * n], self.left[:, 2 * n: 2 * n + self.u.shape[1]] = self.z_left, self.u_left

    def start_from(self, x: np.ndarray) -> np.ndarray:
        """The solver's x interpolated linearly onto the points."""
        return np.stack([np.interp(self.tau, self.tau[:: 2 * self.s], x[:, i]) for i in range(x.shape[1])], axis=1)

    def refine(self, X: np.ndarray) -> np.ndarray:
        """A run on s/2 sub-intervals' points → this run's: its points are every other one,
        the rest from each coarse sub-interval's quadratic through (a, mid, b)."""
        out = np.empty((self.tau.size, X.shape[1]))
        out[::2] = X
        a, mid, b = X[:-1:2], X[1::2], X[2::2]
        out[1::4] = (3 * a + 6 * mid - b) / 8  # quadratic at 1/4
        out[3::4] = (-a + 6 * mid + 3 * b) / 8  # at 3/4
        return out

    def evaluate(self, X: np.ndarray):
        """P (the right limits at the continuation's jumps), ∂P/∂x, corner count, and P with
        the left limits at the jumps (each sub-interval's own end value)."""
        self.xi[:, : self.n] = X
        g, jac, corners = _nearest(self.functional, self.xi, jacobian=True)
        ends = g
        if self.jumps.size:
            self.left[:, : self.n] = X[self.jumps]
            ends = g.copy()
            ends[self.jumps] = _nearest(self.functional, self.left)[0]
        return g, jac, corners, ends

    def integrate(self, g: np.ndarray, ends: np.ndarray | None = None) -> np.ndarray:
        """∫_{τ_0}^{τ_i} of the piecewise quadratic through the values g at every point (each
        sub-interval's end value from `ends` where the integrand jumps there)."""
        g0, g1, g2 = g[:-1:2], g[1::2], (g if ends is None else ends)[2::2]
        H = self.H[:, None]
        ends = np.cumsum(H * (g0 + 4 * g1 + g2) / 6, axis=0)
        out = np.zeros_like(g)
        out[2::2] = ends
        out[1::2] = np.concatenate([np.zeros((1, g.shape[1])), ends[:-1]]) + H * (5 * g0 + 8 * g1 - g2) / 24
        return out

    def solve(self, x0: np.ndarray, X: np.ndarray, tol: float, max_sweeps: int):
        """Newton–Picard sweeps from X to X = x0 + C·P(X): (X, sweeps, last correction, corners)."""
        X = X.copy()
        X[0] = x0
        dt = np.diff(self.tau)
        corners, last, previous = 0, np.inf, np.inf
        for sweep in range(1, max_sweeps + 1):
            g, jac, c, ends = self.evaluate(X)
            corners = max(corners, c)
            residual = x0 + self.integrate(g, ends) - X
            # δ' = J δ + R' by backward Euler: (I − Δ_i J_{i+1}) δ_{i+1} − δ_i = R_{i+1} − R_i, δ_0 = 0
            delta = np.concatenate([np.zeros((1, self.n)), _backward_euler(dt, jac[1:], np.diff(residual, axis=0))])
            X += delta
            last = float(np.max(np.abs(delta)))
            if last <= tol * (1.0 + float(np.max(np.abs(X)))):
                break
            if sweep > 3 and last > previous:  # not contracting: no fixed point to this accuracy
                break
            previous = last
        return X, sweep, last, corners


def _backward_euler(dt: np.ndarray, jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """δ_1 … δ_K of (I − Δ_k J_k) δ_k − δ_{k−1} = rhs_k from δ_0 = 0, for all k at once: the
    block lower-bidiagonal system (blocks n × n: I − Δ_k J_k on the diagonal, −I below) is
    banded, lower bandwidth n and upper n − 1, and LAPACK's banded LU solves it in O(K·n²)."""
    K, n = rhs.shape
    upper = n - 1
    bands = np.zeros((2 * n, K * n))  # row upper + i − j holds entry (i, j) (scipy.linalg.solve_banded)
    blocks = np.eye(n)[None] - dt[:, None, None] * jac  # (K, n, n)
    a, b = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    columns = (np.arange(K)[:, None, None] * n + b[None]).ravel()
    bands[np.broadcast_to(upper + a - b, (K, n, n)).ravel(), columns] = blocks.ravel()
    bands[upper + n, : (K - 1) * n] = -1.0  # −I: entry (k·n + i, (k − 1)·n + i)
    return solve_banded((n, upper), bands, rhs.ravel(), check_finite=False).reshape(K, n)
