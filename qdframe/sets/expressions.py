"""The formulas of the set language: checks, text, the symbols ψ and support-function formulas.

A set's data are SymPy formulas in y = (x, u). Pieces must be continuously
differentiable (paper (supf)/(subf)): :func:`_smooth` refuses |·|, max, min, sign, …
and says where they belong instead. ψ ∈ S_k are the dummy symbols :func:`_psi`.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np
import sympy as sp

from ..errors import InputError

_NONSMOOTH = (sp.Abs, sp.Max, sp.Min, sp.sign, sp.Heaviside, sp.Piecewise, sp.floor, sp.ceiling)


class SetStructureError(InputError):
    """A set whose support function is not of the paper's form Σ max + Σ min (+ sign terms)."""


def norm1(*terms: Any) -> sp.Expr:
    """|t_1| + … + |t_n| (the paper's |x| in Section 5 and Example 7.3); accepts one sequence too."""
    if len(terms) == 1 and isinstance(terms[0], (list, tuple)):
        terms = tuple(terms[0])
    return sp.Add(*(sp.Abs(_expr(t, "norm1")) for t in terms))


def _expr(value: Any, where: str) -> sp.Expr:
    if getattr(value, "is_set", False):  # a Set (qdframe.sets.algebra, which builds on this module)
        raise SetStructureError(where, "a formula (a number or a SymPy expression), not a set", value.label)
    try:
        out = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError):
        try:
            out = sp.Float(float(value))
        except (TypeError, ValueError):
            raise SetStructureError(where, "a number or a SymPy expression", value) from None
    if not isinstance(out, sp.Expr) or out.is_real is False:
        raise SetStructureError(where, "a real scalar formula", value)
    return out


def _smooth(value: Any, where: str) -> sp.Expr:
    expr = _expr(value, where)
    bad = [f for f in _NONSMOOTH if expr.has(f)]
    if bad:
        raise SetStructureError(
            where,
            "a continuously differentiable formula (paper (supf)/(subf)); |e| = max{e, −e} belongs in a set: "
            "Abs(e)*Interval(-1, 1) is the hull of {e, −e}, Interval(lo, hi) has the kink of its own width",
            _s(expr),
        )
    _refuse_singular(expr, where)
    return expr


NORM_HINT = ("a Euclidean norm |v| = sqrt(v1² + v2²) is not C¹ at v = 0 and v/|v| is undefined there (the "
             "sticking state of friction): Filippov's v/|v| is the vector sign Sgn(v1, v2), the closed unit ball "
             "at v = 0 — S = Sgn(v1, v2), then {v1: f1 - mu*S[0], v2: f2 - mu*S[1]}")


def singular_power(expr: sp.Expr) -> sp.Expr | None:
    """A power b^e in `expr` that is not continuously differentiable (or not defined) where its
    base vanishes — a fractional exponent e < 1 (sqrt, 1/sqrt, cube roots) of a base that is not
    provably positive — or None. sqrt(x1² + 3) is fine; sqrt(v1² + v2²) (|v|) and
    v1/sqrt(v1² + v2²) (v/|v|) are not."""
    for power in sorted(sp.preorder_traversal(expr), key=sp.default_sort_key):
        if not isinstance(power, sp.Pow):
            continue
        base, exponent = power.args
        if not exponent.is_number or exponent.is_integer or not base.free_symbols:
            continue
        if float(exponent) < 1 and base.is_positive is not True:
            return power
    return None


def _refuse_singular(expr: sp.Expr, where: str) -> None:
    """A formula with a :func:`singular_power` is an error naming it and pointing to Sgn(v1, v2)."""
    power = singular_power(expr)
    if power is not None:
        raise SetStructureError(
            where,
            f"a continuously differentiable formula (paper (supf)/(subf)), but {_s(power)} is not C¹ (or not "
            f"defined) where {_s(power.args[0])} = 0; {NORM_HINT}",
            _s(expr),
        )


def _vector(value: Any, where: str, smooth: bool = True) -> tuple[sp.Expr, ...]:
    items = tuple(value) if isinstance(value, (list, tuple, np.ndarray, sp.Matrix)) else (value,)
    check = _smooth if smooth else _expr
    return tuple(check(v, where) for v in items)


def _s(expr: Any) -> str:
    """A formula as text, floats short (0.3, not 0.300000000000000)."""
    return sp.sstr(expr, full_prec=False)


def _text(values: Sequence[sp.Expr]) -> str:
    return _s(values[0]) if len(values) == 1 else "(" + ", ".join(map(_s, values)) + ")"


@lru_cache(maxsize=None)
def _psi(k: int) -> tuple[sp.Symbol, ...]:
    """The symbols of ψ ∈ S_k (ψ = ±1 for k = 1)."""
    return tuple(sp.Dummy(f"psi{j + 1}", real=True) for j in range(k))


def _norm(psi: Sequence[sp.Expr]) -> sp.Expr:
    return sp.sqrt(sp.Add(*(p**2 for p in psi)))


def _dot(a: Sequence[sp.Expr], b: Sequence[sp.Expr]) -> sp.Expr:
    return sp.Add(*(u * v for u, v in zip(a, b)))


def _segment_formula(a: Sequence[sp.Expr], b: Sequence[sp.Expr], psi: Sequence[sp.Expr]) -> sp.Expr:
    """c(co{a, b}, ψ) = ⟨(a + b)/2, ψ⟩ + |⟨(b − a)/2, ψ⟩| (for k = 1: mid·ψ + |hi − lo|/2)."""
    mid = [(u + v) / 2 for u, v in zip(a, b)]
    half = [(v - u) / 2 for u, v in zip(a, b)]
    if len(psi) == 1:
        return mid[0] * psi[0] + sp.Abs(half[0]) * _norm(psi)
    return _dot(mid, psi) + sp.Abs(_dot(half, psi))
