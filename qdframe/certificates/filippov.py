"""Event-driven Filippov integration: the true motion of a system with sign terms.

It solves

    x' ∈ g(t, x) + B(t, x)·Sgn(s(t, x)),      s: k switching functions, B: (n, k),

with scipy's DOP853 between events (rtol = atol = 1e-12 by default), the selection
λ_i ∈ Sgn(s_i) of each switch given by its *mode* m_i: +1 (s_i > 0, λ_i = +1), −1 (λ_i = −1)
or 0 (sliding or sticking on s_i = 0). On the sliding set S the selections are the
equivalent control, the solution of

    (∇s_S·B_S)·λ_S = −∇s_S·(g + B_{¬S}·m_{¬S}),

which keeps every ds_i/dt = 0 (i ∈ S). A piece ends at a terminal event: an s_i (i ∉ S)
reaching 0 from its side, or a sliding |λ_i| reaching 1, or a break of the drift in t
(an input's jump). There the new mode of the switches at the surface is chosen among
{+1, −1, 0} for each: a mode is consistent when its λ_S lie in [−1, 1] and every
other switch at the surface moves to its own side (m_i·ds_i/dt ≥ 0). Both are measured
in λ units (ds_i/dt divided by |∇s_i·B_i|), so that at a transversal crossing or an
attractive surface exactly one mode has a non-negative margin (Filippov's rule: attractive
→ slide, transversal → cross); the mode of largest smallest margin is taken. The switches
fall into groups that do not move each other's s, each decided apart (:func:`choose_mode`:
enumerated where small, a box LCP where large), so the choice grows with the groups' sizes,
not as 3^k. The scalar switches share one crossing and one release event per piece.

A vector sign (isotropic friction, `balls`: k consecutive switches s ∈ R^k with one
selection vector λ ∈ B) has two regimes: MOVING, λ = s/|s|, and stuck (mode 0) on s = 0 with
λ the equivalent control, which the same linear solve gives; it stops where s reaches 0
along a line, breaks away where |λ_eq| reaches 1 and leaves in the quasi-static direction
(:func:`quasi_static`), consistent with s/|s| to first order in the time since.

:func:`qdframe.certificates.model_system.model_system` states a qdframe model in this form (its equations and sets as the
drift, its sign terms as B and s, the sets' choice and the controls as inputs of time);
the error certificate by replay (:mod:`qdframe.certificates.estimates`), the default start of a solve
and the benchmark's references use it.
"""

from __future__ import annotations

import bisect
import functools
import itertools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import OdeSolution, solve_ivp
from scipy.sparse.csgraph import connected_components

from .complementarity import box_lcp, labels
from ..errors import QdframeError

SURFACE_TOL = 1e-11  # |s_i| at most this (relative to max(1, |x|)): switch i is at its surface
MARGIN_TOL = 1e-9  # a mode is consistent when every margin (λ units) is ≥ −MARGIN_TOL
MAX_EVENTS = 100_000  # mode changes and events, beyond the declared breaks
MAX_STALLS = 20  # consecutive events without progress in t before giving up (Zeno, chattering)


class FilippovError(QdframeError):
    """The integration cannot continue: no consistent mode, an ODE failure, or no progress."""


@dataclass(frozen=True)
class Fields:
    """The system at one (t, x): drift g (n,), B (n, k), switches s (k,) and ∇_x s (k, n)."""

    g: np.ndarray
    B: np.ndarray
    s: np.ndarray
    ds: np.ndarray


@dataclass(frozen=True)
class FilippovSystem:
    """x' ∈ g(t, x) + B(t, x)·Sgn(s(t, x)), evaluated by `fields(t, x)`.

    `names`: one per switch; `breaks`: times where the drift is not smooth in t (an
    input's jumps), where the integrator ends a piece and chooses the mode afresh; `balls`:
    the vector signs Sgn(s), s ∈ R^k (isotropic friction: λ = s/|s| for s ≠ 0, |λ| ≤ 1 at
    s = 0), each (its first switch, k) over k consecutive switches and columns of B.
    """

    fields: Callable[[float, np.ndarray], Fields]
    names: tuple[str, ...]
    name: str = ""
    breaks: tuple[float, ...] = ()
    balls: tuple[tuple[int, int], ...] = ()  # vector signs: (first switch, k), their k switches s ∈ R^k consecutive

    @property
    def switch_count(self) -> int:
        return len(self.names)


