"""The compiler: a model's sets, surface and cost to qdframe's low-level pieces.

Each set's normal form (:class:`~qdframe.sets.algebra._Support`) becomes a
:class:`~qdframe.model.SetBlock`: polytopes are max-groups, ψ-formulas min-groups, sign
terms :class:`~qdframe.model.SignTerm`. Gradients are derived by SymPy and lambdified to
NumPy once, so every piece is evaluated for all nodes at once.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import sympy as sp

from ..errors import InputError
from ..model import BallSwitch, Cost, MaxGroup, MinGroup, SetBlock, SignTerm, Surface
from .algebra import _NotHere, _Support, as_set
from .primitives import BallArgument, WholeVectorSign
from .expressions import _NONSMOOTH, SetStructureError, _expr, _psi, _refuse_singular, _s, _smooth, _vector


def _scalar_groups(expr: sp.Expr, where: str, allow_min: bool) -> tuple[list[list[sp.Expr]], list[list[sp.Expr]]]:
    """expr = Σ max-groups + Σ min-groups: smooth terms (one piece), c·|e|, c·Max(…), c·Min(…)."""
    terms = sp.Add.make_args(sp.expand(expr, deep=False))
    smooth: list[sp.Expr] = []
    maxes: list[list[sp.Expr]] = []
    mins: list[list[sp.Expr]] = []
    allowed = "smooth terms, c·|e| and c·Max(e_1, …)" + (", c·Min(e_1, …)" if allow_min else " with c > 0")
    for term in terms:
        if not any(term.has(f) for f in _NONSMOOTH):
            _refuse_singular(term, where)
            smooth.append(term)
            continue
        coeff, rest = term.as_coeff_Mul()
        if isinstance(rest, sp.Abs):
            args = [rest.args[0], -rest.args[0]]
            kind = "max" if coeff > 0 else "min"
        elif isinstance(rest, sp.Max):
            args, kind = list(rest.args), "max" if coeff > 0 else "min"
        elif isinstance(rest, sp.Min):
            args, kind = list(rest.args), "min" if coeff > 0 else "max"
        else:
            raise SetStructureError(where, f"a sum of {allowed} (paper (supf)/(subf))", str(term))
        for a in args:
            _smooth(a, f"{where}: argument of {rest.func.__name__}")
        if kind == "min" and not allow_min:
            raise SetStructureError(where, f"an amplitude ≥ 0: a sum of {allowed}", str(term))
        (maxes if kind == "max" else mins).append([coeff * a for a in args])
    if smooth:
        maxes.insert(0, [sp.Add(*smooth)])
    return maxes, mins


# ---------------------------------------------------------------- lambdification
class _Vectorized:
    """Values and y-gradients of formulas, lambdified once and evaluated for all nodes at once."""

    def __init__(self, exprs: Sequence[sp.Expr], symbols: Sequence[sp.Symbol], psi: Sequence[sp.Symbol] = ()) -> None:
        self.count = len(exprs)
        self.width = len(symbols)
        self.psi = tuple(psi)
        self.exprs, self.symbols = tuple(exprs), tuple(symbols)
        grads = [[sp.diff(e, s) for s in symbols] for e in exprs]
        self.entries = [(q, j) for q in range(self.count) for j in range(self.width) if grads[q][j] != 0]
        outputs = list(exprs) + [grads[q][j] for q, j in self.entries]
        self.function = sp.lambdify(list(symbols) + list(self.psi), outputs, modules="numpy", cse=True)
        self.values_function = sp.lambdify(list(symbols) + list(self.psi), list(exprs), modules="numpy", cse=True)

    def __call__(self, y: np.ndarray, psi: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        rows = y.shape[0]
        out = self._evaluate(self.function, y, psi)
        values = self._values(out, rows)
        grads = np.zeros((rows, self.count, self.width))
        for (q, j), value in zip(self.entries, out[self.count :]):
            grads[:, q, j] = value
        return values, grads

    def formulas(self, symbols: Sequence[sp.Symbol], psi: Sequence[Any] = ()) -> list[sp.Expr]:
        """The values as formulas of other `symbols` for y (and `psi`, symbols or numbers, for ψ):
        the pieces' `formulas` hook (:mod:`qdframe.certificates.model_system` compiles a whole model from them)."""
        mapping = dict(zip(self.symbols, symbols)) | dict(zip(self.psi, psi))
        return [sp.sympify(e).xreplace(mapping) for e in self.exprs]

    def values(self, y: np.ndarray, psi: np.ndarray | None = None) -> np.ndarray:
        """The values of __call__ alone, without computing the gradients."""
        return self._values(self._evaluate(self.values_function, y, psi), y.shape[0])

    def _evaluate(self, function: Callable, y: np.ndarray, psi: np.ndarray | None) -> list:
        args = [y[:, i] for i in range(self.width)]
        if self.psi:
            args += [psi[:, j] for j in range(len(self.psi))]  # type: ignore[index]
        with np.errstate(all="ignore"):  # NaN/inf are reported by the functional's checks
            return function(*args)

    def _values(self, out: list, rows: int) -> np.ndarray:
        values = np.empty((rows, self.count))
        for q in range(self.count):
            values[:, q] = out[q]
        return values


