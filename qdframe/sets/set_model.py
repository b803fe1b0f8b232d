"""SetModel and define_model: an InclusionModel written with sets of formulas."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import sympy as sp

from ..errors import InputError
from ..model import Cost, InclusionModel, SetBlock, Surface
from ..registry import plugin_code
from .compiler import Compiled, compile_sets


NUMERIC_ON_SYMBOL = ("loop of ufunc does not support argument", "Cannot convert expression to float")
"""What NumPy's ufuncs and the math module say when given a SymPy symbol (np.sin(θ), math.exp(θ))."""


def _names(value: Any) -> tuple[str, ...]:
    return tuple(value.replace(",", " ").split()) if isinstance(value, str) else tuple(value)


class SetModel(InclusionModel):
    """An :class:`~qdframe.model.InclusionModel` written with sets of formulas.

    Class attributes as for InclusionModel, plus:

    - ``state_names`` / ``control_names`` may be one string, ``"x1 x2"``;
    - ``default_xT = {"x2": 1.0}`` fixes x_j(T) by name (instead of ``end_indices`` and
      ``default_end_values``); ``periodic`` may name its states, ``("x1", "x2")``;
    - ``penalty``: λ of the objective ∫cost + λ·I when there is a running cost.

    - ``parameter_names`` may be one string, ``"mu"``: unknown constants found with x
      (:mod:`qdframe.unknowns`), with ``default_parameters`` their starting guesses.

    Implement :meth:`sets`; optionally :meth:`surface_equations` and :meth:`running_cost`.
    Each receives the states, then the parameters, then the controls as SymPy symbols, in order. The sets
    are compiled once per class (on first use), so they may use class attributes
    (parameters) but not per-instance state.
    """

    state_names: ClassVar[Any] = ()
    control_names: ClassVar[Any] = ()
    default_xT: ClassVar[Mapping[str, float] | None] = None
    penalty: ClassVar[float] = 1.0

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls.state_names = _names(cls.state_names)
        cls.control_names = _names(cls.control_names)
        cls.parameter_names = _names(cls.parameter_names)
        if "periodic" in cls.__dict__:  # names or indices
            cls.periodic = tuple(cls.state_names.index(c) if isinstance(c, str) and c in cls.state_names else c
                                 for c in cls.periodic)
        if "default_xT" in cls.__dict__ and cls.default_xT is not None:
            names = list(cls.state_names)
            missing = [k for k in cls.default_xT if k not in names]
            if missing:
                raise InputError(f"{cls.__name__}.default_xT", f"state names ({', '.join(names)})", ", ".join(missing))
            cls.end_indices = tuple(names.index(k) for k in cls.default_xT)
            cls.default_end_values = tuple(float(v) for v in cls.default_xT.values())
        if not cls.__dict__.get("name"):
            cls.name = cls.__name__
        if not cls.__dict__.get("description") and cls.__doc__:
            cls.description = cls.__doc__.strip().splitlines()[0]

    # -- what an author writes
    def sets(self, *symbols: sp.Symbol) -> Mapping[Any, Any]:
        """{x_i: F_i} for x_i' ∈ F_i (a set or a formula), {(x_i, x_j): F} for an S_2 block."""
        raise NotImplementedError(f"{type(self).__name__}.sets")

    def surface_equations(self, *symbols: sp.Symbol) -> Any:
        """e(x) = 0 as one formula or a list of formulas in the states; None: no surface."""
        return None

    def running_cost(self, *symbols: sp.Symbol) -> Any:
        """The cost integrand (smooth terms, c·|e|, c·Max(…), c·Min(…)); None: no cost."""
        return None

    def terminal_cost(self, *states: sp.Symbol) -> Any:
        """A terminal (Mayer) cost M(x(T)): a smooth formula of the states; None: none."""
        return None

    # -- the InclusionModel interface
    @classmethod
    def symbols(cls) -> tuple[tuple[sp.Symbol, ...], tuple[sp.Symbol, ...]]:
        """The states (then the parameters, if any) and the controls as real SymPy symbols."""
        return (tuple(sp.Symbol(n, real=True) for n in (*cls.state_names, *cls.parameter_names)),
                tuple(sp.Symbol(n, real=True) for n in cls.control_names))

    def compiled(self) -> Compiled:
        cls = type(self)
        cached = cls.__dict__.get("_compiled_sets")
        if cached is None:
            states, controls = cls.symbols()  # the parameters are constant states here: p' = 0
            args = states + controls
            with plugin_code(self, "sets()"):
                try:
                    sets = self.sets(*args)
                except TypeError as exc:  # np.sin(θ), math.exp(θ): functions of numbers, given a SymPy symbol
                    if "positional argument" in str(exc):  # a signature without the parameters (or controls)
                        raise InputError(f"{cls.__name__}.sets()", "a method of the states, then the parameters, then "
                                         f"the controls: sets(self, {', '.join(map(str, args))})", str(exc)) from exc
                    if not any(text in str(exc) for text in NUMERIC_ON_SYMBOL):
                        raise
                    raise InputError(f"{cls.__name__}.sets()", "formulas of SymPy functions of the symbols "
                                     "(from sympy import sin, cos, exp; Abs, Min, Max, sqrt from qdframe.sets): "
                                     "NumPy's and math's functions take numbers, not symbols",
                                     f"{type(exc).__name__}: {exc}") from exc
            if not isinstance(sets, Mapping):  # one set returned bare: whose state's is it?
                names = ", ".join(map(str, states[: len(cls.state_names)]))
                raise InputError(f"{cls.__name__}.sets()", "a dict from each state, or a tuple of states for a "
                                 f"set in several ({{(x1, x2): Ball(...)}}), to its set or formula, over ({names})",
                                 type(sets).__name__)
            with plugin_code(self, "surface_equations()"):
                surface = self.surface_equations(*args)
            with plugin_code(self, "running_cost()"):
                cost = self.running_cost(*args)
            terminal = None
            if cls.terminal_cost is not SetModel.terminal_cost:
                with plugin_code(self, "terminal_cost()"):
                    terminal = self.terminal_cost(*states[: len(cls.state_names)])
            if cls.parameter_names:
                sets = {**sets, **{symbol: 0 for symbol in states[len(cls.state_names):]}}
            cached = compile_sets(sets, states, controls, surface=surface, cost=cost,
                                  weight=float(cls.penalty), model=cls.name or cls.__name__, terminal=terminal,
                                  n_states=len(cls.state_names))
            cls._compiled_sets = cached  # type: ignore[attr-defined]
        return cached

    def blocks(self) -> tuple[SetBlock, ...]:
        """The states' blocks (the parameters' p' = 0 are :mod:`qdframe.unknowns`' to add)."""
        return tuple(block for block in self.compiled().blocks if max(block.coords) < self.n_states)

    def surface(self) -> Surface | None:
        return self.compiled().surface

    def cost(self) -> Cost | None:
        return self.compiled().cost


def define_model(
    name: str,
    states: str | Sequence[str],
    sets: Callable[..., Mapping[Any, Any]],
    *,
    x0: Sequence[float],
    xT: Mapping[str, float] | None = None,
    T: float = 1.0,
    controls: str | Sequence[str] = (),
    surface: Callable[..., Any] | None = None,
    cost: Callable[..., Any] | None = None,
    penalty: float = 1.0,
    description: str = "",
) -> type[SetModel]:
    """A SetModel subclass from functions of the symbols (for scripts and notebooks)."""
    namespace: dict[str, Any] = {
        "name": name, "description": description, "state_names": states, "control_names": controls,
        "default_x0": tuple(x0), "default_T": T, "default_xT": dict(xT or {}), "penalty": penalty,
        "sets": lambda self, *a: sets(*a),
    }
    if surface is not None:
        namespace["surface_equations"] = lambda self, *a: surface(*a)
    if cost is not None:
        namespace["running_cost"] = lambda self, *a: cost(*a)
    cls_name = "".join(part.capitalize() for part in name.replace(".", "-").replace("_", "-").split("-")) or "Model"
    return type(cls_name, (SetModel,), namespace)
