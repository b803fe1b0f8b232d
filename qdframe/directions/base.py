"""The DirectionSolver interface and the min-norm mechanism the QP backends share.

A direction solver turns the iterate ξ into a descent direction G (nodes × d). The
paper's direction (problems (19), (eq), (maxmin)) is, node by node,

    max over vertices w of B_k  of  min over v ∈ A_k  of ‖v + w‖²,   G_k = −(v̄ + w̄),

and each inner problem is a minimum-norm point of a sum of simplices. Backends that
follow the paper subclass :class:`MinNormDirection` and implement only
:meth:`MinNormDirection.min_norm` for a whole batch at once.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ..errors import InputError, close_names
from ..functional.quasidifferential import Quasidifferential

if TYPE_CHECKING:
    from ..functional import Functional


@dataclass(frozen=True)
class Direction:
    """A descent direction and its quality figures.

    step: G, shape (N, d). deviation: per-node ‖v̄ + w̄‖, the Hausdorff deviation of
    −B_k from A_k (0 where the minimum condition (11.400) holds). slope: the
    directional derivative of the objective along G (formula (11.10)), negative
    for a descent direction. stationary: set by solvers whose stationarity test is
    not the paper's deviation ≤ ε (e.g. gauss-newton).
    """

    step: np.ndarray
    deviation: np.ndarray
    slope: float
    stationary: bool | None = None  # a solver's own stationarity verdict; None: deviation ≤ ε decides


@dataclass(frozen=True)
class Rule:
    """The range of one option: `accepts(value)` and the text of the expected form."""

    text: str
    accepts: Callable[[Any], bool]


def number_rule(low: float | None = None, high: float | None = None, *, above: float | None = None,
                integer: bool = False, why: str = "") -> Rule:
    """A finite number (an integer if `integer`) ≥ low, > above, ≤ high; `why` names whose limit it is."""
    kind = "an integer" if integer else "a number"
    parts = [f"≥ {low:g}"] if low is not None else []
    parts += [f"> {above:g}"] if above is not None else []
    parts += [f"≤ {high:g}" if high < 1e6 else f"≤ {int(high)}"] if high is not None else []
    text = " ".join([kind] + [" and ".join(parts)] if parts else [kind]) + (f" ({why})" if why else "")

    def accepts(value: Any) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            return False
        if integer and not float(value).is_integer():
            return False
        return bool(np.isfinite(value) and (low is None or value >= low) and (above is None or value > above)
                    and (high is None or value <= high))

    return Rule(text, accepts)


class OptionError(InputError):
    """A direction option outside its range: `owner.key: expected …, got …` (exit status 2)."""

    def __init__(self, owner: str, key: str, expected: str, value: object) -> None:
        self.key, self.value = key, value
        super().__init__(f"{owner}.{key}", expected, value)


class DirectionSolver(ABC):
    """Computes a descent direction of the discretized objective at ξ.

    A dataclass solver's public fields are its options (``--option KEY=VALUE``);
    `option_rules` gives the range of each (checked by :meth:`check_options` before a
    solve starts, from the command line and in the dataclass's ``__post_init__``), and a
    float option without a rule must be finite.
    """

    name: ClassVar[str] = ""
    option_rules: ClassVar[dict[str, Rule]] = {}
    default_line_search: ClassVar[str] = "golden"  # used when the caller names none
    default_continuation: ClassVar[str] = "none"  # grids before the requested one: "auto" or "none" (continuation.grid_schedule)
    coarsest_nodes: ClassVar[int] = 11  # the first grid of "auto"
    ladder_steps: ClassVar[tuple[int, ...]] = (1,)  # grids of "auto" per decade: (coarsest − 1)·step·10^k + 1
    # its step is a Newton step: where the descent stalls it may take a few whole (γ = 1) to
    # leave a kink (steps.watchdog); the paper's min-norm directions are not
    full_steps: ClassVar[bool] = False
    # the iteration budget of a certified solve (solve's max_iter=None where the mesh is refined)
    certified_max_iter: ClassVar[int] = 500

    def start(self, functional: "Functional") -> None:
        """Called once before a descent on `functional` (and before a watchdog round of full steps:
        steps.watchdog): reset any state kept between iterations (rebind it, do not mutate it in
        place: :meth:`snapshot` keeps the old objects)."""

    def snapshot(self) -> dict:
        """The state kept between iterations, for :meth:`restore` where a trial round of full
        steps is not kept (the descent then goes on as if it had not been tried)."""
        return dict(vars(self))

    def restore(self, state: dict) -> None:
        """Back to a :meth:`snapshot`."""
        vars(self).clear()
        vars(self).update(state)

    def check_options(self) -> None:
        """Raise :class:`OptionError` for the first option outside its range (`option_rules`;
        a float option without a rule must be finite). Subclasses add checks that tie
        options together (call this first)."""
        if not dataclasses.is_dataclass(self):
            return
        for item in dataclasses.fields(self):
            if not item.init or item.name.startswith("_"):
                continue
            value = getattr(self, item.name)
            rule = self.option_rules.get(item.name)
            if rule is not None and not rule.accepts(value):
                raise OptionError(type(self).__name__, item.name, rule.text, value)
            if rule is None and isinstance(value, float) and not np.isfinite(value):
                raise OptionError(type(self).__name__, item.name, "a finite number", value)

    @abstractmethod
    def compute(self, functional: "Functional", xi: np.ndarray, delta: float) -> Direction:
        """Direction at ξ with δ-active pieces (paper Section 6)."""


ROUNDING = 16 * np.finfo(float).eps  # a direction entry below this × its node's largest datum is rounding


class MinNormDirection(DirectionSolver):
    """The paper's direction; subclasses supply the batched min-norm QP solver.

    By default a solve with it starts on coarse grids ("auto"): a first-order step is
    cut short by every node near a kink, and a coarse solution starts the fine grid with
    its kinks already settled, so the iteration count stays flat in N.
    """

    default_continuation: ClassVar[str] = "auto"
    # first order: carried on with ε and δ shrinking, paper-7.1 is certified after 4726 iterations
    certified_max_iter: ClassVar[int] = 5000

    @abstractmethod
    def min_norm(
        self, center: np.ndarray, generators: np.ndarray, mask: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Minimum-norm points of a batch of simplex sums.

        Solves, for every row b, min ‖center_b + Σ_g Σ_p λ_bgp generators_bgp‖ with
        λ_bg in the unit simplex over the entries where mask_bg is True.
        center: (B, d); generators: (B, G, m, d); mask: (B, G, m), each group with
        at least one True. Returns the points (B, d) and the weights λ (B, G, m).
        """

    def compute(self, functional: "Functional", xi: np.ndarray, delta: float) -> Direction:
        return self.from_quasidifferential(functional.quasidifferential(xi, delta), functional.weights)

    def from_quasidifferential(self, qd: Quasidifferential, weights: np.ndarray) -> Direction:
        """Solve (maxmin) at every node: one batched min-norm call over nodes × vertices."""
        vertices, valid = qd.sup.vertices()  # w ∈ B_k: (N, V, d)
        nodes, count, dim = vertices.shape
        sub = qd.sub
        groups, width = sub.generators.shape[1:3]
        center = (sub.center[:, None, :] + vertices).reshape(nodes * count, dim)
        generators = np.broadcast_to(
            sub.generators[:, None], (nodes, count, groups, width, dim)
        ).reshape(nodes * count, groups, width, dim)
        mask = np.broadcast_to(sub.mask[:, None], (nodes, count, groups, width)).reshape(
            nodes * count, groups, width
        )
        points, _ = self.min_norm(center, generators, mask)
        distance = np.linalg.norm(points, axis=1).reshape(nodes, count)
        distance = np.where(valid, distance, -np.inf)
        worst = np.argmax(distance, axis=1)  # the worst vertex of −B_k
        rows = np.arange(nodes)
        step = -points.reshape(nodes, count, dim)[rows, worst]
        # an entry at the rounding of its node's data is 0 in exact arithmetic (a coordinate where
        # the point sits on a kink, e.g. x1 of |x1| at x1 = 0): kept, its |g|·|generator| in the
        # directional derivative outweighs ‖G‖² once ‖G‖ ≲ 1e-8, and G ascends (paper-7.1 at ε = 1e-8)
        scale = np.maximum(np.abs(center).reshape(nodes, count, dim).max(axis=(1, 2)),
                           np.abs(generators).reshape(nodes, -1).max(axis=1, initial=0.0) if generators.size else 0.0)
        step = np.where(np.abs(step) <= ROUNDING * scale[:, None], 0.0, step)
        deviation = distance[rows, worst]
        return Direction(step=step, deviation=deviation, slope=qd.directional_derivative(step, weights))


def with_options(solver: DirectionSolver, options: dict[str, str]) -> DirectionSolver:
    """A copy of `solver` with public dataclass fields set from text (the CLI's
    ``--option KEY=VALUE``): each value is parsed as the field's current type (bool,
    int, float or str), then the options are checked against their ranges
    (:meth:`DirectionSolver.check_options`). An unknown key (with the close ones), a value
    of the wrong form or out of range is an InputError naming the option and its range."""
    if not options:
        return solver
    scalar = (bool, int, float, str, type(None))
    fields = {f.name: getattr(solver, f.name) for f in dataclasses.fields(solver)
              if f.init and not f.name.startswith("_") and isinstance(getattr(solver, f.name), scalar)} \
        if dataclasses.is_dataclass(solver) else {}
    values = {}
    label = getattr(solver, "label", solver.name)
    for key, text in options.items():
        if key not in fields:
            close = close_names(key, list(fields))
            form = (f"KEY=VALUE with KEY one of: {', '.join(fields)}" + (f" (did you mean {close[0]}?)" if close else "")
                    if fields else f"no options (direction {label!r} has none)")
            raise InputError("--option", form, f"{key}={text}")
        current = fields[key]
        kind = type(current) if isinstance(current, (bool, int, float, str)) else None
        try:
            if kind is bool:
                if text.lower() not in ("true", "false", "1", "0"):
                    raise ValueError
                values[key] = text.lower() in ("true", "1")
            elif kind is None:
                values[key] = None if text.lower() == "none" else _number(text)
            else:
                values[key] = kind(text)
        except ValueError:
            expected = {bool: "true or false", int: "an integer", float: "a number", str: "text"}.get(kind, "a number or none")
            raise InputError("--option", f"{key}=<{expected}>", f"{key}={text}") from None
    try:
        changed = dataclasses.replace(solver, **values)
        changed.check_options()  # a dataclass without __post_init__ checks here
    except OptionError as exc:  # the range, as the command line spells the option
        given = f"{exc.key}={options[exc.key]}" if exc.key in options else ", ".join(f"{k}={v}" for k, v in options.items())
        raise InputError("--option", f"{exc.key}=<{exc.expected}> for direction {label!r}", given) from None
    return changed


def _number(text: str) -> int | float:
    try:
        return int(text)
    except ValueError:
        return float(text)