def _max_pieces(vertices: list[tuple[sp.Expr, ...]], symbols) -> Callable:
    k = len(vertices[0])
    flat = _Vectorized([v for vertex in vertices for v in vertex], symbols)
    m = len(vertices)

    def pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values, grads = flat(y)
        return values.reshape(-1, m, k), grads.reshape(-1, m, k, flat.width)

    return _with_formulas(pieces, flat)


def _with_formulas(function: Callable, vectorized: _Vectorized) -> Callable:
    """`function` with the `formulas` hook of the lambdified formulas it evaluates."""
    function.formulas = vectorized.formulas  # type: ignore[attr-defined]
    return function


def _min_group(formulas: list[sp.Expr], symbols, dim: int, label: str) -> MinGroup:
    vectorized = _Vectorized(formulas, symbols, _psi(dim))
    return MinGroup(_with_formulas(lambda y, psi: vectorized(y, psi), vectorized), label, values=vectorized.values)


def _hessian(expr: sp.Expr, symbols) -> Callable[[np.ndarray], np.ndarray] | None:
    """∇²c(y) (N, w, w) of a smooth cost integrand, or None where it is affine (no curvature)."""
    gradient = [sp.diff(expr, s) for s in symbols]
    if all(sp.diff(g, s) == 0 for g in gradient for s in symbols):
        return None
    vectorized = _Vectorized(gradient, symbols)
    return lambda y: vectorized(y)[1]


