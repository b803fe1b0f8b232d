"""The starting iterates a solve chooses from: the model's own, the simulated motion, and
the straight line between the given ends (:func:`straight_line`, where the model's own ends
at a local minimum of I).

A friction model that a user writes has, by default, a constant start x ≡ x0, z ≡ 0; from
there semismooth Newton has to find every stick, slip and crossing itself, and on a
pendulum with pivot friction or a long stick-slip horizon it does not. Where the model's
sets are points apart from their sign terms, its true Filippov motion can be integrated
(:mod:`qdframe.certificates.filippov`) and sampled on the grid; a model with controls u is moved by its
first controls (``initial_controls``, u ≡ 0 by default), which the solve then changes:

- x(0) wholly given: the motion from x0 (an initial-value problem: that motion is the
  solution; with end conditions too, it is the start the conditions are then met from);
- some x_i(0) free: shooting, the free values chosen by least squares so that the motion
  meets the end and periodic conditions (scipy's least_squares, a few dozen motions).

:class:`Starts` offers both on any grid; a solve takes, per grid, the one with the lower
objective (the model's own where the model is better), and says which it took.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import least_squares

from ..certificates.filippov import MOVING, FilippovError, FilippovTrajectory, integrate
from ..certificates.model_system import model_system
from ..errors import ModelOutputError, QdframeError
from ..functional import Functional
from ..schemes.grid import Grid
from ..unknowns import Unknowns

MODEL, SIMULATED, LINE = "model", "simulated", "straight line"
SHOOTING_EVALUATIONS = 40  # motions integrated at most while shooting for free x(0) values
SIMULATION_TOL = 1e-10  # DOP853's rtol and atol for a start (the solve makes it exact)
SIMULATION_SECONDS = 20.0  # a shooting search stops after this long, with what it has
TURN_DENSITY = 16 / np.pi  # a first mesh from the motion: intervals per radian its velocity turns …
MIN_PER_PIECE = 4  # … and at least this many per piece of constant mode
TURN_SAMPLES = 257  # points per piece where the turning is measured
SWEEP_OCTAVES = 6  # a free T's first guess is sought in [T/2, T·2^k], k ≤ this, along the motion from x(0)
SWEEP_POINTS = 4001
SWEEP_TOL = 1e-9
SWEEP_NEAR = 1e-3  # misses within this (relative to |x|) of the least count as near-best
MODE_TIME_TOL = 1e-9  # relative to T: a point this near a mode change is sampled in the mode before it


class Starts:
    """The starts of one solve of `model`: the model's own, and its simulated motion where it
    has one (computed once, on first use, and sampled on every grid)."""

    def __init__(self, model, simulate: bool = True) -> None:
        self.model = model
        self.simulate = simulate
        self._motion: FilippovTrajectory | None = None
        self._tried = False
        self.note = ""  # why there is no simulated start

    def candidates(self, functional: Functional) -> list[tuple[str, np.ndarray]]:
        """(label, ξ) of each start on `functional`'s grid: the model's, then the simulated one."""
        out = [(MODEL, functional.initial_point())]
        motion = self.motion()
        if motion is not None:
            try:
                out.append((SIMULATED, sample(functional, motion)))
                if functional.grid.scheme.name == "implicit-euler":  # its discrete solution, step by step
                    out.append((SIMULATED, stepped(functional, motion(np.array([0.0]))[0])))
            except (QdframeError, np.linalg.LinAlgError, ValueError) as exc:
                self.note = f"no simulated start: {exc}"
        return out

    def best(self, functional: Functional) -> tuple[str, np.ndarray]:
        """The simulated start where there is one with a finite objective (it is the model's
        true motion: on a coarse grid its discretization residual may exceed a hand-made
        start's, but it has the solution's switches), else the model's. With controls the
        motion is only that of the first controls, which may run far from every solution (an
        unstable x' = 5x + u under u ≡ 0 grows by e^20 over T = 4): the lower objective wins."""
        candidates = self.candidates(functional)
        if functional.m:
            values = [_objective(functional, xi) for _, xi in candidates]
            return candidates[int(np.argmin(values))]
        for label, xi in reversed(candidates[1:]):
            try:
                if np.isfinite(functional.objective(xi)):
                    return label, xi
            except ModelOutputError:  # non-finite along the motion: the model's start (its errors are named there)
                continue
        return candidates[0]

    def motion(self) -> FilippovTrajectory | None:
        """The simulated motion (None: the model leaves a choice, or the simulation failed)."""
        if self.simulate and not self._tried:
            self._tried = True
            try:
                self._motion = simulate(Functional(self.model, Grid(self.model.T, 2, "implicit-euler")))
            except (QdframeError, np.linalg.LinAlgError, ValueError, OverflowError) as exc:  # NaN: the model's start
                self.note = f"no simulated start: {exc}"
        return self._motion

    def mesh(self, intervals: int) -> np.ndarray | None:
        """A first mesh for refinement from the motion (None without one): a point on every
        mode change, and in each piece of constant mode TURN_DENSITY intervals per radian
        that the motion's velocity turns (its states scaled to their ranges), at least
        MIN_PER_PIECE, and at least `intervals` in all. A swing of a spring-mass is π: 16
        intervals, where Radau IIA's discrete motion is near enough to the true one for
        semismooth Newton from it (8 were not, on stick-slip-oscillator)."""
        motion = self.motion()
        if motion is None:
            return None
        T = self.model.T
        edges = np.unique(np.concatenate([[0.0], np.asarray(motion.switch_times, dtype=float), [T]]))
        edges = edges[(edges >= 0.0) & (edges <= T)]
        fine = np.linspace(0.0, 1.0, TURN_SAMPLES)
        samples = [motion(a + (b - a) * fine) for a, b in zip(edges[:-1], edges[1:])]
        span = np.ptp(np.concatenate(samples), axis=0)
        scale = np.where(span > 0, span, 1.0)
        counts = np.array([max(MIN_PER_PIECE, int(np.ceil(TURN_DENSITY * _turning(x / scale)))) for x in samples])
        counts = np.maximum(counts, np.ceil(counts * intervals / counts.sum()).astype(int))
        return np.concatenate([np.linspace(a, b, k + 1)[:-1] for a, b, k in zip(edges[:-1], edges[1:], counts)] + [[T]])


class LineStarts(Starts):
    """The starts of a second run where the model's own ended at a local minimum of I: the
    straight line between the given ends (:func:`straight_line`) on every grid."""

    def __init__(self, model) -> None:
        super().__init__(model, simulate=False)

    def best(self, functional: Functional) -> tuple[str, np.ndarray]:
        line = straight_line(functional)
        return (LINE, line) if line is not None else super().best(functional)


def _objective(functional: Functional, xi: np.ndarray) -> float:
    """The objective at ξ, +inf where the model is non-finite there (the model's start then
    names it)."""
    try:
        value = functional.objective(xi)
    except ModelOutputError:
        return np.inf
    return float(value) if np.isfinite(value) else np.inf


def straight_line(functional: Functional) -> np.ndarray | None:
    """ξ of :func:`straight_guess` on `functional`'s grid (the model's controls); None where the
    model gives no end value. The second start where the model's own ends at a local minimum
    of I: paper-7.3's (the paper's x ≡ 0) stalls on its coarsest grid, where this one is
    solved (docs/paper.md has the figures)."""
    model = functional.model
    if not len(model.end_indices):
        return None
    t = functional.grid.t
    x, z = straight_guess(model, t)
    return functional.pack(x, z, np.asarray(model.initial_controls(t), dtype=float))


def straight_guess(model, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, z) at the times t: every state whose x_i(0) is given held at it (z_i = 0), and every
    state with an end value drawn straight from its start value to it (z its slope); the
    model's own guess elsewhere (a free x_i(0), a constant state)."""
    x, z = (np.array(part, dtype=float) for part in model.initial_guess(t))
    given = np.isfinite(model.x0)
    x[:, given], z[:, given] = model.x0[given], 0.0
    span = t[-1] - t[0]
    for j, value in zip(model.end_indices, model.end_values):
        x[:, j] = x[0, j] + (value - x[0, j]) * (t - t[0]) / span
        z[:, j] = (value - x[0, j]) / span
    return x, z


def _turning(x: np.ndarray) -> float:
    """The angle (radians) through which the velocity of the sampled path x (K, n) turns."""
    step = np.diff(x, axis=0)
    length = np.linalg.norm(step, axis=1)
    moving = step[length > 1e-12 * max(1.0, float(np.max(length, initial=0.0)))]
    if moving.shape[0] < 2:
        return 0.0
    unit = moving / np.linalg.norm(moving, axis=1)[:, None]
    return float(np.sum(np.arccos(np.clip(np.sum(unit[1:] * unit[:-1], axis=1), -1.0, 1.0))))


def simulate(functional: Functional) -> FilippovTrajectory | None:
    """The model's Filippov motion over [0, T] from x(0) (free values by shooting), under its
    first controls where it has controls; None where a set is not a point (the velocity is
    a choice) or the controls have a cost to minimize."""
    model = functional.model
    if functional.m and functional.cost is not None:  # the controls are the optimum's to choose: the motion
        return None                                    # under their first guess (at rest, often) starts nothing
    exact = functional if functional.signs == "exact" else Functional(model, functional.grid, signs="exact")
    controls = None
    if exact.m:  # the motion under the model's own first controls
        def controls(time: float) -> np.ndarray:
            return np.asarray(model.initial_controls(np.array([time])), dtype=float)[0]
    try:
        system = model_system(exact, controls)
    except FilippovError:  # a set that is not a point: the motion needs a choice
        return None
    given = exact.start_given
    x0 = np.where(given, np.nan_to_num(model.x0), exact.initial_point()[0, : exact.n])
    T = exact.grid.T
    if given.all() or (exact.end.size == 0 and exact.periodic.size == 0):
        return integrate(system, x0, T, SIMULATION_TOL, SIMULATION_TOL)
    free = np.flatnonzero(~given)
    clock = time.perf_counter()

    def misses(values: np.ndarray) -> np.ndarray:
        if time.perf_counter() - clock > SIMULATION_SECONDS:
            raise _OutOfTime
        start = x0.copy()
        start[free] = values
        end = integrate(system, start, T, SIMULATION_TOL, SIMULATION_TOL)(np.array([T]))[0]
        return np.concatenate([end[exact.end] - model.end_values, end[exact.periodic] - start[exact.periodic]])

    try:
        found = least_squares(misses, x0[free], max_nfev=SHOOTING_EVALUATIONS, xtol=1e-12, ftol=1e-12, gtol=1e-12)
        best = found.x
    except _OutOfTime:
        return None
    start = x0.copy()
    start[free] = best
    return integrate(system, start, T, SIMULATION_TOL, SIMULATION_TOL)


class _OutOfTime(Exception):
    pass


def sample(functional: Functional, motion: FilippovTrajectory) -> np.ndarray:
    """ξ on `functional`'s grid from a motion: x(t_k), z_k = its velocity g + B·λ in the mode
    of t_k, λ_k that mode's selections (the equivalent control while sliding). The model is
    evaluated at all nodes at once (:func:`qdframe.certificates.model_system.model_system` one point at a
    time is only for the integrator); nodes are grouped by mode for the small solves."""
    from ..functional.nearest import nearest

    t = functional.grid.t
    x = motion(t)
    exact = functional if functional.signs == "exact" else Functional(functional.model, functional.grid, signs="exact")
    n, p = exact.n, exact.p
    u = np.asarray(exact.model.initial_controls(t), dtype=float) if exact.m else None
    row = exact.pack(x, np.zeros_like(x), u, np.zeros((t.size, p)) if p else None)
    if p:
        row[:, 2 * n + exact.m:] = 0.0  # λ = 0: the sets without their sign terms
    g = nearest(exact, row)[0]  # the sets are points: z is irrelevant
    lam = np.zeros((t.size, p))
    if p:
        y = exact.arguments(row)
        B = np.zeros((t.size, n, p))
        for (b, term), k in zip(exact.sign_terms, exact.sign_columns):
            B[:, exact.blocks[b].coords[0], k] += term.sense * exact.pieces.amplitude_values(exact.blocks[b], term, y)
        s, ds = exact.switch_values(y)
        ds = ds[:, :, :n]
        starts = np.array([start for start, _ in motion.modes])
        # the mode before a change at t_k (to MODE_TIME_TOL): z_k belongs to the interval that ends at t_k
        near = MODE_TIME_TOL * max(1.0, float(t[-1]))
        which = np.clip(np.searchsorted(starts, t - near, side="left") - 1, 0, len(motion.modes) - 1)
        ball = np.zeros(p, dtype=bool)
        for first, width in exact.balls:
            ball[first : first + width] = True
        for index in np.unique(which):
            nodes = np.flatnonzero(which == index)
            mode = np.array(motion.modes[index][1], dtype=float)
            # a vector sign: s/|s| while it moves; stuck or leaving, its equivalent control (projected onto B)
            moving = ball & (mode == MOVING)
            mode[ball & ~moving] = 0.0
            lam[nodes] = mode
            for first, width in exact.balls:
                if moving[first]:
                    part = s[nodes, first : first + width]
                    radius = np.linalg.norm(part, axis=1)[:, None]
                    lam[nodes, first : first + width] = np.where(radius > 0, part / np.where(radius > 0, radius, 1.0),
                                                                 np.eye(width)[0])
            sliding = np.flatnonzero(mode == 0)
            if sliding.size:
                base = g[nodes] + np.einsum("nij,nj->ni", B[nodes], np.where(mode == 0, 0.0, lam[nodes]))
                grads = ds[nodes][:, sliding, :]  # (K, S, n)
                matrix = grads @ B[nodes][:, :, sliding]  # (K, S, S)
                rhs = -np.einsum("ksn,kn->ks", grads, base)[..., None]
                lam[np.ix_(nodes, sliding)] = np.linalg.solve(matrix, rhs)[..., 0]
                lam[nodes] = exact.project(lam[nodes])
        z = g + np.einsum("nij,nj->ni", B, lam)
    else:
        z = g
    return functional.pack(x, z, None, lam if functional.p else None)



def stepped(functional: Functional, x0: np.ndarray) -> np.ndarray:
    """ξ on an implicit-Euler grid from the simulator's steps on its very points
    (:func:`qdframe.simulate.simulate_on`): the discrete solution of an initial-value
    problem whose model leaves no choice, so that the solve has only to confirm it."""
    from ..simulate import simulate_on

    run = simulate_on(functional.model, functional.grid.t, x0)
    z = np.concatenate([run.z[:1], run.z[:-1]])  # z_k of the step that ends at t_k (implicit Euler's)
    lam = None
    if functional.p and run.selections is not None:
        lam = np.concatenate([run.selections[:1], run.selections[:-1]])
    return functional.pack(run.x, z, None, lam)


def swept_T(wrapper: Unknowns) -> float:
    """A better first T of a model with T free where x(0) is given (the start of its solve):
    the first of :func:`swept_candidates`, or the guess where there is none."""
    found = swept_candidates(wrapper)
    return found[0] if found else wrapper.T0


def swept_candidates(wrapper: Unknowns) -> list[float]:
    """The first T's worth trying for a model with T free where x(0) is given: the motion from
    x(0) with the guessed p, integrated once over [T/2^k, T·2^k] ([T/2, T·2^k] for a period),
    and the T's there that miss the end and periodic conditions least (each stretch of
    near-best T's gives its best), nearest to the guess first; k = 1, 2, … up to
    SWEEP_OCTAVES until one misses by less than SWEEP_NEAR·max(1, |x|). A guess of a period
    a quarter off can sit where the misses are stationary (a corner of the relay's orbit), and
    shooting from there does not move; a period has several (every half-period where a
    velocity alone is periodic), which :func:`qdframe.solve.solving` tries in turn. Empty where
    there are no conditions or the motion fails."""
    if not wrapper.end_indices and not wrapper.periodic:
        return []
    best: list[float] = []
    for octave in range(1, SWEEP_OCTAVES + 1):
        # an end condition: downwards too (a stop before the guess); a period: not towards T = 0,
        # where a constant x is periodic
        lowest = wrapper.T0 / 2 if wrapper.periodic else wrapper.T0 / 2.0**octave
        found = _swept(wrapper, lowest, wrapper.T0 * 2.0**octave)
        if found is None:
            return best
        best, near = found
        if near:
            break
    return best

def _swept(wrapper: Unknowns, lo: float, hi: float) -> tuple[list[float], bool] | None:
    """(the best T of each stretch of near-best T's in [lo, hi], nearest to the guess first;
    whether they nearly meet the conditions), or None."""
    lo = max(lo, wrapper.time_bound.lo * (1 + 1e-9) + 1e-300)
    hi = min(hi, wrapper.time_bound.hi * (1 - 1e-9))
    start = [*wrapper.inner.x0, *(bound.inverse(p) for bound, p in zip(wrapper.bounds, wrapper.inner.parameters)),
             wrapper.time_bound.inverse(hi)]
    try:
        motion = integrate(model_system(Functional(wrapper, Grid(1.0, 2, "implicit-euler"))), start, 1.0,
                           SWEEP_TOL, SWEEP_TOL)
    except (QdframeError, FilippovError, np.linalg.LinAlgError, ValueError, OverflowError):
        return None
    s = np.linspace(lo / hi, 1.0, SWEEP_POINTS)
    X = motion(s)[:, : wrapper.n]
    end, periodic = list(wrapper.end_indices), list(wrapper.periodic)
    misses = np.concatenate([X[:, end] - wrapper.end_values, X[:, periodic] - wrapper.inner.x0[periodic]], axis=1)
    size = np.linalg.norm(misses, axis=1)
    if not np.all(np.isfinite(size)):
        return None
    scale = SWEEP_NEAR * max(1.0, float(np.max(np.abs(X))))
    near = size <= size.min() + scale
    times = s * hi
    edges = np.flatnonzero(np.diff(np.concatenate([[0], near.astype(int), [0]])))  # each stretch's first and past-last
    stretches = [np.arange(start, stop) for start, stop in zip(edges[::2], edges[1::2])]
    # in a stretch, the T nearest to the guess (the misses there are all near-best)
    found = [float(times[k][np.argmin(np.abs(np.log(times[k] / wrapper.T0)))]) for k in stretches]
    return sorted(found, key=lambda T: abs(np.log(T / wrapper.T0))), bool(size.min() <= scale)
