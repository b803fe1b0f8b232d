"""The one yardstick of `qdframe bench run`: a trajectory's error against a reference.

Every row, qdframe's and each peer's, is judged here from its own time grid t, states x,
velocities z (and controls u), never from the solver's own residuals. The reference is one
of three kinds:

* ``exact`` — the model's closed-form solution (``model.exact_solution``; its
  ``switch_times``), where the problem has exactly one solution. Once per sweep it is
  cross-checked against an independent integrator (:func:`~.problems.reference`: DOP853,
  rtol = atol = 1e-12, one event per switching function, sliding by its equivalent control)
  where that integrator can state the model; report.md gives the discrepancy.
* ``events replay`` — a problem whose solutions form a set (a bounded input to choose)
  and that :mod:`.replay_statements` can state with an input: the true Filippov motion from the
  trajectory's x(0) driven by the input recovered from the trajectory itself (the peer's
  own input where it has one), integrated with event location.
* ``projection replay`` — any other problem without a unique solution: the true motion
  x_ref' = P_F(x_ref)(z(t)) that Filippov's theorem builds from the trajectory
  (:func:`~.replay.replay`).

Measures (max norms over states):

* ``error`` — max over the trajectory's own grid of |x(t_k) − x_ref(t_k)|; for a replay,
  the larger of that and ``end_miss``, how far the true motion misses the boundary
  conditions (a trajectory near a motion that misses them is near no solution);
* ``end_error`` — |x(T) − x_ref(T)| (exact), or the replay's ``end_miss``;
* ``switch_error`` — the largest distance from a known switch time to the nearest switch
  time the solver reported (None where the model has none or the solver reports none).
"""

from __future__ import annotations

import bisect
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..certificates.filippov import FilippovError, integrate
from ..model import InclusionModel
from . import problems

EXACT, EVENTS, PROJECTION = "exact", "events replay", "projection replay"


@dataclass(frozen=True)
class Judgement:
    """A trajectory judged against its reference."""

    error: float | None
    distance: float | None  # max |x − x_ref| alone (for a replay, error also counts the end miss)
    end_error: float | None
    switch_error: float | None
    kind: str
    uncertainty: float | None  # the reference's own accuracy where it is not a closed form
    seconds: float  # time spent making the reference for this row
    recipe: str


def kind(model: InclusionModel) -> str:
    """Which reference judges `model`'s rows."""
    if model.exact_solution(np.array([0.0, model.T])) is not None:
        return EXACT
    if problems.recovers_inputs(model):
        return EVENTS
    return PROJECTION


def judge(
    model: InclusionModel,
    t: np.ndarray,
    x: np.ndarray,
    z: np.ndarray,
    u: np.ndarray | None = None,
    switch_times: Sequence[float] | None = None,
    inputs: Callable[[float], np.ndarray] | None = None,
    velocity: Continuation | None = None,
    selections: np.ndarray | None = None,
) -> Judgement:
    """Judge the trajectory (t, x, z, u) of `model`. For an events replay, `inputs` is the
    peer's own input u(t); else the input is recovered at the points t from the trajectory
    (the catalogue's input recovery, :mod:`.problems`, from the trajectory's own `selections` λ (N, p) where it has them) and
    continued between them by `velocity` (a :data:`Continuation`: the scheme's own rule for
    x', :class:`SchemeRule`; default piecewise linear).
    Where the trajectory leaves its input undetermined at some points (a recoverer returns
    several admissible candidates), each is replayed and the nearest true motion is the
    reference: any admissible input whose motion is that near proves the distance."""
    start = time.perf_counter()
    t, x, z = np.asarray(t, float), np.asarray(x, float), np.asarray(z, float)
    which = kind(model)
    if which == EXACT:
        exact = np.asarray(model.exact_solution(t), float)
        error = float(np.max(np.abs(x - exact)))
        end = float(np.max(np.abs(x[-1] - exact[-1])))
        return Judgement(error, error, end, _switch_error(model, switch_times), EXACT, None,
                         time.perf_counter() - start, "the model's closed-form solution at the trajectory's own times")
    if which == EVENTS:
        best = None
        recovered = [] if inputs is not None else problems.recovered_inputs(model, x, z, u, selections)
        recovered = [recovered] if isinstance(recovered, np.ndarray) else list(recovered)
        drives = ([("the peer's own input", inputs)] if inputs is not None else
                  [(label, _Drive(rule, values, breaks)) for label, rule, breaks in continuations(t, velocity)
                   for values in recovered])
        for label, drive in drives:
            try:
                reference = integrate(problems.statement(model, drive), x[0], float(t[-1]))(t)
            except FilippovError as exc:
                if best is None and label == "linear":
                    raise
                last = exc
                continue
            miss = end_miss(model, reference)
            error = float(np.max(np.abs(x - reference)))
            if best is None or (max(error, miss), error) < (max(best[0], best[1]), best[0]):  # ties: the nearer
                best = (error, miss, label)
        if best is None:
            raise last
        error, miss, label = best
        recipe = ("the true Filippov motion from the trajectory's x(0) driven by "
                  + ("the peer's own input" if inputs is not None else
                     f"the input recovered from the trajectory, continued between its points by {label}")
                  + ", DOP853 rtol = atol = 1e-12 with event location")
        return Judgement(max(error, miss), error, miss, _switch_error(model, switch_times), EVENTS, None,
                         time.perf_counter() - start, recipe)
    from ..certificates.projection_replay import replay

    runs = [(label, replay(model, t, x, z, u, continuation=None if label == "linear" else rule))
            for label, rule, _ in continuations(t, velocity)]
    label, result = min(runs, key=lambda run: max(run[1].error, run[1].end_miss))
    return Judgement(max(result.error, result.end_miss), result.error, result.end_miss, _switch_error(model, switch_times),
                     PROJECTION, result.uncertainty, time.perf_counter() - start,
                     f"{result.recipe}; z and u continued between the points by {label}")


