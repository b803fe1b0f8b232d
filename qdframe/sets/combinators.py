"""The combinators: Minkowski sum, hull (union), intersection and scaling (paper Section 5).

A sum adds the operands' groups; a hull of polytopes is one max-group of their vertices
(paper (supf)); an intersection is one min-group of its operands' ψ-formulas (paper
(subf), Remark 5.1); a scaling by a number scales (and for c < 0 flips) each group, and
|e|·A for a symmetric polytope A is co{±e·v}.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import sympy as sp

from .base import _MAX_VERTICES, Point, Set, _cartesian_sum, _NotHere, _role, _same_dim, _Support, as_set
from .expressions import _NONSMOOTH, SetStructureError, _expr, _psi, _refuse_singular, _s


class Sum(Set):
    """The Minkowski sum A + B + …: c = Σ c(A_i, ψ)."""

    def __init__(self, *sets: Set) -> None:
        flat: list[Set] = []
        for s in sets:
            flat.extend(s.sets if isinstance(s, Sum) else [s])
        self.sets = tuple(flat)
        self.dim = _same_dim(self.sets, " + ".join(s.label for s in self.sets))
        self.label = " + ".join(s.label for s in self.sets)

    def support(self):
        out = _Support(self.dim)
        for s in self.sets:
            part = s.support()
            out.polytopes += part.polytopes
            out.mins += part.mins
            out.signs += part.signs
        return out.merged()

    def polytope(self):
        return _cartesian_sum([_role(s, "polytope", self.label) for s in self.sets], self.label)

    def component(self, index: int) -> Set:
        return Sum(*(_role(s, "component", self.label, index) for s in self.sets))

    def formulas(self, psi):
        parts = [_role(s, "formulas", self.label, psi) for s in self.sets]
        if int(np.prod([len(p) for p in parts])) > 64:
            raise _NotHere("a sum of intersections with more than 64 combinations")
        return [sp.Add(*combo) for combo in itertools.product(*parts)]


class Hull(Set):
    """co(A ∪ B ∪ …) (paper Section 5, unions): c = max_i c(A_i, ψ), one max-group."""

    def __init__(self, *sets: Any) -> None:
        if not sets:
            raise SetStructureError("hull()", "at least one set")
        self.sets = tuple(as_set(s) for s in sets)
        self.dim = _same_dim(self.sets, "hull")
        self.label = "co{" + ", ".join(s.label.strip("{}") if isinstance(s, Point) else s.label for s in self.sets) + "}"
        vertices: list[tuple[sp.Expr, ...]] = []
        for s in self.sets:
            try:
                part = s.polytope()
            except _NotHere as exc:
                raise SetStructureError(
                    self.label,
                    "inside a hull/union only sets with finitely many vertices: Point, Interval, Box, hull, and their "
                    "sums and scalings — c = max_q ⟨f_q, ψ⟩ (paper (supf)); a max over a min of ψ-formulas "
                    "(an intersection, a Ball or an Ellipse) or over a sign term is not of the form "
                    f"Σ max + Σ min; here {s.label} is {exc.what}",
                ) from None
            vertices += [v for v in part if v not in vertices]
        if len(vertices) > _MAX_VERTICES:
            raise SetStructureError(self.label, f"at most {_MAX_VERTICES} vertices", len(vertices))
        self.vertices = vertices

    def polytope(self):
        return list(self.vertices)


def hull(*sets: Any) -> Set:
    """co(A_1 ∪ … ∪ A_m): its support function is max_i c(A_i, ψ) (paper Section 5)."""
    return Hull(*sets)


union = hull


class Intersection(Set):
    """A ∩ B ∩ … (paper Section 5, Remark 5.1): c̃ = min_i c(A_i, ψ), one min-group."""

    def __init__(self, *sets: Any) -> None:
        if not sets:
            raise SetStructureError("intersection()", "at least one set")
        flat: list[Set] = []
        for s in (as_set(s) for s in sets):
            flat.extend(s.sets if isinstance(s, Intersection) else [s])
        self.sets = tuple(flat)
        self.dim = _same_dim(self.sets, "intersection")
        self.label = " ∩ ".join(f"({s.label})" if isinstance(s, Sum) else s.label for s in self.sets)
        psi = _psi(self.dim)
        self.pieces: list[sp.Expr] = []
        for s in self.sets:
            try:
                self.pieces += s.formulas(psi)
            except _NotHere as exc:
                raise SetStructureError(
                    self.label,
                    "inside an intersection sets whose support function is one formula g(y, ψ) — Point, Interval, "
                    "Box, Ball, Ellipse, intersections, and their sums and constant scalings — "
                    "c̃ = min_p g_p(y, ψ) (paper (subf), Remark 5.1); "
                    f"here {s.label} is {exc.what}",
                ) from None

    def support(self):
        return _Support(self.dim, mins=[(self.label, list(self.pieces))])

    def polytope(self):
        raise _NotHere("an intersection (a min over ψ-formulas, paper (subf))")

    def formulas(self, psi):
        if tuple(psi) == _psi(self.dim):
            return list(self.pieces)
        mapping = dict(zip(_psi(self.dim), psi))
        return [g.xreplace(mapping) for g in self.pieces]


def intersection(*sets: Any) -> Set:
    """A_1 ∩ … ∩ A_m: the min-group min_i c(A_i, ψ) (paper (sf), Remark 5.1)."""
    return Intersection(*sets)


def minkowski_sum(*sets: Any) -> Set:
    """A_1 + … + A_m (formulas are points)."""
    return Sum(*(as_set(s) for s in sets))


class Scaled(Set):
    """factor · A: a number, or a formula of y (points scale; |e|·A for a symmetric A is co{±e·A})."""

    def __init__(self, inner: Set, factor: Any) -> None:
        self.inner = inner
        self.factor = _expr(factor, f"factor of {inner.label}")
        _refuse_singular(self.factor, f"factor of {inner.label}")  # |v|·A: not C¹ at v = 0
        self.dim = inner.dim
        text = _s(self.factor)
        self.label = f"-{inner.label}" if self.factor == -1 else f"({text})·{inner.label}" if len(text) > 8 else f"{text}·{inner.label}"
        self.support()  # validate now, at the line that builds the set

    # number c: c(cA, ψ) = |c|·c(A, sign(c)ψ)
    def _number(self) -> float | None:
        return float(self.factor) if self.factor.is_number else None

    def support(self):
        inner = self.inner.support()
        c = self.factor
        out = _Support(self.dim)
        if self._number() is not None:
            out.polytopes = [(f"{_s(c)}·{label}", [tuple(c * v for v in vertex) for vertex in vs]) for label, vs in inner.polytopes]
            out.mins = [(f"{_s(c)}·{label}", [_scale_formula(g, c, self.dim) for g in gs]) for label, gs in inner.mins]
            out.signs = [(label, c * a, s, band) for label, a, s, band in inner.signs]  # the compiler signs it
            return out.merged()
        if inner.mins:
            raise SetStructureError(
                self.label,
                "a state-dependent factor only on points, intervals, hulls, boxes and Sgn terms; scale a Ball, "
                "Ellipse or intersection by a number, or put the factor into its center and radius",
            )
        out.signs = [(label, c * a, s, band) for label, a, s, band in inner.signs]
        if not inner.polytopes or not any(c.has(f) for f in _NONSMOOTH):
            out.polytopes = [(f"{_s(c)}·{label}", [tuple(c * v for v in vertex) for vertex in vs]) for label, vs in inner.polytopes]
            return out.merged()
        # |e|·A for a symmetric polytope A = co{±e·v}: one max-group per term of the factor
        terms = _abs_terms(c, self.label)
        for label, vertices in inner.polytopes:
            if not _symmetric(vertices):
                raise SetStructureError(
                    self.label,
                    "a factor with |·| only on a symmetric set (vertices ±v, e.g. Interval(-1, 1)): |e|·co{±v} = co{±e·v}",
                    label,
                )
            for term in terms:
                out.polytopes.append((f"{_s(term)}·{label}", [tuple(_strip_abs(term) * v for v in vertex) for vertex in vertices]))
        return out.merged()

    def polytope(self):
        support = self.support()
        if support.mins or support.signs:
            raise _NotHere("not a polytope")
        return _cartesian_sum([vs for _, vs in support.polytopes], self.label)

    def component(self, index: int) -> Set:
        return Scaled(_role(self.inner, "component", self.label, index), self.factor)

    def formulas(self, psi):
        c = self._number()
        if c is None:
            return Set.formulas(self, psi)
        inner = _role(self.inner, "formulas", self.label, psi)
        mapping = {p: (1 if c >= 0 else -1) * p for p in psi}
        return [abs(c) * g.xreplace(mapping) for g in inner]


def _scale_formula(g: sp.Expr, c: sp.Expr, dim: int) -> sp.Expr:
    psi = _psi(dim)
    flip = {p: sp.sign(c) * p for p in psi}
    return sp.Abs(c) * g.xreplace(flip)


def _symmetric(vertices: list[tuple[sp.Expr, ...]]) -> bool:
    return all(any(all(sp.expand(a + b) == 0 for a, b in zip(v, w)) for w in vertices) for v in vertices)


def _abs_terms(factor: sp.Expr, where: str) -> list[sp.Expr]:
    """The terms c_i·|e_i| (c_i > 0) and positive numbers of a factor, or an error."""
    terms = sp.Add.make_args(sp.expand(factor, deep=False))
    negative = [t for t in terms if t.as_coeff_Mul()[0] < 0]
    if negative and len(negative) == len(terms):  # −Σ c|e|·A = Σ c|e|·A for a symmetric A
        terms = tuple(-t for t in terms)
    for term in terms:
        coeff, rest = term.as_coeff_Mul()
        ok = coeff > 0 and (rest == 1 or (isinstance(rest, sp.Abs) and not any(rest.args[0].has(f) for f in _NONSMOOTH)))
        if not ok:
            raise SetStructureError(
                where,
                "a factor with |·| of the form Σ c_i·|e_i| with c_i > 0 (plus numbers ≥ 0), e_i smooth",
                str(factor),
            )
    return list(terms)


def _strip_abs(term: sp.Expr) -> sp.Expr:
    coeff, rest = term.as_coeff_Mul()
    return coeff * (rest.args[0] if isinstance(rest, sp.Abs) else rest)
