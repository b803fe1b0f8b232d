"""Stewart's form of a switched field, as nosnoc states it: modes f_σ and switching functions c.

A field that is f_σ(x) in the region where the switching functions c_1, …, c_k have the signs
σ ∈ {−1, +1}^k (nosnoc's F with its sign matrix S and c) is, in Filippov's sense, the convex
hull of the modes active at x. With one switching function that is

    x' ∈ (f₊ + f₋)/2 + (f₊ − f₋)/2·Sgn(c),

the exact sign term of the set language, and with k the multilinear expansion

    Σ_σ f_σ·Π_i (1 + σ_i·λ_i)/2 = Σ_A a_A·Π_{i∈A} λ_i,   a_A = 2^−k·Σ_σ f_σ·Π_{i∈A} σ_i,   λ_i ∈ Sgn(c_i),

whose terms with one λ are sign terms a_i·Sgn(c_i). Where every a_A with two or more λ's is 0
(each state's modes differ along one switching function at a time: friction on several
contacts, one relay per input), the field is exactly g + Σ_i a_i·Sgn(c_i), and its Filippov
set at any x, the hull of the active modes, is the box g + Σ_i a_i·[−1, 1] on the active
switches (a parallelotope is the hull of its vertices): :func:`Modes` compiles to that, each
a_i·Sgn(c_i) whose a_i is a formula as max(a_i, 0)·Sgn(c_i) − max(−a_i, 0)·Sgn(c_i) (one
selection, each amplitude ≥ 0 as a sign term's must be, whatever the sign of f₊ − f₋). A
product of selections is not in the set language: a field whose modes need one (nosnoc's
codim-2 stick-slip example, whose fourth mode alone adds x0·(x1 + 0.8)·(x2 + 0.6) to x0') is
refused, naming the state and the switching functions.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import sympy as sp

from .expressions import SetStructureError, _s, _smooth
from .primitives import Sgn


def Modes(switches: Any, modes: Mapping[tuple[int, ...], Mapping[Any, Any]] | None = None, *,
          positive: Mapping[Any, Any] | None = None, negative: Mapping[Any, Any] | None = None) -> dict[Any, Any]:
    """The sets {state: F_state} of the switched field whose mode is `modes[σ]` where the
    switching functions `switches` have the signs σ (module docstring); each mode a mapping
    {state: formula} over the same states. One switching function: ``Modes(c, positive=f₊,
    negative=f₋)`` (f₊ where c > 0), or ``Modes(c, {(+1,): f₊, (−1,): f₋})``; k of them:
    ``Modes((c1, c2), {(−1, −1): f1, (−1, +1): f2, (+1, −1): f3, (+1, +1): f4})``, each of the
    2^k sign patterns given once (nosnoc's S, row by row). The result goes where ``sets``
    returns its dict, or merged into it (``{**Modes(...), other: ...}``)."""
    single = not isinstance(switches, (list, tuple))
    functions = [switches] if single else list(switches)
    if not functions:
        raise SetStructureError("Modes", "at least one switching function", switches)
    functions = [_smooth(c, "Modes switching function") for c in functions]
    table = _table(len(functions), modes, positive, negative)
    states = list(next(iter(table.values())))
    for sigma, mode in table.items():
        if list(mode) != states and set(mode) != set(states):
            raise SetStructureError(f"Modes mode {sigma}", f"the same states as the others ({', '.join(map(str, states))})",
                                    ", ".join(map(str, mode)))
    k = len(functions)
    out: dict[Any, Any] = {}
    for state in states:
        values = {sigma: _smooth(mode[state], f"Modes mode {sigma}, {state}'") for sigma, mode in table.items()}
        field: Any = sp.simplify(sum(values.values()) / 2**k)
        for size in range(1, k + 1):
            for chosen in itertools.combinations(range(k), size):
                coefficient = sp.simplify(sum(value * sp.Mul(*(sigma[i] for i in chosen))
                                              for sigma, value in values.items()) / 2**k)
                if coefficient == 0:
                    continue
                if size > 1:
                    raise SetStructureError(
                        f"Modes: {state}'", "modes that differ along one switching function at a time (a product "
                        "of sign terms is not in the set language)",
                        f"a term {_s(coefficient)}·" + "·".join(f"Sgn({_s(functions[i])})" for i in chosen))
                field = field + _signed(coefficient, functions[chosen[0]])
        out[state] = field
    return out


def _signed(amplitude: sp.Expr, switch: sp.Expr):
    """a·Sgn(c) with a sign term's amplitude ≥ 0 (the band's support function needs it): a constant as
    it is (a negative one is the sense −1), a formula as max(a, 0)·Sgn(c) − max(−a, 0)·Sgn(c), two terms on
    one switch and so one selection λ, which sum to a·λ whatever the sign of a (f₊ − f₋ of a friction law
    is negative; of a relay, positive)."""
    if amplitude.is_number:
        return amplitude * Sgn(switch)
    return sp.Max(amplitude, 0) * Sgn(switch) - sp.Max(-amplitude, 0) * Sgn(switch)


def _table(k: int, modes, positive, negative) -> dict[tuple[int, ...], Mapping[Any, Any]]:
    """{σ: mode} for the 2^k sign patterns, from `modes` or (k = 1) `positive`/`negative`."""
    if positive is not None or negative is not None:
        if modes is not None or k != 1 or positive is None or negative is None:
            raise SetStructureError("Modes", "positive= and negative= together, for one switching function, "
                                    "without a table of modes", "")
        modes = {(1,): positive, (-1,): negative}
    if not isinstance(modes, Mapping):
        raise SetStructureError("Modes modes", "a mapping {(±1, …): {state: formula}} of the sign patterns", modes)
    table = {}
    for sigma, mode in modes.items():
        pattern = (sigma,) if isinstance(sigma, int) and k == 1 else tuple(sigma) if isinstance(sigma, Sequence) else None
        if pattern is None or len(pattern) != k or any(s not in (1, -1) for s in pattern):
            raise SetStructureError("Modes sign pattern", f"a tuple of {k} signs ±1 (nosnoc's row of S)", sigma)
        if pattern in table:
            raise SetStructureError("Modes sign pattern", "each pattern once", sigma)
        if not isinstance(mode, Mapping) or not mode:
            raise SetStructureError(f"Modes mode {pattern}", "a mapping {state: formula}", mode)
        table[pattern] = mode
    missing = [sigma for sigma in itertools.product((1, -1), repeat=k) if sigma not in table]
    if missing:
        raise SetStructureError("Modes", f"a mode for each of the 2^{k} sign patterns", f"none for {missing[0]}")
    return table
