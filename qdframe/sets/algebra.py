"""Set: the algebra every set of the language shares, the normal form it compiles from, and
the combinators its operators build (paper Section 5).

Each set has a support function of the paper's form Σ max-groups + Σ min-groups (+ sign
terms), :class:`_Support`; a set asked for a role it cannot take (the vertices of a ball,
one ψ-formula for a hull of three points) raises :class:`_NotHere`, which the
combinators turn into a :class:`~qdframe.sets.expressions.SetStructureError` naming the set.
A formula is the point :class:`Point`.

The combinators: a sum adds the operands' groups; a hull of polytopes is one max-group of
their vertices (paper (supf)); an intersection is one min-group of its operands'
ψ-formulas (paper (subf), Remark 5.1); a scaling by a number scales (and for c < 0 flips)
each group, and |e|·A for a symmetric polytope A is co{±e·v}. They live here with
:class:`Set`, whose operators build them.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from .expressions import (_NONSMOOTH, SetStructureError, _dot, _expr, _psi, _refuse_singular, _s, _segment_formula,
                          _text, _vector)

_MAX_VERTICES = 256  # a hull of sums multiplies vertex counts: refuse beyond this


class _NotHere(Exception):
    """Internal: a set that cannot take the role asked of it; `what` says what it is."""

    def __init__(self, what: str) -> None:
        super().__init__(what)
        self.what = what


@dataclass
class _Support:
    """The paper's form: Σ max-groups (polytopes: lists of vertices) + Σ min-groups + sign terms."""

    dim: int
    polytopes: list[tuple[str, list[tuple[sp.Expr, ...]]]] = field(default_factory=list)
    mins: list[tuple[str, list[sp.Expr]]] = field(default_factory=list)  # formulas in (y, ψ)
    signs: list[tuple[str, sp.Expr, sp.Expr, float]] = field(default_factory=list)  # label, amplitude, switch, band

    def merged(self) -> "_Support":
        """Single points summed into one (an exact equation is one piece)."""
        points = [(label, v[0]) for label, v in self.polytopes if len(v) == 1]
        if len(points) <= 1:
            return self
        others = [(label, v) for label, v in self.polytopes if len(v) > 1]
        total = tuple(sp.Add(*(p[i] for _, p in points)) for i in range(self.dim))
        return _Support(self.dim, [(" + ".join(label for label, _ in points), [total])] + others, self.mins, self.signs)


