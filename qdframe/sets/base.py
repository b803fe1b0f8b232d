"""Set: the algebra every set of the language shares, and the normal form it compiles from.

Each set has a support function of the paper's form Σ max-groups + Σ min-groups (+ sign
terms), :class:`_Support`; a set asked for a role it cannot take (the vertices of a ball,
one ψ-formula for a hull of three points) raises :class:`_NotHere`, which the
combinators turn into a :class:`~qdframe.sets.expressions.SetStructureError` naming the set.
A formula is the point :class:`Point`; the operators build the combinators of
:mod:`qdframe.sets.combinators`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from .expressions import SetStructureError, _dot, _expr, _segment_formula, _text, _vector

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
    dim: int = 1
    label: str = "set"

    # -- algebra (the combinators import this module, hence the imports inside the operators)
    def __add__(self, other: Any) -> "Set":
        from .combinators import Sum

        return Sum(self, as_set(other, self.dim))

    def __radd__(self, other: Any) -> "Set":
        from .combinators import Sum

        return Sum(as_set(other, self.dim), self)

    def __sub__(self, other: Any) -> "Set":
        return self + -as_set(other, self.dim)

    def __rsub__(self, other: Any) -> "Set":
        return as_set(other, self.dim) + -self

    def __neg__(self) -> "Set":
        return self * -1

    def __mul__(self, factor: Any) -> "Set":
        from .combinators import Scaled

        if isinstance(factor, Set):
            raise SetStructureError(f"{self.label} · {factor.label}", "a set times a number or a formula, not a set")
        return Scaled(self, factor)

    __rmul__ = __mul__

    def __truediv__(self, factor: Any) -> "Set":
        return self * (1 / _expr(factor, f"{self.label} / …"))

    def __and__(self, other: Any) -> "Set":
        from .combinators import intersection

        return intersection(self, other)

    def __or__(self, other: Any) -> "Set":
        from .combinators import hull

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