Continuation = Callable[[np.ndarray, np.ndarray], np.ndarray]  # (values at t (N, k), times (M,)) -> (M, k)


def continuations(t: np.ndarray, velocity: Continuation | None = None) -> list[tuple[str, Continuation, tuple[float, ...]]]:
    """The ways to continue a trajectory's velocities (and inputs) between its points t, each a
    true motion's input when replayed; the judge takes the one whose motion is nearest (every one
    is a genuine motion of the inclusion, so the nearest bounds the distance to the solution set):

    - "the Radau IIA rule" where the points are a Radau IIA layout (a stage at a third of every
      interval: qdframe's accuracy-refined trajectories), the polynomial through each interval's
      stages (:meth:`~qdframe.schemes.base.Scheme.velocity`), jumps at the mesh points;
    - "the implicit Euler rule": constant on (t_{k−1}, t_k] at the value of t_k, jumps at every point;
    - "linear" interpolation through the points.

    `velocity` (a :data:`Continuation`, e.g. :class:`SchemeRule`) replaces the first two: the
    caller's own rule.
    """
    from ..schemes import radau

    t = np.asarray(t, dtype=float)
    out: list[tuple[str, Continuation, tuple[float, ...]]] = []
    linear = _LinearRule(t)
    if velocity is not None:
        out.append(("the caller's rule", velocity, tuple(t[1:-1])))
        return out + [("linear", linear, ())]
    mesh = np.arange(0, t.size, 2)
    if t.size >= 3 and t.size % 2 == 1 and np.allclose(t[1::2], t[:-1:2] + np.diff(t[::2]) / 3.0, rtol=0.0,
                                                       atol=1e-12 * max(1.0, abs(t[-1]))):
        out.append(("the Radau IIA rule", SchemeRule(radau.RadauIIA(), t, mesh), tuple(t[2:-1:2])))
    else:
        def backward(values: np.ndarray, times: np.ndarray) -> np.ndarray:
            return values[np.clip(np.searchsorted(t, times, side="left"), 0, t.size - 1)]

        out.append(("the implicit Euler rule", backward, tuple(t[1:-1])))
    return out + [("linear", linear, ())]


def _linear(t: np.ndarray, values: np.ndarray, times: np.ndarray) -> np.ndarray:
    values = np.asarray(values, dtype=float).reshape(t.size, -1)
    return np.stack([np.interp(times, t, column) for column in values.T], axis=1)


class _LinearRule:
    """Linear interpolation through the points t as a :data:`Continuation`, with `point`."""

    def __init__(self, t: np.ndarray) -> None:
        self.t, self.times = t, t.tolist()

    def __call__(self, values: np.ndarray, times: np.ndarray) -> np.ndarray:
        return _linear(self.t, values, times)

    def point(self, values: np.ndarray) -> Callable[[float], np.ndarray]:
        values = np.asarray(values, dtype=float).reshape(self.t.size, -1)
        times = self.times

        def at(s: float) -> np.ndarray:  # np.interp's value, clamped at the ends, in O(log N)
            k = min(max(bisect.bisect_right(times, s) - 1, 0), len(times) - 2)
            w = min(max((s - times[k]) / (times[k + 1] - times[k]), 0.0), 1.0)
            return values[k] + w * (values[k + 1] - values[k])

        return at