@dataclass
class FilippovTrajectory:
    """The integrated motion: DOP853 dense outputs of the pieces between events.

    `switch_times`: the times the mode changed (entering or leaving sliding, crossing);
    `modes`: (start time, mode) of every mode taken, the first at t0.
    """

    starts: np.ndarray  # (P,) start time of each piece
    pieces: list[OdeSolution]
    switch_times: tuple[float, ...]
    modes: list[tuple[float, tuple[int, ...]]]
    T: float
    events: int = 0  # terminal events met (mode changes, re-choices, breaks)
    seconds: float = field(default=0.0, compare=False)
    steps: int = 0  # accepted steps over all pieces
    one_step: bool = False  # every piece one accepted DOP853 step (a polynomial motion between an input's kinks)
    halted: float | None = None  # where `integrate` was told to stop before T

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """x(t), (K, n), for the times t (K,): each time from the piece containing it."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        which = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.pieces) - 1)
        n = np.atleast_1d(self.pieces[0](self.starts[0])).size
        out = np.empty((t.size, n))
        order = np.argsort(which, kind="stable")  # the times of each piece together: O(K log K), not O(K·pieces)
        pieces, first = np.unique(which[order], return_index=True)
        for index, chosen in zip(pieces, np.split(order, first[1:])):
            out[chosen] = np.atleast_2d(self.pieces[index](t[chosen])).T
        return out


class _Cached:
    """`fields` with a one-entry memory: DOP853's last stage and the events ask for the same point."""

    def __init__(self, system: FilippovSystem) -> None:
        self.system = system
        self.key: tuple | None = None
        self.value: Fields | None = None
        self.calls = 0

    def __call__(self, t: float, x: np.ndarray) -> Fields:
        key = (float(t), np.asarray(x, dtype=float).tobytes())
        if key != self.key:
            self.value = self.system.fields(float(t), np.asarray(x, dtype=float))
            self.key = key
            self.calls += 1
        return self.value  # type: ignore[return-value]