def _terminal(expr: Any, states: tuple, model: str) -> Callable[[np.ndarray], tuple[float, np.ndarray, np.ndarray]]:
    """M(x), ∇M and ∇²M at one state x (n,) from a formula of the states."""
    formula = _expr(expr, f"{model} terminal cost")
    extra = formula.free_symbols - set(states)
    if extra:
        raise InputError(f"{model} terminal_cost()", f"a formula in the states {', '.join(map(str, states))}",
                         ", ".join(sorted(map(str, extra))))
    if formula.has(sp.Abs, sp.Max, sp.Min, sp.sign):
        raise InputError(f"{model} terminal_cost()", "a smooth formula of the states (no Abs, Max, Min)", formula)
    value = _Vectorized([formula], states)
    gradient = _Vectorized([sp.diff(formula, s) for s in states], states)

    def terminal(x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        point = np.asarray(x, float)[None, :]
        grad, hess = gradient(point)
        return float(value.values(point)[0, 0]), grad[0], hess[0]

    return terminal


def _scalar_pieces(exprs: list[sp.Expr], symbols) -> Callable:
    vectorized = _Vectorized(exprs, symbols)
    return _with_formulas(lambda y: vectorized(y), vectorized)


SAME_SWITCH_RTOL = 1e-12  # coefficient ratios equal to this: two switches are one surface


class _Switches:
    """The distinct switching functions of one model: s(y) and ∇s, one callable per surface.

    Sign terms on one surface share one Filippov selection (:class:`~qdframe.model.SignTerm`),
    and Sgn(c·s) = sign(c)·Sgn(s) for every constant c ≠ 0, so a switch that is a constant
    multiple of one seen before (−s, 2s, or 0.866·v1 − 0.5·v2 against −0.866·v1 + 0.5·v2)
    is that one, with the sign of the multiple: :meth:`find` returns (callable, ±1). A vector
    switch (:meth:`find_ball`) is one with another up to a constant factor and a signed
    permutation of its components.
    """

    def __init__(self, symbols) -> None:
        self.symbols = tuple(symbols)
        self.known: list[tuple[dict, Callable]] = []
        self.balls: list[tuple[list[dict], BallSwitch]] = []  # vector switches: each component's coefficients

    def find(self, expr: sp.Expr) -> tuple[Callable, float]:
        terms = _coefficients(expr)
        for reference, switch in self.known:
            ratio = _ratio(terms, reference)
            if ratio is not None:
                return switch, 1.0 if ratio > 0 else -1.0
        switch = _switch_cached(sp.expand(expr), self.symbols)
        self.known.append((terms, switch))
        return switch, 1.0

    def find_ball(self, exprs: tuple[sp.Expr, ...]) -> tuple[BallSwitch, list[tuple[int, float]]]:
        """The :class:`~qdframe.model.BallSwitch` of the vector switch s = `exprs`, and for each of
        its components j the component of that switch's selection and the sign it enters with.
        One vector surface, one selection: s' = c·P·s for a constant c > 0 and a signed
        permutation P (Sgn(2·v), Sgn(−v) = −Sgn(v), Sgn(v2, v1)) is the switch s, and
        Sgn(s')_j = ±Sgn(s)_π(j)."""
        terms = [_coefficients(e) for e in exprs]
        for reference, switch in self.balls:
            if len(reference) != len(terms):
                continue
            mapping, scale = [], None
            for own in terms:
                found = [(i, _ratio(own, other)) for i, other in enumerate(reference)]
                found = [(i, r) for i, r in found if r is not None and i not in [m for m, _ in mapping]]
                if not found:
                    break
                i, ratio = found[0]
                if scale is None:
                    scale = abs(ratio)
                if abs(abs(ratio) - scale) > SAME_SWITCH_RTOL * scale:
                    break
                mapping.append((i, 1.0 if ratio > 0 else -1.0))
            else:
                return switch, mapping
        expanded = tuple(sp.expand(e) for e in exprs)
        vectorized = _Vectorized(list(expanded), self.symbols)
        switch = BallSwitch(_with_formulas(lambda y: vectorized(y), vectorized), len(expanded), f"Sgn({', '.join(_s(e) for e in expanded)})")
        self.balls.append((terms, switch))
        return switch, [(j, 1.0) for j in range(len(expanded))]


def _coefficients(expr: sp.Expr) -> dict:
    """{term without its numeric factor: the factor} of the expanded expression."""
    return {key: complex(value) for key, value in sp.expand(expr).as_coefficients_dict().items() if value != 0}


def _ratio(terms: dict, reference: dict) -> float | None:
    """c with terms = c·reference (the same keys, every coefficient ratio c to SAME_SWITCH_RTOL), or None."""
    if not terms or terms.keys() != reference.keys():
        return None
    ratios = [terms[key] / reference[key] for key in terms]
    c = ratios[0]
    if abs(c.imag) > 0 or c.real == 0:
        return None
    if all(abs(r - c) <= SAME_SWITCH_RTOL * abs(c) for r in ratios):
        return c.real
    return None


@lru_cache(maxsize=None)
def _switch_cached(expr: sp.Expr, symbols: tuple) -> Callable:
    vectorized = _Vectorized([expr], symbols)

    def switch(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values, grads = vectorized(y)
        return values[:, 0], grads[:, 0, :]

    return _with_formulas(switch, vectorized)


# ------------------------------------------------------------------- compilation
@dataclass(frozen=True)
class Compiled:
    """A model's sets, surface and cost as low-level qdframe objects."""

    blocks: tuple[SetBlock, ...]
    surface: Surface | None
    cost: Cost | None


def _sign_term(label: str, amplitude: sp.Expr, switch: sp.Expr, band: float, switches: _Switches,
               where: str) -> SignTerm:
    """a·Sgn(s) = |a|·Sgn(±s) as sense·|a|·Sgn(s0), s0 the model's switch that ±s is a
    constant multiple of (the first term on a surface has sense +1: its |a|·Sgn(±s) as written).
    A vector sign's component, a·λ_j with λ ∈ Sgn(s) ⊂ B: sense·|a|·λ_j on the shared
    :class:`~qdframe.model.BallSwitch` of s, sense the sign of a times that of the multiple."""
    amplitude = sp.sympify(amplitude)
    name = label if amplitude == 1 else f"({_s(amplitude)})·{label}" if amplitude.is_Add else f"{_s(amplitude)}·{label}"
    if isinstance(switch, BallArgument):
        ball, mapping = switches.find_ball(switch.switch)
        component, sense = mapping[switch.component]
        if amplitude.is_number:
            value: float | tuple = abs(float(amplitude))
            sense *= 1.0 if float(amplitude) >= 0 else -1.0
        else:
            terms = sp.Add.make_args(sp.expand(amplitude, deep=False))
            if all(t.as_coeff_Mul()[0] < 0 for t in terms):  # −a·λ_j: sense −1
                amplitude, sense = -amplitude, -sense
            maxes, _ = _scalar_groups(amplitude, f"{where}: amplitude of {label}", allow_min=False)
            value = tuple(_scalar_pieces(group, switches.symbols) for group in maxes)
        return SignTerm(value, ball, band, name, sense, component)
    negated = 1.0
    if amplitude.is_number:
        a = float(amplitude)
        value: float | tuple = abs(a)
        switch, negated = (switch, 1.0) if a >= 0 else (-switch, -1.0)
    else:
        terms = sp.Add.make_args(sp.expand(amplitude, deep=False))
        if all(t.as_coeff_Mul()[0] < 0 for t in terms):  # −a·Sgn(s) = a·Sgn(−s)
            amplitude, switch, negated = -amplitude, -switch, -1.0
        maxes, _ = _scalar_groups(amplitude, f"{where}: amplitude of {label}", allow_min=False)
        value = tuple(_scalar_pieces(group, switches.symbols) for group in maxes)
    callable_, sense = switches.find(switch)
    # sense·|a|·Sgn(s0) = a·Sgn(s) as written: the written Sgn(s)'s λ is negated·sense times the selection's
    return SignTerm(value, callable_, band, name, sense, written=negated * sense)


def compile_sets(
    sets: Mapping[Any, Any],
    states: Sequence[sp.Symbol],
    controls: Sequence[sp.Symbol] = (),
    surface: Any = None,
    cost: Any = None,
    weight: float = 1.0,
    model: str = "model",
    terminal: Any = None,
    n_states: int | None = None,
) -> Compiled:
    """Compile {state or tuple of states: set} (+ surface formulas, cost integrand, terminal
    cost of the first `n_states` states) to qdframe's pieces."""
    symbols = tuple(states) + tuple(controls)
    index = {s: i for i, s in enumerate(states)}
    switches = _Switches(symbols)
    blocks: list[SetBlock] = []
    for key, value in sets.items():
        keys = tuple(key) if isinstance(key, (tuple, list)) else (key,)
        coords = []
        for k in keys:
            k = sp.Symbol(k, real=True) if isinstance(k, str) else k
            if k not in index:
                raise InputError(f"{model}.sets", f"keys that are states ({', '.join(map(str, states))}) or tuples of them", k)
            coords.append(index[k])
        name = "F[" + ", ".join(str(states[c]) for c in coords) + "]"
        try:
            f = as_set(value)
        except SetStructureError as exc:  # a formula refused where it became a point: name the model and block
            raise SetStructureError(f"{model} {name} ({exc.field})", exc.expected, exc.got) from None
        if f.dim != len(coords):
            hint = (f"; a vector sign Sgn(v1, …) is a set in R^{f.dim}: use its coordinates, S = {f.label} and "
                    f"S[0], S[1], … in one-coordinate blocks, or the whole in a block of {f.dim} coordinates"
                    if _has_vector_sign(f) else "")
            raise SetStructureError(f"{model} {name} = {f.label}", f"a set in R^{len(coords)}{hint}",
                                    f"a set in R^{f.dim}")
        if len(coords) > 1 and _has_vector_sign(f):  # a vector sign: one block per coordinate, λ shared
            for i, c in enumerate(coords):
                try:
                    part = f.component(i)
                except _NotHere as exc:
                    raise SetStructureError(
                        f"{model} {name} = {f.label}",
                        "with a vector sign, a block of several coordinates whose coordinates are sets of their own "
                        "(a point plus scalings of Sgn(v1, …), boxes): or write each coordinate's set, "
                        "{v1: f1 - mu*S[0], v2: f2 - mu*S[1]} with S = Sgn(v1, v2)", exc.what) from None
                blocks.append(_compile_block(part, (c,), f"F[{states[c]}]", symbols, switches, model))
            continue
        blocks.append(_compile_block(f, tuple(coords), name, symbols, switches, model))
    compiled_surface = None
    if surface is not None:
        formulas = _vector(surface, f"{model} surface")
        extra = set().union(*(e.free_symbols for e in formulas)) - set(states)
        if extra:
            raise InputError(f"{model} surface", f"formulas in the states {', '.join(map(str, states))}",
                             ", ".join(sorted(map(str, extra))))
        vectorized = _Vectorized(list(formulas), tuple(states))
        compiled_surface = Surface(lambda x: vectorized(x))
    compiled_cost = None
    if cost is None and terminal is not None:
        cost = sp.Integer(0)  # a terminal cost alone: a zero integrand
    if cost is not None:
        maxes, mins = _scalar_groups(_expr(cost, f"{model} cost"), f"{model} cost", allow_min=True)
        smooth = len(maxes) == 1 and len(maxes[0]) == 1 and not mins  # one formula: its Hessian models it
        compiled_cost = Cost(
            tuple(_scalar_pieces(g, symbols) for g in maxes), tuple(_scalar_pieces(g, symbols) for g in mins), weight,
            hessian=_hessian(maxes[0][0], symbols) if smooth else None,
            terminal=None if terminal is None else _terminal(terminal, tuple(states)[: n_states or len(states)], model),
        )
    return Compiled(tuple(blocks), compiled_surface, compiled_cost)


def _compile_block(f, coords: tuple[int, ...], name: str, symbols: tuple, switches: _Switches, model: str) -> SetBlock:
    """One block's set in its normal form as a :class:`~qdframe.model.SetBlock`."""
    support = f.support().merged()
    used = set().union(*(e.free_symbols for e in _all_exprs(support))) if _all_exprs(support) else set()
    psi_used = {s for s in used if s in _psi(f.dim)}
    unknown = used - set(symbols) - psi_used
    if unknown:
        raise InputError(f"{model} {name}", f"formulas in the states and controls {', '.join(map(str, symbols))}",
                         ", ".join(sorted(map(str, unknown))))
    if support.signs and f.dim != 1:
        raise SetStructureError(f"{model} {name}", "Sgn terms only in one-coordinate blocks")
    max_groups = tuple(MaxGroup(_max_pieces(vs, symbols), label) for label, vs in support.polytopes)
    min_groups = tuple(_min_group(gs, symbols, f.dim, label) for label, gs in support.mins)
    signs = tuple(_sign_term(label, a, s, band, switches, f"{model} {name}") for label, a, s, band in support.signs
                  if sp.sympify(a) != 0)  # 0·Sgn(s) (a coefficient set to 0): no term, no selection to leave free
    return SetBlock(coords, max_groups, min_groups, name, signs)


def _has_vector_sign(f) -> bool:
    """Whether a set's normal form holds a whole vector sign (a block of several coordinates to split)."""
    return any(isinstance(s, WholeVectorSign) for _, _, s, _ in f.support().signs)


def _all_exprs(support: _Support) -> list[sp.Expr]:
    out = [v for _, vs in support.polytopes for vertex in vs for v in vertex]
    out += [g for _, gs in support.mins for g in gs]
    for _, a, s, _ in support.signs:
        out.append(sp.sympify(a))
        out += list(s.switch) if isinstance(s, BallArgument) else list(s.sign.switch) if isinstance(s, WholeVectorSign) \
            else [s]
    return out