class SchemeRule:
    """A scheme's rule for x' on the points t (mesh: the mesh points' indices) as a
    :data:`Continuation`, with `point(values)` for one time at a time in O(log N)."""

    def __init__(self, scheme, t: np.ndarray, mesh: np.ndarray) -> None:
        from ..certificates.estimates import PointRule
        from ..schemes.grid import Grid

        self.scheme, self.t, self.mesh = scheme, t, mesh
        self.grid, self.rule = Grid.from_mesh(t[mesh], scheme), PointRule

    def __call__(self, values: np.ndarray, times: np.ndarray) -> np.ndarray:
        return self.scheme.velocity(self.t, self.mesh, values, times)

    def point(self, values: np.ndarray) -> Callable[[float], np.ndarray]:
        return self.rule(self.grid, values)


class _Drive:
    """An input u(s) continued by a rule from its values at the points, with the rule's jumps as `breaks`.
    The integrator asks for one time at a time: a rule with `point` answers in O(log N)."""

    def __init__(self, rule: Continuation, values: np.ndarray, breaks: tuple[float, ...]) -> None:
        self.rule, self.values, self.breaks = rule, np.atleast_2d(np.asarray(values, float).T).T, breaks
        self.one = rule.point(self.values) if hasattr(rule, "point") else None

    def __call__(self, s: float) -> np.ndarray:
        if self.one is not None:
            return np.atleast_1d(np.asarray(self.one(s), dtype=float))
        return self.rule(self.values, np.array([s]))[0]


def end_miss(model: InclusionModel, x: np.ndarray) -> float:
    """How far the states x (on [0, T]) miss the model's end and periodic conditions."""
    gaps = [0.0]
    ends = np.asarray(model.end_indices, dtype=int)
    if ends.size:
        gaps.append(float(np.max(np.abs(x[-1, ends] - np.asarray(model.end_values, float)))))
    periodic = np.asarray(getattr(model, "periodic", ()), dtype=int)
    if periodic.size:
        gaps.append(float(np.max(np.abs(x[-1, periodic] - x[0, periodic]))))
    return max(gaps)


def _switch_error(model: InclusionModel, found: Sequence[float] | None) -> float | None:
    known = np.asarray(getattr(type(model), "switch_times", ()) or (), float)
    if known.size == 0 or found is None or len(found) == 0:
        return None
    found = np.asarray(found, float)
    return float(np.max(np.min(np.abs(known[:, None] - found[None, :]), axis=1)))


# ------------------------------------------------------------------ inputs from a trajectory


def _interpolated(t: np.ndarray, values: np.ndarray) -> Callable[[float], np.ndarray]:
    """u(s) piecewise linear through (t_k, values_k), held constant outside [t_0, t_end]."""
    values = np.atleast_2d(np.asarray(values, float).T).T

    def drive(s: float) -> np.ndarray:
        return np.array([np.interp(s, t, column) for column in values.T])

    return drive




# ------------------------------------------------------------------ recipes for the report


@lru_cache(maxsize=None)
def cross_check(name: str) -> str:
    """How `name`'s reference was made, with its independent cross-check where there is one."""
    from ..registry import load_model

    model = load_model(name)
    which = kind(model)
    if which == EVENTS:
        return (f"{EVENTS}: per row, the true Filippov motion from the row's x(0) driven by its input "
                f"(recovered from the row's z, or the peer's own), DOP853 rtol = atol = 1e-12 with event location; "
                f"error includes how far that motion misses the end conditions")
    if which == PROJECTION:
        return (f"{PROJECTION}: per row, the true motion x' = P_F(x)(z(t)) from the row's x(0) (Filippov's "
                f"theorem), see the row's reference uncertainty; error includes how far it misses the end conditions")
    start = time.perf_counter()
    try:
        motion = problems.reference(model)
    except Exception as exc:  # an integrator failure is reported, not fatal
        return f"{EXACT}: closed form (cross-check failed: {type(exc).__name__}: {exc})"
    if motion is None and callable(getattr(model, "equations", None)):  # models.user_friction's
        return (f"{EXACT}: the model's own hand-written equations x' ∈ g + B·Sgn(s), integrated by the "
                f"event-driven Filippov integrator (DOP853, rtol = atol = 1e-12); no second statement")
    if motion is None:
        return f"{EXACT}: closed form (no independent statement for the event integrator)"
    t = np.linspace(0.0, model.T, 2001)
    gap = float(np.max(np.abs(motion(t) - model.exact_solution(t))))
    return (f"{EXACT}: closed form; DOP853 with event location (rtol = atol = 1e-12) agrees to {gap:.1e} "
            f"on 2001 times ({time.perf_counter() - start:.2f} s)")
