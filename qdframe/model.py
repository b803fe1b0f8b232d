"""The InclusionModel interface: what a model author writes.

A model states the problem of paper Section 3:

    x'(t) ∈ F(x(t)),  x(0) = x0,  x_j(T) = xT_j (j ∈ J),  e(x(t)) = 0 (optional),

with F split into blocks of coordinates. Each block's set is given through its
support function (paper (support), (supf), (subf)):

    c(F_b(x), ψ) = Σ_j max_q <f_jq(x), ψ>  +  Σ_j min_p g_jp(x, ψ),

ψ ∈ {−1, +1} for a one-coordinate block (closed form) and ψ ∈ S_k for a block of k
coordinates (ψ* is searched numerically, Remark 5.1 / Example 7.2). Every piece
comes with its x-gradient, evaluated for all nodes at once: arrays are (N, ...).

An exact equation z_i = f(x) is the one-piece max-group f (a singleton set).

With unknown controls u (`control_names`, paper Example 7.3) every piece is a function
of y = (x, u), an array of shape (N, n + m), and its gradients have n + m columns.

A piece callable may carry an optional attribute `formulas`: `formulas(symbols)` (a min
group's `formulas(symbols, psi)`) returns its values, flattened in the order the callable
returns them, as SymPy formulas of the given symbols for y (and ψ). Where every piece of a
model has it, the event-driven integrator behind the replay certificate and the simulated
start evaluates the model's whole Filippov system at one point in one compiled call, not
one call per piece (:mod:`qdframe.certificates.model_system`). The set language and
:mod:`qdframe.ready_pieces` attach it; a hand-written piece without it still works.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from .errors import InputError

# x (N, n) -> values (N, m, k) and Jacobians (N, m, k, n)
MaxPieces = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
# x (N, n), psi (N, k) -> values (N, m) and x-gradients (N, m, n)
MinPieces = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
# x (N, n), psi (N, k) -> values (N, m) alone
MinValues = Callable[[np.ndarray, np.ndarray], np.ndarray]
# x (N, n) -> values (N, m) and gradients (N, m, n)
ScalarPieces = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]



@dataclass(frozen=True)
class MaxGroup:
    """max_q <f_q(x), ψ>: the support function of co{f_1(x), …, f_m(x)} (paper (supf)).

    `pieces(x)` returns f of shape (N, m, k) and ∂f/∂x of shape (N, m, k, n).
    """

    pieces: MaxPieces
    name: str = "max"


@dataclass(frozen=True)
class MinGroup:
    """min_p g_p(x, ψ) (paper (subf)): intersections, Remark 5.1's c̃.

    `pieces(x, psi)` returns g of shape (N, m) and ∂g/∂x of shape (N, m, n).

    `values(x, psi)`, optional, returns g alone, the same numbers as `pieces(x, psi)[0]`.
    On a block of k ≥ 2 coordinates the search for ψ* (Remark 5.1) evaluates g some 100–200
    times per node and per new iterate and never uses ∂g/∂x: a `values` that skips the
    gradients makes that search cheaper and its temporaries smaller (docs/benchmarks.md
    has the timing on paper-7.2). A functional compares the
    two before its first search (64 nodes, 32 directions each) and raises :class:`~qdframe.errors.ModelOutputError` where
    they differ (a wrong `values` would find a wrong ψ* and understate the distance to F);
    `qdframe check-model` compares them at random points.
    """

    pieces: MinPieces
    name: str = "min"
    values: MinValues | None = None


@dataclass(frozen=True)
class BallSwitch:
    """The switch of a vector sign Sgn(s(y)), s ∈ R^k (k ≥ 2): Filippov's s/|s| for s ≠ 0 and
    the closed unit ball B at s = 0, the subdifferential of the Euclidean norm |s| (isotropic
    Coulomb friction in the plane or in space: v' ∈ f − μ·Sgn(v1, v2)).

    `function(y)` returns s (N, k) and ∇s (N, k, n + m). The solver gives the switch ONE
    selection vector λ ∈ B per node (k columns of the selections), tied to s by the natural
    map λ = P_B(λ + c·s) (P_B the projection onto the ball: Alart and Curnier's
    second-order-cone complementarity), so that λ = s/|s| where s ≠ 0 and |λ| ≤ 1 where
    s = 0. Sign terms pass it as their `switch` with a `component` j: each contributes
    sense·a(y)·λ_j to its coordinate, and every term on the same BallSwitch object shares λ.

    A weighted norm |W·v| (elliptic friction, principal axes μ-scaled) is the ball switch
    s = W·v with the terms of Wᵀ·λ: ∂|Wv| = Wᵀ·Sgn(Wv) (the set language's
    ``Sgn(v1, v2, matrix=W)``).
    """

    function: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    dim: int
    name: str = "Sgn"

    def __call__(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.function(y)


@dataclass(frozen=True)
class SignTerm:
    """sense·a(y)·Sgn(s(y)), Filippov's set-valued sign term (paper Section 5): {a·sign s}
    for s ≠ 0 and a·[−1, 1] at s = 0, with the amplitude a(y) = Σ_i max_q a_iq(y) ≥ 0 and
    `sense` +1 or −1.

    One switch, one selection: sign terms whose `switch` is the same callable share one
    selection λ ∈ Sgn(s) per node (exact signs), each contributing sense·a(y)·λ. A switch
    s that enters one coordinate as +a·Sgn(s) and another as −b·Sgn(s) (a friction law whose
    principal axes are not the coordinate axes) is two terms on the same callable with
    senses +1 and −1: writing the second as b·Sgn(−s) with a new callable would give it a
    selection of its own, and F would be larger than Filippov's set. The set language
    (:mod:`qdframe.sets`) does this for you: Sgn(c·s) for any constant c ≠ 0 shares s's
    selection.

    `amplitude` is a constant a ≥ 0 or a tuple of groups, each `pieces(y)` returning
    values (N, m) and gradients (N, m, n + m) (|y_i| is the group {y_i, −y_i}: see
    :func:`qdframe.ready_pieces.abs_sum`). `switch(y)` returns s (N,) and ∇s (N, n + m).

    The solver uses the support function a(y)·κ_ψ(s) with κ_ψ(s) = 1 − 2·S(u),
    u = clip(−ψs/β, 0, 1), S(u) = 3u² − 2u³: the whole interval a·[−1, 1] at s = 0,
    a·sign(s) for |s| ≥ β, shrinking smoothly in between. It contains Filippov's set,
    is C¹ in s (no jump for the descent to stall on, no kink for Gauss–Newton) and is
    exact for β = 0, which the simulator uses. β = inf keeps the whole interval
    a·[−1, 1] everywhere: the paper's form on the discontinuity surface s = 0, exact
    when the model's surface enforces s = 0. Only for one-coordinate blocks.

    A vector sign: `switch` a :class:`BallSwitch` and `component` j in 0..k − 1; the term is
    sense·a(y)·λ_j with λ ∈ Sgn(s) ⊂ B the switch's selection vector. Its band (for
    ``signs="band"`` and the band start) is the interval [w·s_j/|s| − (1 − w), w·s_j/|s| + (1 − w)],
    w = S(min(|s|/β, 1)): the whole [−1, 1] at s = 0, s_j/|s| for |s| ≥ β, C¹ in s.

    `written` (±1) relates the selection to the term as the model wrote it (its `name`):
    −0.3·Sgn(v) is stored as 0.3·Sgn(−v), whose selection is −1 where v > 0, and `written` −1
    makes the result's frames show +1, the λ ∈ Sgn(v) of the name.
    """

    amplitude: float | tuple[Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], ...]
    switch: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | BallSwitch
    band: float = 1e-3
    name: str = "sgn"
    sense: float = 1.0
    component: int | None = None  # j of a BallSwitch's λ (None for a scalar switch)
    written: float = 1.0  # λ of the Sgn(s) in `name`, as written, over the selection λ ∈ Sgn(switch): ±1

    @property
    def ball(self) -> BallSwitch | None:
        """The vector sign's switch, or None for a scalar sign term."""
        return self.switch if isinstance(self.switch, BallSwitch) else None