# ----------------------------------------------------------------- modes and fields
def velocity(fields: Fields, mode: Sequence[int], balls: Sequence[tuple[int, int]] = (),
             aims: dict[int, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """x' = g + B·λ in `mode` and the selections λ (k,): m_i off the surface, the
    equivalent control on it. Raises numpy.linalg.LinAlgError when ∇s_S·B_S is singular.

    A vector sign (`balls`: (first switch, dimension) of each) takes λ = s/|s| while it moves
    (mode MOVING; its aim, the direction last taken, where s = 0 exactly), the equivalent
    control while stuck (0), and the quasi-static direction (:func:`quasi_static`) while it
    leaves s = 0 (LEAVING)."""
    return _solve_mode(fields, mode, balls, aims)[:2]


MOVING, LEAVING = 2, 3  # a vector sign's mode (on each of its columns): λ = s/|s|, and leaving s = 0; 0: stuck
RELEASE_RADIUS = 1e-7  # a leaving vector sign moves by s/|s| once |s| ≥ this·max(1, |x|) (quasi-static before)
STIFF_RADIUS = 1e-3  # a vector sign that moves from |s| below this·max(1, |x|): the piece is stiff (_method)
# a moving vector sign whose |s| falls to REACH_ATOLS·atol (at most STOP_TOL/2, relative to max(1, |x|))
# is at a stop, which the mode choice confirms or not: below a few atol DOP853's steps no longer
# follow s/|s| and can circle s = 0 without ⟨s, aim⟩ ever reaching 0 (an elliptic puck at rtol =
# atol = 1e-12 on an AVX-512 CPU: |s| ≈ 5e-12 for ever, steps of 1e-15 s)
REACH_ATOLS = 100.0
STOP_TOL = 1e-8  # a moving vector sign's ⟨s, aim⟩ = 0 with |s| ≤ this·max(1, |x|) is a stop (else a new aim)


def _solve_mode(fields: Fields, mode: Sequence[int], balls: Sequence[tuple[int, int]],
                aims: dict[int, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray, dict[int, np.ndarray]]:
    """:func:`velocity`, and each stuck or leaving vector sign's equivalent control λ_eq (its
    first switch: λ_eq), the selection that would keep its s at 0."""
    if not balls:  # scalar signs alone: the same numbers with the mode's layout made once
        fixed, sliding = _scalar_layout(tuple(mode))
        base = fields.g + fields.B @ fixed
        if not sliding:
            return base, fixed.copy(), {}
        lam = fixed.copy()
        grads = fields.ds[sliding]
        lam[sliding] = _solved(grads @ fields.B[:, sliding], -(grads @ base))
        return base + fields.B[:, sliding] @ lam[sliding], lam, {}
    lam = np.array(mode, dtype=float)
    ball_of = {a + j: (a, k) for a, k in balls for j in range(k)}
    sliding = [i for i, m in enumerate(mode) if m == 0 or (i in ball_of and m == LEAVING)]
    for a, k in balls:
        if mode[a] == MOVING:
            part = fields.s[a : a + k]
            radius = float(np.linalg.norm(part))
            lam[a : a + k] = part / radius if radius > 0 else (aims or {}).get(a, np.eye(k)[0])
        elif mode[a] == LEAVING:
            lam[a : a + k] = 0.0
    base = fields.g + fields.B @ _without(lam, sliding)
    equivalent: dict[int, np.ndarray] = {}
    if sliding:
        grads = fields.ds[sliding]
        lam[sliding] = _solved(grads @ fields.B[:, sliding], -(grads @ base))
        leaving = [(a, k) for a, k in balls if mode[a] == LEAVING]
        for a, k in balls:
            if mode[a] in (0, LEAVING):
                equivalent[a] = lam[a : a + k].copy()
        if leaving:  # the leaving signs at their quasi-static direction, the other sliding switches again
            for a, k in leaving:
                response = fields.ds[a : a + k] @ fields.B[:, a : a + k]
                lam[a : a + k] = quasi_static(response, equivalent[a])
            fixed = [i for i in sliding if not (i in ball_of and mode[ball_of[i][0]] == LEAVING)]
            base = fields.g + fields.B @ _without(lam, fixed)
            if fixed:
                grads = fields.ds[fixed]
                lam[fixed] = _solved(grads @ fields.B[:, fixed], -(grads @ base))
            return base + fields.B[:, fixed] @ lam[fixed], lam, equivalent
        base = base + fields.B[:, sliding] @ lam[sliding]
    return base, lam, equivalent


@functools.lru_cache(maxsize=4096)
def _scalar_layout(mode: tuple[int, ...]) -> tuple[np.ndarray, list[int]]:
    """λ of a mode of scalar switches with its sliding ones at 0, and those sliding ones."""
    sliding = [i for i, m in enumerate(mode) if m == 0]
    fixed = np.array(mode, dtype=float)
    fixed[sliding] = 0.0
    fixed.flags.writeable = False
    return fixed, sliding


def _solved(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """matrix⁻¹·rhs: one sliding switch (1 × 1) by a division (np.linalg.solve costs ~20 µs a
    call at this size, and the event integrator asks once per right-hand side), else LAPACK.
    Raises numpy.linalg.LinAlgError where the matrix is singular, as np.linalg.solve does."""
    if matrix.shape == (1, 1):
        if matrix[0, 0] == 0.0 or not np.isfinite(matrix[0, 0]):
            raise np.linalg.LinAlgError("Singular matrix")
        return rhs / matrix[0, 0]
    return np.linalg.solve(matrix, rhs)


def _without(lam: np.ndarray, columns: Sequence[int]) -> np.ndarray:
    """λ with the entries `columns` set to 0 (a few, one point at a time: no np.isin)."""
    out = lam.copy()
    out[list(columns)] = 0.0
    return out


def quasi_static(response: np.ndarray, equivalent: np.ndarray) -> np.ndarray:
    """The direction λ (|λ| = 1) in which a vector sign leaves s = 0: with A = ∇s·B (k×k) and
    λ_eq the equivalent control (|λ_eq| ≥ 1), s' = A·(λ − λ_eq) must grow along λ itself,
    A·(λ − λ_eq) = κ·λ with κ ≥ 0, so λ = (A − κI)⁻¹·A·λ_eq with |λ| = 1. It agrees with the
    true s/|s| to first order in the time since the break-away (isotropic friction, A = −μI:
    λ = λ_eq/|λ_eq|). κ by bisection on |λ(κ)| = 1 (decreasing in κ for a dissipative A);
    λ_eq/|λ_eq| where that fails."""
    size = float(np.linalg.norm(equivalent))
    fallback = equivalent / size if size > 0 else np.eye(equivalent.size)[0]
    if size <= 1.0:
        return equivalent if size == 1.0 else fallback
    target = response @ equivalent
    identity = np.eye(equivalent.size)

    def direction(kappa: float) -> np.ndarray:
        return np.linalg.solve(response - kappa * identity, target)

    try:
        low, high = 0.0, max(1.0, float(np.max(np.abs(response))))
        for _ in range(200):
            if np.linalg.norm(direction(high)) < 1.0:
                break
            high *= 2.0
        else:
            return fallback
        for _ in range(200):
            middle = 0.5 * (low + high)
            if middle in (low, high):
                break
            if np.linalg.norm(direction(middle)) > 1.0:
                low = middle
            else:
                high = middle
        found = direction(0.5 * (low + high))
    except np.linalg.LinAlgError:
        return fallback
    norm = float(np.linalg.norm(found))
    return found / norm if np.isfinite(norm) and norm > 0 else fallback


def _margins(fields: Fields, mode: tuple[int, ...], at: Sequence[int], balls: Sequence[tuple[int, int]] = (),
             aims: dict[int, np.ndarray] | None = None) -> np.ndarray:
    """For the switches `at` the surface, in λ units: 1 − |λ_i| when sliding,
    m_i·(ds_i/dt)/|∇s_i·B_i| when moving (≥ 0 means consistent). A vector sign at the surface
    (its first switch in `at`): 1 − |λ_eq| when stuck, |λ_eq| − 1 when leaving."""
    try:
        f, lam, equivalent = _solve_mode(fields, mode, balls, aims)
    except np.linalg.LinAlgError:
        return np.array([-np.inf])
    firsts = {a for a, _ in balls}
    inner = {a + j for a, k in balls for j in range(1, k)}
    out = []
    for i in at:
        if i in inner:
            continue
        if i in firsts:
            size = float(np.linalg.norm(equivalent[i])) if i in equivalent else 1.0
            out.append(1.0 - size if mode[i] == 0 else size - 1.0)
            continue
        if mode[i] == 0:
            out.append(1.0 - abs(lam[i]))
            continue
        grad = fields.ds[i]
        scale = abs(grad @ fields.B[:, i])
        out.append(mode[i] * (grad @ f) / (scale if scale > 1e-14 else 1.0))
    return np.array(out)


def choose_mode(fields: Fields, x: np.ndarray, current: tuple[int, ...] | None = None, crossed: int | None = None,
                released: tuple[int, int] | None = None, name: str = "", t: float = 0.0,
                balls: Sequence[tuple[int, int]] = (), aims: dict[int, np.ndarray] | None = None) -> tuple[int, ...]:
    """The Filippov mode at a point: of the modes {0, +1, −1} of the switches at their surface
    (|s_i| ≤ SURFACE_TOL·max(1, |x|), sliding in `current`, or the `crossed` one), the
    consistent ones (every margin ≥ −MARGIN_TOL), the one of largest smallest margin, the
    first in the order (0, +1, −1) of the switches where several are. `crossed`: switch i
    reached s_i = 0 from side current[i], which it cannot keep; `released`: (i, ±1), sliding
    switch i's λ reached ±1: it leaves to that side.

    A vector sign (`balls`, indexed by its first switch) is at its surface where |s| ≤
    SURFACE_TOL·max(1, |x|) (or stuck in `current`, or `crossed`: it stopped); there it is
    stuck (0) or LEAVING, elsewhere MOVING; `released` = (a, LEAVING) when its |λ_eq| reached 1.

    The switches at their surface fall into groups that do not move each other's s (no entry
    of ∇s·B between two groups): each group is decided on its own, so k independent blocks
    cost 3k margin checks, not 3^k. A group of at most ENUMERATED modes is enumerated; a
    larger group of scalar sign terms is solved as a box LCP (:mod:`qdframe.certificates.complementarity`),
    and the switches whose margin there is within AMBIGUOUS of 0 are enumerated around it."""
    near = SURFACE_TOL * max(1.0, float(np.max(np.abs(x), initial=0.0)))
    ball_of = {a + j: (a, k) for a, k in balls for j in range(k)}
    at = {i for i, c in enumerate(fields.s) if i not in ball_of and abs(c) <= near}
    at |= {a for a, k in balls if float(np.linalg.norm(fields.s[a : a + k])) <= near}
    if current is not None:
        at |= {i for i, m in enumerate(current) if m == 0 and (i not in ball_of or ball_of[i][0] == i)}
    at |= {i for i in (crossed, None if released is None else released[0]) if i is not None}
    fixed = [1 if c > 0 else -1 for c in fields.s]
    for a, k in balls:
        fixed[a : a + k] = [MOVING] * k
    rule = _Rule(fields, tuple(fixed), ball_of, balls, aims, current, crossed, released)
    candidates = [rule.candidates(group) for group in _groups(fields, sorted(at), ball_of)]
    if any(not found for found in candidates):
        raise FilippovError(f"{name}: no consistent Filippov mode at t = {t:.17g} (switches at the surface: "
                            f"{', '.join(str(i) for i in sorted(at))})")
    # the largest smallest margin over all groups, and in each group its first mode that reaches it
    # (the first of the whole product in its order, as one enumeration of every group together takes)
    best = min((max(value for _, value in found) for found in candidates), default=np.inf)
    mode = list(fixed)
    for found in candidates:
        for part, value in found:
            if value >= best:
                rule.put(mode, part)
                break
    return tuple(mode)


ENUMERATED_SWITCHES = 6  # a group of scalar switches with at most 3^this modes is enumerated …
ENUMERATED = 3**ENUMERATED_SWITCHES  # … and as many of a larger group's least sure ones around its LCP mode
AMBIGUOUS = 1e-6  # a margin of a box-LCP mode below this (λ units): the switch's other modes are tried too


def _groups(fields: Fields, at: list[int], ball_of: dict[int, tuple[int, int]]) -> list[list[int]]:
    """The switches `at` their surface (a vector sign by its first switch) in groups that move
    each other's s, ∇s_i·B_j ≠ 0, each in increasing order: connected components."""
    if len(at) <= 1:
        return [at] if at else []
    columns = [list(range(i, i + ball_of[i][1])) if i in ball_of else [i] for i in at]
    flat = [c for cols in columns for c in cols]
    unit = np.repeat(np.arange(len(at)), [len(cols) for cols in columns])
    response = fields.ds[flat] @ fields.B[:, flat]
    rows, cols = np.nonzero(response)
    coupled = np.zeros((len(at), len(at)), dtype=bool)
    coupled[unit[rows], unit[cols]] = True
    count, label = connected_components(coupled, directed=True, connection="weak")
    return [[at[j] for j in np.flatnonzero(label == g)] for g in range(count)]


@dataclass
class _Rule:
    """The consistency rule of :func:`choose_mode` over one group of switches at their surface,
    the others at `fixed` (which leaves the group's margins unchanged: no coupling)."""

    fields: Fields
    fixed: tuple[int, ...]
    ball_of: dict[int, tuple[int, int]]
    balls: Sequence[tuple[int, int]]
    aims: dict[int, np.ndarray] | None
    current: tuple[int, ...] | None
    crossed: int | None
    released: tuple[int, int] | None

    def options(self, i: int) -> tuple[int, ...]:
        return (0, LEAVING) if i in self.ball_of else (0, 1, -1)

    def put(self, mode: list[int], part: dict[int, int]) -> None:
        for i, m in part.items():
            if i in self.ball_of:
                a, k = self.ball_of[i]
                mode[a : a + k] = [m] * k
            else:
                mode[i] = m

    def value(self, group: list[int], part: dict[int, int]) -> float:
        """The smallest margin of the group in `part` (−inf where `crossed` or `released` forbid it)."""
        if self.crossed in part and self.current is not None and part[self.crossed] == self.current[self.crossed]:
            return -np.inf
        if self.released is not None and self.released[0] in part and part[self.released[0]] != self.released[1]:
            return -np.inf
        mode = list(self.fixed)
        self.put(mode, part)
        margins = _margins(self.fields, tuple(mode), group, self.balls, self.aims)
        return float(margins.min()) if margins.size else np.inf

    def enumerate(self, group: list[int], base: dict[int, int] | None = None,
                  free: list[int] | None = None) -> list[tuple[dict[int, int], float]]:
        """The consistent modes of the group, in the order (0, +1, −1) of its switches `free`
        (all by default; the others as in `base`), each with its smallest margin."""
        free = group if free is None else free
        out = []
        for choice in itertools.product(*(self.options(i) for i in free)):
            part = dict(base or {})
            part.update(zip(free, choice))
            value = self.value(group, part)
            if value >= -MARGIN_TOL:
                out.append((part, value))
        return out

    def candidates(self, group: list[int]) -> list[tuple[dict[int, int], float]]:
        """The group's consistent modes with their smallest margins, in enumeration order: all
        of them where the group is small or holds a vector sign, else the box LCP's and its
        neighbours' in its ambiguous switches."""
        if math.prod(len(self.options(i)) for i in group) <= ENUMERATED or any(i in self.ball_of for i in group):
            return self.enumerate(group)
        A, b = self._system(group)
        lam = self._solved(group, A, b)
        if lam is None:
            raise FilippovError(f"no Filippov mode found for the {len(group)} coupled switches {group} "
                                "(Lemke's method ended on a ray: the coupling is not dissipative)")
        part = dict(zip(group, labels(A, b, lam)))
        if self.released is not None and self.released[0] in part:
            part[self.released[0]] = self.released[1]
        mode = list(self.fixed)
        self.put(mode, part)
        margins = _margins(self.fields, tuple(mode), group, self.balls, self.aims)
        order = np.argsort(margins, kind="stable")  # the least sure first
        unsure = {group[j] for j in order[:ENUMERATED_SWITCHES] if margins[j] < AMBIGUOUS}
        return self.enumerate(group, part, sorted(unsure | ({self.crossed} & set(group))))

    def _system(self, group: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """A = ∇s·B and b over the group's switches, the others at `fixed`: w = A·λ + b."""
        fields = self.fields
        mode = list(self.fixed)
        self.put(mode, dict.fromkeys(group, 1))
        lam = _solve_mode(fields, tuple(mode), self.balls, self.aims)[1]
        lam[group] = 0.0
        A = fields.ds[group] @ fields.B[:, group]
        return A, fields.ds[group] @ (fields.g + fields.B @ lam)

    def _solved(self, group: list[int], A: np.ndarray, b: np.ndarray) -> np.ndarray | None:
        """The box LCP's λ over the group (a released switch held at its side)."""
        if self.released is not None and self.released[0] in group:  # its side is given: λ_i = ±1
            i = group.index(self.released[0])
            keep = [j for j in range(len(group)) if j != i]
            lam = np.full(len(group), float(self.released[1]))
            rest = box_lcp(A[np.ix_(keep, keep)], b[keep] + A[keep, i] * self.released[1])
            if rest is None:
                return None
            lam[keep] = rest
            return lam
        return box_lcp(A, b)


# ------------------------------------------------------------------------ integrate
def integrate(system: FilippovSystem, x0: Sequence[float], T: float, rtol: float = 1e-12, atol: float = 1e-12, *,
              t0: float = 0.0, halt: Callable[[float, float, OdeSolution], bool] | None = None) -> FilippovTrajectory:
    """The Filippov motion of `system` from x(t0) = x0 over [t0, T]: DOP853 (dense output)
    between terminal events, the mode re-chosen by :func:`choose_mode` at every event.
    `halt(start, end, piece)`, asked after each piece, ends the integration there when it
    says True (the trajectory's `halted` is then the time it reached).

    A vector sign (the system's `balls`) that moves ends its piece where ⟨s, aim⟩ reaches 0,
    aim the direction of s when the piece began: a stop where |s| ≈ 0 there (|s| → 0 along
    a line through 0), else the direction has turned (also ended where it turns by 60°), and
    the piece goes on with a new aim; and where |s| falls to REACH_ATOLS·atol, from where it
    is carried on at its present rate to |s| = 0 (:func:`_to_rest`). A stop that sticks puts
    x on s = 0 (:func:`_onto_rest`), which the stuck mode then keeps. Stuck, it ends where |λ_eq| reaches 1 (break-away);
    then it leaves in its quasi-static direction until |s| = RELEASE_RADIUS·max(1, |x|), and
    moves by s/|s| from there (the first-order agreement of the two keeps the error of that
    start at O(τ³) in s', τ the time it takes), by Radau IIA while s/|s| is stiff
    (:func:`_method`). tests/models/test_isotropic_friction.py holds it to isotropic-puck's
    closed form within 1e-9 at rtol = atol = 1e-12."""
    clock = time.perf_counter()
    x = np.array(x0, dtype=float)
    if not np.all(np.isfinite(x)):
        raise FilippovError(f"{system.name}: x0 must be finite, got {x}")
    fields = _Cached(system)
    balls = tuple(system.balls)
    t, T = float(t0), float(T)
    stops = sorted({b for b in system.breaks if t < b < T} | {T})
    mode = choose_mode(fields(t, x), x, name=system.name, t=t, balls=balls)
    aims = _aims(fields(t, x), mode, balls, {})
    starts, pieces, switches, modes = [], [], [], [(t, mode)]
    events = stalls = 0
    left: dict[int, float] = {}  # when each vector sign last began to leave rest
    # a piece tries its whole span as its first step where it ends at a break (an input's kink: a
    # driven replay restarts at every mesh point) or the piece before it was one step
    whole = False
    steps, one_step = 0, True
    halted = None
    while t < T:
        stop = _after(stops, t)
        inside = _inside(t, stop)
        current, aimed = mode, dict(aims)
        scale = max(1.0, float(np.max(np.abs(x), initial=0.0)))
        method, until = _method(fields(inside(t), x), current, balls, scale, aimed, t, left)
        watched = _events(fields, current, inside, balls, aimed, scale, min(REACH_ATOLS * atol, STOP_TOL / 2) * scale,
                          (t, x))
        span = min(until, stop) - t
        run = solve_ivp(lambda s, y: velocity(fields(inside(s), y), current, balls, aimed)[0], (t, t + span),
                        x, method=method, rtol=rtol, atol=atol, dense_output=True, events=[e for e, _ in watched],
                        first_step=span if (whole or stop < T) and method == "DOP853" else None)
        whole = run.t.size == 2
        steps += run.t.size - 1
        one_step = one_step and (whole and method == "DOP853" or run.t.size == 1)
        if run.status == -1:
            raise FilippovError(f"{system.name}: DOP853 failed at t = {run.t[-1]:.17g} in mode {mode}: {run.message}")
        end = float(run.t[-1])
        if end > t:
            starts.append(t)
            pieces.append(run.sol)
            if halt is not None and halt(t, end, run.sol):
                halted = end
                break
        stalls = stalls + 1 if end <= t + 1e-14 * max(1.0, abs(t)) else 0
        events += 1
        if stalls > MAX_STALLS or events > MAX_EVENTS + len(stops):
            raise FilippovError(f"{system.name}: no progress at t = {t:.17g} ({events} events): Zeno or chattering")
        t, x = end, run.y[:, -1].copy()
        switched = True  # a mode change that is a switch of the motion (not a new aim, not the end of a release)
        if run.status == 1:
            (e,) = [j for j, hits in enumerate(run.t_events) if hits.size][:1]
            kind, i = watched[e][1]
            t, x = float(run.t_events[e][0]), run.y_events[e][0].copy()
            if i is None:  # an event shared by several switches: the one at its extreme
                i = watched[e][0].which(_inside(t, stop)(t), x)
            here = fields(_inside(t, stop)(t), x)
            near = max(1.0, float(np.max(np.abs(x), initial=0.0)))
            if kind == "release":
                lam = velocity(here, mode, balls, aims)[1][i]
                new = choose_mode(here, x, mode, released=(i, 1 if lam > 0 else -1), name=system.name, t=t,
                                  balls=balls, aims=aims)
            elif kind == "cross":
                new = choose_mode(here, x, mode, crossed=i, name=system.name, t=t, balls=balls, aims=aims)
            elif kind in ("ball-stop", "ball-aim", "ball-reach") and np.linalg.norm(
                    here.s[i : i + _width(balls, i)]) <= STOP_TOL * near:
                if kind == "ball-reach":  # |s| at a few atol: on to where it reaches 0 at its present rate
                    t, x = _to_rest(here, x, t, stop, mode, balls, aims, i)
                    here = fields(_inside(t, stop)(t), x)
                new = choose_mode(here, x, mode, crossed=i, name=system.name, t=t, balls=balls, aims=aims)
                if new[i] == 0:  # stuck: on s = 0 itself, which the stuck mode keeps (not at the |s| it stopped at)
                    x = _onto_rest(here, x, i, _width(balls, i))
            elif kind == "ball-release":
                new = choose_mode(here, x, mode, released=(i, LEAVING), name=system.name, t=t, balls=balls, aims=aims)
            elif kind == "ball-grown":
                k = _width(balls, i)
                new = mode[:i] + (MOVING,) * k + mode[i + k :]
                switched = False
            else:  # a moving vector sign turned (or ⟨s, aim⟩ = 0 away from s = 0): a new aim
                new, switched = mode, False
        elif t < stop:  # the end of a stiff start (_method): on by DOP853
            new, switched = mode, False
        elif t < T:  # a break in the drift: choose afresh just after it
            new = choose_mode(fields(_inside(t, _after(stops, t))(t), x), x, mode,
                              name=system.name, t=t, balls=balls, aims=aims)
        else:
            break
        aims = _aims(fields(_inside(t, _after(stops, t, T))(t), x), new, balls, aims)
        if new != mode and t < T:
            if switched:
                switches.append(t)
            modes.append((t, new))
        left.update({a: t for a, _ in balls if new[a] == LEAVING and mode[a] != LEAVING})
        mode = new
    if not pieces:
        raise FilippovError(f"{system.name}: nothing integrated over [{t0}, {T}]")
    return FilippovTrajectory(np.array(starts), pieces, tuple(switches), modes, T, events,
                              time.perf_counter() - clock, steps, one_step, halted)


def _to_rest(fields: Fields, x: np.ndarray, t: float, stop: float, mode: tuple[int, ...],
             balls: Sequence[tuple[int, int]], aims: dict[int, np.ndarray], first: int) -> tuple[float, np.ndarray]:
    """(t, x) moved on along the motion to where the vector sign's |s| reaches 0 at its present
    rate (first order: exact where s approaches 0 along a line), within the piece."""
    k = _width(balls, first)
    try:
        f = velocity(fields, mode, balls, aims)[0]
    except np.linalg.LinAlgError:
        return t, x
    part = fields.s[first : first + k]
    radius = float(np.linalg.norm(part))
    rate = float(part @ (fields.ds[first : first + k] @ f)) / radius if radius > 0 else 0.0
    if not rate < 0:
        return t, x
    tau = min(radius / -rate, np.nextafter(stop, t) - t)
    return t + tau, x + tau * f


def _onto_rest(fields: Fields, x: np.ndarray, first: int, k: int) -> np.ndarray:
    """x moved least onto s_a = 0 (a, the k switches of a vector sign from `first`): one
    Gauss–Newton step, exact for a switch linear in x (a velocity, W·v)."""
    rows = fields.ds[first : first + k]
    try:
        return x - rows.T @ np.linalg.solve(rows @ rows.T, fields.s[first : first + k])
    except np.linalg.LinAlgError:
        return x


def _after(stops: list[float], t: float, default: float | None = None) -> float:
    """The first of the sorted `stops` after t (`default` when none is): O(log N), where an
    input that jumps at every point of a fine mesh gives N stops."""
    index = bisect.bisect_right(stops, t)
    if index < len(stops):
        return stops[index]
    if default is None:
        raise ValueError(f"no stop after t = {t}")
    return default


def _method(fields: Fields, mode: Sequence[int], balls: Sequence[tuple[int, int]], scale: float,
            aims: dict[int, np.ndarray], t: float, left: dict[int, float]) -> tuple[str, float]:
    """The method of the next piece and the time it ends by: DOP853 to the next event, or Radau
    IIA (implicit) where a vector sign moves away from rest with |s| < STIFF_RADIUS·max(1, |x|)/2.
    There s/|s| turns back to its slow direction at a rate ~|∇s·B|/|s|, so just after a
    break-away (|s| ~ τ², τ the time since it began to leave) an explicit method needs steps
    ~|s| (≈ 600 DOP853 steps on isotropic-puck), an implicit one steps of the motion's own
    scale. The Radau piece ends at the time |s| should reach STIFF_RADIUS·max(1, |x|) (τ grown
    by √(STIFF_RADIUS·max(1, |x|)/|s|)), a step's end: SciPy's Radau is less accurate than
    DOP853 at tight tolerances once its steps grow, and its interpolant (at an event) more so."""
    try:
        f = velocity(fields, mode, balls, aims)[0]
    except np.linalg.LinAlgError:
        return "DOP853", np.inf
    for a, k in balls:
        part = fields.s[a : a + k]
        radius = float(np.linalg.norm(part))
        if mode[a] == MOVING and radius < 0.5 * STIFF_RADIUS * scale and part @ (fields.ds[a : a + k] @ f) > 0:
            since = t - left.get(a, t)
            return "Radau", t + since * (np.sqrt(STIFF_RADIUS * scale / max(radius, 1e-300)) - 1.0) if since > 0 else np.inf
    return "DOP853", np.inf


def _width(balls: Sequence[tuple[int, int]], first: int) -> int:
    return next(k for a, k in balls if a == first)


def _aims(fields: Fields, mode: Sequence[int], balls: Sequence[tuple[int, int]],
          previous: dict[int, np.ndarray]) -> dict[int, np.ndarray]:
    """Each vector sign's aim for the next piece: the direction of s where it moves (the
    previous aim where s = 0), its quasi-static direction where it leaves s = 0."""
    out = {}
    for a, k in balls:
        part = fields.s[a : a + k]
        radius = float(np.linalg.norm(part))
        if mode[a] == MOVING and radius > 0:
            out[a] = part / radius
        elif mode[a] == LEAVING:
            try:
                out[a] = velocity(fields, mode, balls, previous)[1][a : a + k].copy()
            except np.linalg.LinAlgError:
                out[a] = previous.get(a, np.eye(k)[0])
        else:
            out[a] = previous.get(a, np.eye(k)[0])
    return out


def _events(fields: _Cached, mode: tuple[int, ...], inside: Callable[[float], float],
            balls: Sequence[tuple[int, int]] = (), aims: dict[int, np.ndarray] | None = None,
            scale: float = 1.0, reach: float = 0.0, start: tuple[float, np.ndarray] | None = None
            ) -> list[tuple[Callable, tuple[str, int | None]]]:
    """The terminal events of a piece in `mode` from `start` = (t, x), each with (its kind, its
    switch); a moving vector sign stops where ⟨s, aim⟩ reaches 0 or |s| falls to `reach`.

    The scalar switches share two events, whatever their number: the first crossing, min_i m_i·s_i
    over the moving ones reaching 0, and the first release, max_i |λ_i| − 1 over the sliding ones
    reaching 0 (one linear solve for all); the switch is the one at the minimum (maximum) there
    (the event's `which`). One event per switch would cost k calls a step and a root search
    for every switch a long step passes, k² over k stops. A switch that starts the piece at
    its event's zero (just crossed, or released on a tie) has an event of its own."""
    out: list[tuple[Callable, tuple[str, int | None]]] = []
    ball_of = {a + j: (a, k) for a, k in balls for j in range(k)}
    scalar = [i for i in range(len(mode)) if i not in ball_of]
    moving = np.array([i for i in scalar if mode[i] != 0], dtype=int)
    sliding = np.array([i for i in scalar if mode[i] == 0], dtype=int)
    sides = np.array([mode[i] for i in moving], dtype=float)
    here = fields(inside(start[0]), start[1]) if start is not None else None
    if moving.size:
        away = np.ones(moving.size, dtype=bool) if here is None else sides * here.s[moving] > 0
        together, alone = moving[away], moving[~away]
        signs = sides[away]
        if together.size:
            def crossing(t: float, x: np.ndarray) -> float:
                return float(np.min(signs * fields(inside(t), x).s[together]))

            crossing.which = lambda t, x: int(together[np.argmin(signs * fields(t, x).s[together])])
            crossing.terminal, crossing.direction = True, -1.0
            out.append((crossing, ("cross", None)))
        for i in alone:
            def crossing_one(t: float, x: np.ndarray, i: int = int(i)) -> float:
                return float(fields(inside(t), x).s[i])

            crossing_one.terminal, crossing_one.direction = True, -float(mode[i])
            out.append((crossing_one, ("cross", int(i))))
    if sliding.size:
        def selections(t: float, x: np.ndarray) -> np.ndarray:
            return np.abs(velocity(fields(inside(t), x), mode, balls, aims)[1][sliding])

        try:
            inside_band = np.ones(sliding.size, dtype=bool) if here is None else \
                np.abs(velocity(here, mode, balls, aims)[1][sliding]) < 1.0
        except np.linalg.LinAlgError:
            inside_band = np.ones(sliding.size, dtype=bool)
        shared, own = sliding[inside_band], sliding[~inside_band]
        for members in ([shared] if shared.size else []) + [np.array([i]) for i in own]:
            def release(t: float, x: np.ndarray, members: np.ndarray = members) -> float:
                try:
                    return float(np.max(np.abs(velocity(fields(inside(t), x), mode, balls, aims)[1][members]))) - 1.0
                except np.linalg.LinAlgError:
                    return 1.0

            def which(t: float, x: np.ndarray, members: np.ndarray = members) -> int:
                try:
                    return int(members[np.argmax(np.abs(velocity(fields(t, x), mode, balls, aims)[1][members]))])
                except np.linalg.LinAlgError:
                    return int(members[0])

            release.which = which
            release.terminal, release.direction = True, 1.0
            out.append((release, ("release", None if members is shared else int(members[0]))))
    for a, k in balls:
        aim = (aims or {}).get(a, np.eye(k)[0])
        if mode[a] == MOVING:
            def stopping(t: float, x: np.ndarray, a: int = a, k: int = k, aim: np.ndarray = aim) -> float:
                return float(fields(inside(t), x).s[a : a + k] @ aim)

            def turning(t: float, x: np.ndarray, a: int = a, k: int = k, aim: np.ndarray = aim) -> float:
                part = fields(inside(t), x).s[a : a + k]
                return float(part @ aim - 0.5 * np.linalg.norm(part))

            def reaching(t: float, x: np.ndarray, a: int = a, k: int = k) -> float:
                return float(np.linalg.norm(fields(inside(t), x).s[a : a + k])) - reach

            stopping.terminal, stopping.direction = True, -1.0
            turning.terminal, turning.direction = True, -1.0
            reaching.terminal, reaching.direction = True, -1.0
            out += [(stopping, ("ball-stop", a)), (turning, ("ball-aim", a)), (reaching, ("ball-reach", a))]
        elif mode[a] == 0:
            def breaking(t: float, x: np.ndarray, a: int = a) -> float:
                try:
                    return float(np.linalg.norm(_solve_mode(fields(inside(t), x), mode, balls, aims)[2][a])) - 1.0
                except np.linalg.LinAlgError:
                    return -1.0

            breaking.terminal, breaking.direction = True, 1.0
            out.append((breaking, ("ball-release", a)))
        else:  # LEAVING: quasi-static until |s| has grown to RELEASE_RADIUS
            def growing(t: float, x: np.ndarray, a: int = a, k: int = k) -> float:
                return float(np.linalg.norm(fields(inside(t), x).s[a : a + k])) - RELEASE_RADIUS * scale

            growing.terminal, growing.direction = True, 1.0
            out.append((growing, ("ball-grown", a)))
    return out


def _inside(start: float, stop: float) -> Callable[[float], float]:
    """t clipped into the open piece (start, stop), one ulp in from each end: DOP853's last
    stage t + h can round past `stop`, where an input's jump (a break) would be seen too early."""
    low, high = np.nextafter(start, stop), np.nextafter(stop, start)
    return lambda t: min(max(t, low), high)