class Set:
    """A set-valued formula F(y) ⊂ R^k of the states and controls y = (x, u).

    Sets combine with ``+`` (Minkowski sum; a formula is a point), ``-``, ``*`` by a number
    or a formula, ``|`` (hull of the union) and ``&`` (intersection).
    """

    __array_ufunc__ = None  # numpy scalars defer to our operators
    is_set = True  # what a formula is not (the expressions refuse a set where a formula stands)
    dim: int = 1
    label: str = "set"

    # -- algebra: the operators build the combinators below
    def __add__(self, other: Any) -> "Set":

        return Sum(self, as_set(other, self.dim))

    def __radd__(self, other: Any) -> "Set":

        return Sum(as_set(other, self.dim), self)

    def __sub__(self, other: Any) -> "Set":
        return self + -as_set(other, self.dim)

    def __rsub__(self, other: Any) -> "Set":
        return as_set(other, self.dim) + -self

    def __neg__(self) -> "Set":
        return self * -1

    def __mul__(self, factor: Any) -> "Set":

        if isinstance(factor, Set):
            raise SetStructureError(f"{self.label} · {factor.label}", "a set times a number or a formula, not a set")
        return Scaled(self, factor)

    __rmul__ = __mul__

    def __truediv__(self, factor: Any) -> "Set":
        return self * (1 / _expr(factor, f"{self.label} / …"))

    def __and__(self, other: Any) -> "Set":

        return intersection(self, other)

    def __or__(self, other: Any) -> "Set":

        return hull(self, other)

    def __repr__(self) -> str:
        return self.label

    def __getitem__(self, index: int) -> "Set":
        """Coordinate `index` of a product-like set (a point, a box, a vector sign, their sums
        and scalings) as a set in R: ``Sgn(v1, v2)[0]``."""
        if not (isinstance(index, (int, np.integer)) and -self.dim <= index < self.dim):
            raise SetStructureError(f"{self.label}[{index!r}]", f"a coordinate index in 0..{self.dim - 1}")
        try:
            return self.component(int(index) % self.dim)
        except _NotHere as exc:
            raise SetStructureError(f"{self.label}[{index}]", "a set whose coordinates are sets of their own (points, "
                                    f"boxes, vector signs, their sums and scalings); here {self.label} is {exc.what}") from None

    def component(self, index: int) -> "Set":
        """Coordinate `index` as a set in R (a product's factor), or _NotHere."""
        if self.dim == 1 and index == 0:
            return self
        raise _NotHere("not a product of sets in R")

    # -- normal forms (overridden)
    def support(self) -> _Support:
        """The paper's form of this set's support function (max-groups, min-groups, sign terms)."""
        return _Support(self.dim, [(self.label, self.polytope())])

    def polytope(self) -> list[tuple[sp.Expr, ...]]:
        """Vertices f_q(y) with c(F, ψ) = max_q ⟨f_q, ψ⟩, or _NotHere."""
        raise _NotHere("not a polytope")

    def formulas(self, psi: Sequence[sp.Expr]) -> list[sp.Expr]:
        """g_p(y, ψ) with c(F, ψ) = min_p g_p (one formula for a plain convex set), or _NotHere."""
        vertices = self.polytope()
        if len(vertices) == 1:
            return [_dot(vertices[0], psi)]
        if len(vertices) == 2:
            return [_segment_formula(vertices[0], vertices[1], psi)]
        raise _NotHere(f"a hull of {len(vertices)} points (max of {len(vertices)} linear functions of ψ)")


def as_set(value: Any, dim: int | None = None) -> Set:
    """A set, or a point for a formula (or a tuple of formulas)."""
    if isinstance(value, Set):
        return value
    point = Point(value)
    if dim is not None and point.dim != dim and point.dim == 1 and dim > 1:
        raise SetStructureError(f"{point.label} + a set in R^{dim}", f"a point with {dim} coordinates (a tuple), or a "
                                f"set in R: of a set in R^{dim} such as the vector sign S = Sgn(v1, v2), a coordinate S[i]")
    return point


class Point(Set):
    """The singleton {f(y)} (f a formula, or a tuple of k formulas): an exact equation z = f."""

    def __init__(self, f: Any) -> None:
        self.f = _vector(f, "Point")
        self.dim = len(self.f)
        self.label = "{" + _text(self.f) + "}"

    def polytope(self):
        return [self.f]

    def component(self, index: int) -> "Set":
        return Point(self.f[index])


def _same_dim(sets: Sequence[Set], what: str) -> int:
    dims = {s.dim for s in sets}
    if len(dims) != 1:
        raise SetStructureError(what, "sets of one dimension", ", ".join(f"{s.label} ⊂ R^{s.dim}" for s in sets))
    return dims.pop()


def _cartesian_sum(polytopes: Sequence[list[tuple[sp.Expr, ...]]], where: str) -> list[tuple[sp.Expr, ...]]:
    count = int(np.prod([len(p) for p in polytopes]))
    if count > _MAX_VERTICES:
        raise SetStructureError(where, f"at most {_MAX_VERTICES} vertices inside a hull", count)
    out = []
    for combo in itertools.product(*polytopes):
        vertex = tuple(sp.Add(*parts) for parts in zip(*combo))
        if vertex not in out:
            out.append(vertex)
    return out


def _role(s: Set, role: str, parent: str, *args):
    try:
        return getattr(s, role)(*args)
    except _NotHere as exc:
        raise _NotHere(f"{exc.what} ({s.label} in {parent})") from None


# -- the combinators (paper Section 5) --------------------------------------------------


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