@dataclass(frozen=True)
class SetBlock:
    """The set F_b(x) of the coordinates `coords` of z, via its support function:
    c(F_b, ψ) = Σ max-groups + Σ min-groups (+ Σ sign terms for one coordinate)."""

    coords: tuple[int, ...]
    max_groups: tuple[MaxGroup, ...] = ()
    min_groups: tuple[MinGroup, ...] = ()
    name: str = ""
    signs: tuple[SignTerm, ...] = ()

    @property
    def size(self) -> int:
        return len(self.coords)

    @classmethod
    def equation(
        cls,
        coord: int,
        rhs: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
        name: str = "",
        signs: tuple[SignTerm, ...] = (),
    ) -> "SetBlock":
        """z_coord = rhs(y) (+ Σ sign terms); rhs returns values (N,) and gradients (N, n + m)."""

        def pieces(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            value, grad = rhs(x)
            return value[:, None, None], grad[:, None, None, :]

        if hasattr(rhs, "formulas"):
            pieces.formulas = rhs.formulas  # type: ignore[attr-defined]
        return cls((coord,), (MaxGroup(pieces, name or f"z{coord}"),), (), name, signs)


@dataclass(frozen=True)
class Cost:
    """A cost integrand ∫ [Σ_j max_q a_jq(x) + Σ_j min_p b_jp(x)] dt with penalty weight λ.

    The descent then minimizes the cost + λ·I (paper Example 7.1). Each group's
    `pieces(x)` returns values (N, m) and gradients (N, m, n). Where the cost's least
    value over the solutions is not 0 (a shortest time), λ is raised from `weight` until
    the minimizer is a solution and an optimum within the target (:mod:`qdframe.solve.optimum`).
    """

    max_groups: tuple[ScalarPieces, ...] = ()
    min_groups: tuple[ScalarPieces, ...] = ()
    weight: float = 1.0
    # optional: ∇²c(y) (N, w, w) of a smooth integrand (one max-group of one piece), y = (x, u);
    # gauss-newton then models the cost to second order (its PSD part)
    hessian: Callable[[np.ndarray], np.ndarray] | None = None
    # optional: a terminal (Mayer) cost M(x(T)): x (n,) -> (value, gradient (n,), Hessian (n, n))
    terminal: Callable[[np.ndarray], tuple[float, np.ndarray, np.ndarray]] | None = None


@dataclass(frozen=True)
class Surface:
    """e(x) = 0: `function(x)` returns e (N, o) and ∂e/∂x (N, o, n)."""

    function: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


class InclusionModel(ABC):
    """A differential inclusion with boundary data (paper Section 3).

    Subclasses set the class attributes and implement :meth:`blocks`; override
    :meth:`surface`, :meth:`cost`, :meth:`initial_guess` and :meth:`exact_solution`
    as the scene needs. `T`, `x0` and `end_values` can be overridden per instance.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    state_names: ClassVar[tuple[str, ...]] = ()
    control_names: ClassVar[tuple[str, ...]] = ()  # unknown controls u(t), solved for with x and z
    # resolved states {i: j}: x_i' = x_j exactly (as 7.3's x1' = x4); z_i is then not an
    # unknown but x_j itself, with no set and no block (the paper's reduction of 7.3)
    resolved: ClassVar[dict[int, int]] = {}
    default_T: ClassVar[float] = 1.0
    default_x0: ClassVar[tuple[float, ...]] = ()
    end_indices: ClassVar[tuple[int, ...]] = ()  # J, zero-based
    default_end_values: ClassVar[tuple[float, ...]] = ()
    periodic: ClassVar[tuple[int, ...]] = ()  # P: x_i(T) = x_i(0), zero-based
    default_tol: ClassVar[float] = 1e-10
    # the scheme a solve uses unless told (qdframe.schemes): implicit Euler, first order and
    # robust for sticking, sliding and switching; smooth models may prefer "radau-iia" or
    # "trapezoid" (the paper's, second order)
    default_scheme: ClassVar[str] = "implicit-euler"
    # states with x_i' = 0 exactly (their block z_i = 0): unknown constants, which gauss-newton
    # keeps one unknown for all nodes (qdframe.unknowns declares its T and parameters so)
    constant_states: ClassVar[tuple[int, ...]] = ()
    # free end time (:mod:`qdframe.unknowns`): T is found with x, starting from `T`, kept in
    # `T_bounds` (lo, hi), 0 ≤ lo < hi ≤ inf
    free_T: ClassVar[bool] = False
    T_bounds: ClassVar[tuple[float, float]] = (0.0, np.inf)
    # unknown constant parameters p (:mod:`qdframe.unknowns`): found with x; the pieces then
    # take y = (x, p, u), n + q + m columns; `default_parameters` are the starting guesses and
    # `parameter_bounds` {name: (lo, hi)} optional open bounds
    parameter_names: ClassVar[tuple[str, ...]] = ()
    default_parameters: ClassVar[tuple[float, ...]] = ()
    parameter_bounds: ClassVar[dict[str, tuple[float, float]]] = {}
    # the true T and parameters where they are known (with exact_solution): a result's error
    # vs the known solution then covers them as well as x
    exact_T: ClassVar[float | None] = None
    exact_parameters: ClassVar[Mapping[str, float] | Sequence[float]] = {}  # {name: value} or values in order
    # bounds lo ≤ u_j(t) ≤ hi on controls and lo ≤ x_i(t) ≤ hi on states (path constraints, held
    # at every point of the scheme), {name: (lo, hi)}, ±inf for a free side (solved by gauss-newton)
    control_bounds: ClassVar[Mapping[str, tuple[float, float]]] = {}
    state_bounds: ClassVar[Mapping[str, tuple[float, float]]] = {}
    # the least cost where it is known (with exact_solution): a `solved` result's cost is held to it
    exact_cost: ClassVar[float | None] = None

    def __init__(
        self,
        T: float | None = None,
        x0: Sequence[float] | None = None,
        end_values: Sequence[float] | None = None,
        periodic: Sequence[int | str] | None = None,
        *,
        free_T: bool | None = None,
        parameters: Mapping[str, float] | Sequence[float] | None = None,
    ) -> None:
        """`x0`: n values, NaN where x_i(0) is free. `end_values`: the values of the model's
        J in order, or n values with NaN where x_i(T) is free (this chooses J). `periodic`:
        the coordinates (indices or state names) with x_i(T) = x_i(0). `free_T`: T unknown,
        `T` its starting guess (None: the class's `free_T`). `parameters`: starting guesses
        of the unknown parameters, {name: value} or q values in `parameter_names` order."""
        n = len(self.state_names)
        if n == 0:
            raise InputError(f"{type(self).__name__}.state_names", "a non-empty tuple of names")
        self.T = _positive_float("T", self.default_T if T is None else T)
        if free_T is not None:
            if not isinstance(free_T, (bool, np.bool_)):
                raise InputError("free_T", "True or False", free_T)
            self.free_T = bool(free_T)
        self.T_bounds = _bounds("T_bounds", self.T_bounds)
        if self.free_T and not (0 <= self.T_bounds[0] < self.T < self.T_bounds[1]):
            raise InputError("T", f"a starting guess of the free T inside T_bounds ({self.T_bounds[0]:g}, "
                                  f"{self.T_bounds[1]:g}) (with 0 ≤ lo)", self.T)
        self.parameters = self._parameter_guesses(parameters)
        self.exact_parameters = self._exact_parameters()
        self.bounds_table = self._bounds_table()
        self.x0 = _finite_vector("x0", self.default_x0 if x0 is None else x0, n, free=True)
        if end_values is not None and len(end_values) == n != len(self.end_indices):
            chosen = np.asarray(end_values, dtype=float)
            self.end_indices = tuple(int(i) for i in np.flatnonzero(~np.isnan(chosen)))
            end_values = chosen[~np.isnan(chosen)]
        if periodic is not None:
            self.periodic = tuple(self._index("periodic", c) for c in periodic)
        for j in self.end_indices:
            if not (isinstance(j, (int, np.integer)) and 0 <= j < n):
                raise InputError(f"{type(self).__name__}.end_indices", f"indices in 0..{n - 1}", j)
        if len(set(self.end_indices)) != len(self.end_indices):
            raise InputError(f"{type(self).__name__}.end_indices", "distinct indices", self.end_indices)
        values = self.default_end_values if end_values is None else end_values
        self.end_values = _finite_vector("xT", values, len(self.end_indices))
        for i in self.periodic:
            if not (isinstance(i, (int, np.integer)) and 0 <= i < n) or i in self.end_indices:
                raise InputError("periodic", f"state indices in 0..{n - 1} not in the end coordinates J", i)
        self._check_blocks()

    def _parameter_guesses(self, parameters: Mapping[str, float] | Sequence[float] | None) -> np.ndarray:
        """The starting guesses of the parameters, checked against their names and bounds."""
        names = tuple(self.parameter_names)
        if len(set(names)) != len(names) or set(names) & set(self.state_names):
            raise InputError(f"{type(self).__name__}.parameter_names", "distinct names, none a state's", names)
        if isinstance(parameters, Mapping):
            unknown = [key for key in parameters if key not in names]
            if unknown:
                raise InputError("parameters", f"names among the model's parameters ({', '.join(names) or 'none'})",
                                 ", ".join(map(str, unknown)))
            guesses = _finite_vector(f"{type(self).__name__}.default_parameters", self.default_parameters, len(names))
            guesses = np.array([_finite_number(f"parameters[{name!r}]", parameters.get(name, value))
                                for name, value in zip(names, guesses)])
        else:
            values = self.default_parameters if parameters is None else parameters
            guesses = _finite_vector("parameters", values, len(names))
        unknown = [key for key in self.parameter_bounds if key not in names]
        if unknown:
            raise InputError(f"{type(self).__name__}.parameter_bounds", f"keys among parameter_names ({', '.join(names)})",
                             ", ".join(map(str, unknown)))
        for name, guess in zip(names, guesses):
            lo, hi = _bounds(f"parameter_bounds[{name!r}]", self.parameter_bounds.get(name, (-np.inf, np.inf)))
            if not lo < guess < hi:
                raise InputError(f"parameters[{name!r}]", f"a starting guess inside its bounds ({lo:g}, {hi:g})", float(guess))
        return guesses

    def _bounds_table(self) -> dict[str, tuple[float, float]]:
        """`state_bounds` and `control_bounds` checked, as {name: (lo, hi)}: each name a state
        or a control of the model, lo < hi, not both infinite."""
        table: dict[str, tuple[float, float]] = {}
        for attribute, names in (("state_bounds", self.state_names), ("control_bounds", self.control_names)):
            given = getattr(type(self), attribute)
            where = f"{type(self).__name__}.{attribute}"
            if not isinstance(given, Mapping):
                raise InputError(where, "{name: (lo, hi)}", given)
            for name, bound in given.items():
                if name not in names:
                    raise InputError(f"{where}[{name!r}]", f"one of {', '.join(names) or '(none)'}", name)
                try:
                    lo, hi = (float(value) for value in bound)
                except (TypeError, ValueError):
                    raise InputError(f"{where}[{name!r}]", "(lo, hi): two numbers, ±inf for a free side",
                                     bound) from None
                if not (lo < hi) or np.isnan(lo) or np.isnan(hi) or (np.isinf(lo) and np.isinf(hi)):
                    raise InputError(f"{where}[{name!r}]", "(lo, hi) with lo < hi, at most one side infinite", bound)
                table[name] = (lo, hi)
        return table

    def _exact_parameters(self) -> dict[str, float]:
        """`exact_parameters` as {name: value}, given as a mapping or as q values in
        `parameter_names` order (like `default_parameters`)."""
        names, given = tuple(self.parameter_names), type(self).exact_parameters
        where = f"{type(self).__name__}.exact_parameters"
        if isinstance(given, Mapping):
            unknown = [key for key in given if key not in names]
            if unknown:
                raise InputError(where, f"names among parameter_names ({', '.join(names) or 'none'})",
                                 ", ".join(map(str, unknown)))
            return {name: float(_finite_vector(where, [value], 1)[0]) for name, value in given.items()}
        if isinstance(given, (str, bytes)) or not isinstance(given, Sequence | np.ndarray):
            raise InputError(where, "{name: value} or the values in parameter_names order", given)
        return dict(zip(names, map(float, _finite_vector(where, given, len(names))))) if len(given) else {}

    @property
    def n_parameters(self) -> int:
        return len(self.parameter_names)

    @property
    def has_unknowns(self) -> bool:
        """Whether T or parameters are found with x (:mod:`qdframe.unknowns` solves such a model)."""
        return bool(self.free_T or self.parameter_names)

    def _index(self, field_name: str, coordinate: int | str) -> int:
        """A state index from an index or a state name."""
        if isinstance(coordinate, str) and coordinate in self.state_names:
            return self.state_names.index(coordinate)
        try:
            return int(coordinate)
        except (TypeError, ValueError):
            raise InputError(field_name, f"state indices or names ({', '.join(self.state_names)})", coordinate) from None

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    @property
    def n_controls(self) -> int:
        return len(self.control_names)

    @abstractmethod
    def blocks(self) -> Sequence[SetBlock]:
        """The blocks of F, covering every state coordinate exactly once."""

    def surface(self) -> Surface | None:
        """The surface e(x) = 0, or None (no ω term)."""
        return None

    def cost(self) -> Cost | None:
        """The cost integrand and its penalty weight λ, or None."""
        return None

    def initial_guess(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The first iterate (x, z), each (N, n). Default: x ≡ x0 (0 where x0 is free), z ≡ 0."""
        return np.tile(np.nan_to_num(self.x0), (t.size, 1)), np.zeros((t.size, self.n_states))

    def initial_controls(self, t: np.ndarray) -> np.ndarray:
        """The first iterate of the controls u, (N, m). Default: u ≡ 0."""
        return np.zeros((t.size, self.n_controls))

    def exact_solution(self, t: np.ndarray) -> np.ndarray | None:
        """A known solution x(t) (N, n) for the default boundary data, or None."""
        return None

    def accuracy_scale(self, x: np.ndarray) -> float:
        """max(1, max|x|): what an accuracy target is relative to (the states the user is given)."""
        return max(1.0, float(np.max(np.abs(x))))

    def time_scale(self, x: np.ndarray) -> float:
        """The user's time of the solver's: t = s·time_scale(x) (1 but where T is found)."""
        return 1.0

    def observed(self, x: np.ndarray) -> np.ndarray:
        """What the user is given of a trajectory's points (N, ·), which an error estimate
        compares: x itself (:mod:`qdframe.unknowns`: x, then the T and parameters found)."""
        return x

    def _check_blocks(self) -> None:
        from .registry import plugin_code

        with plugin_code(self, "blocks()"):
            blocks = tuple(self.blocks())
        for block in blocks:
            if block.signs and block.size != 1:
                raise InputError(f"{type(self).__name__}.blocks", "sign terms only in one-coordinate blocks", block.coords)
            for term in block.signs:
                if not (term.band >= 0):  # NaN fails too; inf is allowed
                    raise InputError(f"{type(self).__name__} sign term {term.name!r} band", "a number ≥ 0", term.band)
                if term.sense not in (1.0, -1.0):
                    raise InputError(f"{type(self).__name__} sign term {term.name!r} sense", "+1 or −1", term.sense)
                ball = term.ball
                if ball is not None:
                    if not (isinstance(ball.dim, (int, np.integer)) and ball.dim >= 2):
                        raise InputError(f"{type(self).__name__} sign term {term.name!r} BallSwitch dim",
                                         "an integer k ≥ 2 (one coordinate: a scalar switch)", ball.dim)
                    if not (isinstance(term.component, (int, np.integer)) and 0 <= term.component < ball.dim):
                        raise InputError(f"{type(self).__name__} sign term {term.name!r} component",
                                         f"an index in 0..{ball.dim - 1} of its BallSwitch's λ", term.component)
                elif term.component is not None:
                    raise InputError(f"{type(self).__name__} sign term {term.name!r} component",
                                     "None for a scalar switch (a component needs a BallSwitch)", term.component)
        for i, j in self.resolved.items():
            if not (0 <= i < self.n_states and 0 <= j < self.n_states):
                raise InputError(f"{type(self).__name__}.resolved", f"pairs i: j of indices in 0..{self.n_states - 1}", (i, j))
        covered = sorted([c for block in blocks for c in block.coords] + list(self.resolved))
        if covered != list(range(self.n_states)):
            raise InputError(
                f"{type(self).__name__}.blocks",
                f"blocks (with the resolved states) covering each coordinate 0..{self.n_states - 1} exactly once",
                covered,
            )


def _positive_float(field_name: str, value: object) -> float:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(field_name, "a positive number", value) from None
    if not np.isfinite(number) or number <= 0:
        raise InputError(field_name, "a positive finite number", value)
    return number


def _bounds(field_name: str, bounds: object) -> tuple[float, float]:
    """(lo, hi) with lo < hi (infinite ends allowed)."""
    try:
        lo, hi = (float(v) for v in bounds)  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise InputError(field_name, "a pair (lo, hi) of numbers (±inf for none)", bounds) from None
    if np.isnan(lo) or np.isnan(hi) or not lo < hi:
        raise InputError(field_name, "a pair (lo, hi) with lo < hi (±inf for none)", bounds)
    return lo, hi


def _finite_number(field_name: str, value: object) -> float:
    """One finite number, or InputError naming the field."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not np.isfinite(value):
        raise InputError(field_name, "a finite number", value)
    return float(value)


def _finite_vector(field_name: str, values: object, length: int, free: bool = False) -> np.ndarray:
    try:
        vector = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(field_name, f"{length} numbers", values) from None
    if vector.size != length:
        raise InputError(field_name, f"{length} comma-separated numbers", ",".join(map(str, vector)))
    if not np.all(np.isfinite(vector) | (free & np.isnan(vector))):
        expected = "finite numbers, or nan (free)" if free else "finite numbers (no NaN or inf)"
        raise InputError(field_name, expected, ",".join(map(str, vector)))
    return vector
