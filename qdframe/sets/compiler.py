"""A modeling layer that reads like the paper: sets of formulas compile to support-function pieces.

An author writes the sets F_b(x) of x' ∈ F(x) with SymPy formulas in the states and
controls — points, intervals, hulls (unions), intersections, Minkowski sums, scalings,
Filippov sign terms a·Sgn(s), balls and ellipses — and never a derivative::

    from qdframe.sets import SetModel, Interval, intersection, Abs

    class Example71(SetModel):
        name = "example-7.1"
        state_names = "x1 x2"
        default_x0 = (0.0, 0.0)
        default_xT = {"x2": 1.0}
        penalty = 10.0

        def sets(self, x1, x2):
            return {x1: intersection(Interval(x1, x2), Interval(x2 - 1, x2 + 1)),  # x1' ∈ …
                    x2: x1 + 1}                                                     # x2' = x1 + 1

        def running_cost(self, x1, x2):
            return Abs(x1)

Each set compiles to the pieces of paper (support)–(subf), the low-level
:class:`~qdframe.model.SetBlock`: a hull of points is one max-group max_q ⟨f_q(y), ψ⟩
(paper (supf)); an intersection is one min-group min_p g_p(y, ψ) of its operands'
support formulas (paper (subf), Remark 5.1); a Minkowski sum adds groups; a·Sgn(s) is a
:class:`~qdframe.model.SignTerm`. Gradients are derived by SymPy and lambdified to NumPy,
so every piece is evaluated for all nodes at once.

Not every combination has that form: a hull of an intersection is max{…, min{…}}, which is
not a sum of maxima and minima. Such sets raise :class:`SetStructureError` naming the set
and what is allowed where it stands. Pieces must be continuously differentiable in (x, u):
|e| appears only as a factor of a symmetric set (``Abs(e) * Interval(-1, 1)`` is the hull
of {e, −e}) and in costs and sign amplitudes, where it is the group max{e, −e}.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, ClassVar

import numpy as np
import sympy as sp
from sympy import Abs, Max, Min, sqrt  # re-exported for model authors

from ..errors import InputError
from ..model import Cost, InclusionModel, MaxGroup, MinGroup, SetBlock, SignTerm, Surface

__all__ = [
    "Abs",
    "Ball",
    "Box",
    "Ellipse",
    "Interval",
    "Max",
    "Min",
    "Point",
    "Set",
    "SetModel",
    "SetStructureError",
    "Sgn",
    "compile_sets",
    "define_model",
    "hull",
    "intersection",
    "minkowski_sum",
    "norm1",
    "sqrt",
    "union",
]

_NONSMOOTH = (sp.Abs, sp.Max, sp.Min, sp.sign, sp.Heaviside, sp.Piecewise, sp.floor, sp.ceiling)
_MAX_VERTICES = 256  # a hull of sums multiplies vertex counts: refuse beyond this


class SetStructureError(InputError):
    """A set whose support function is not of the paper's form Σ max + Σ min (+ sign terms)."""


def norm1(*terms: Any) -> sp.Expr:
    """|t_1| + … + |t_n| (the paper's |x| in Section 5 and Example 7.3); accepts one sequence too."""
    if len(terms) == 1 and isinstance(terms[0], (list, tuple)):
        terms = tuple(terms[0])
    return sp.Add(*(sp.Abs(_expr(t, "norm1")) for t in terms))


# --------------------------------------------------------------------------- helpers
def _expr(value: Any, where: str) -> sp.Expr:
    if isinstance(value, Set):
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
    return expr


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


# --------------------------------------------------------------------------- sets
class Set:
    """A set-valued formula F(y) ⊂ R^k of the states and controls y = (x, u).

    Sets combine with ``+`` (Minkowski sum; a formula is a point), ``-``, ``*`` by a number
    or a formula, ``|`` (hull of the union) and ``&`` (intersection).
    """

    __array_ufunc__ = None  # numpy scalars defer to our operators
    dim: int = 1
    label: str = "set"

    # -- algebra
    def __add__(self, other: Any) -> "Set":
        return Sum(self, as_set(other, self.dim))

    def __radd__(self, other: Any) -> "Set":
        return Sum(as_set(other, self.dim), self)

    def __sub__(self, other: Any) -> "Set":
        return Sum(self, Scaled(as_set(other, self.dim), -1))

    def __rsub__(self, other: Any) -> "Set":
        return Sum(as_set(other, self.dim), Scaled(self, -1))

    def __neg__(self) -> "Set":
        return Scaled(self, -1)

    def __mul__(self, factor: Any) -> "Set":
        if isinstance(factor, Set):
            raise SetStructureError(f"{self.label} · {factor.label}", "a set times a number or a formula, not a set")
        return Scaled(self, factor)

    __rmul__ = __mul__

    def __truediv__(self, factor: Any) -> "Set":
        return Scaled(self, 1 / _expr(factor, f"{self.label} / …"))

    def __and__(self, other: Any) -> "Set":
        return intersection(self, other)

    def __or__(self, other: Any) -> "Set":
        return hull(self, other)

    def __repr__(self) -> str:
        return self.label

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
        raise SetStructureError(f"{point.label} + a set in R^{dim}", f"a point with {dim} coordinates")
    return point


class Point(Set):
    """The singleton {f(y)} (f a formula, or a tuple of k formulas): an exact equation z = f."""

    def __init__(self, f: Any) -> None:
        self.f = _vector(f, "Point")
        self.dim = len(self.f)
        self.label = "{" + _text(self.f) + "}"

    def polytope(self):
        return [self.f]


class Interval(Set):
    """The segment [lo(y), hi(y)] (co{lo, hi}; endpoints in either order): c = max{lo·ψ, hi·ψ}.

    ``Interval(Min(e_1, …, e_m), Max(e_1, …, e_m))`` is the hull co{e_1, …, e_m}
    (:func:`hull`), the paper's [min, max] velocity range (Section 5)."""

    def __new__(cls, lo: Any = None, hi: Any = None) -> "Set":
        ends = [_expr(v, "Interval end") if isinstance(v, (sp.Basic, int, float)) else None for v in (lo, hi)]
        if isinstance(ends[0], sp.Min) and isinstance(ends[1], sp.Max) and set(ends[0].args) == set(ends[1].args):
            return Hull(*ends[0].args)  # [min e_i, max e_i] = co{e_i}
        return super().__new__(cls)

    def __init__(self, lo: Any, hi: Any) -> None:
        for end, where in ((lo, "Interval lower end"), (hi, "Interval upper end")):
            if isinstance(end, sp.Basic) and end.has(sp.Min, sp.Max):
                raise SetStructureError(
                    where, "a continuously differentiable formula; for the range [min e_i, max e_i] write "
                    "hull(e_1, …, e_m) (or Interval(Min(e_1, …), Max(e_1, …)) with the same e_i)", _s(end))
        self.lo, self.hi = _smooth(lo, "Interval lower end"), _smooth(hi, "Interval upper end")
        if self.lo.is_number and self.hi.is_number and self.lo > self.hi:
            raise SetStructureError(f"Interval({self.lo}, {self.hi})", "lo ≤ hi for constant ends")
        self.label = f"[{_s(self.lo)}, {_s(self.hi)}]"

    def polytope(self):
        return [(self.lo,), (self.hi,)]


class Box(Set):
    """The box Π_i [lo_i, hi_i] ⊂ R^k: the Minkowski sum of its k axis segments."""

    def __init__(self, lo: Sequence[Any], hi: Sequence[Any]) -> None:
        self.lo, self.hi = _vector(lo, "Box lower corner"), _vector(hi, "Box upper corner")
        if len(self.lo) != len(self.hi):
            raise SetStructureError("Box", "corners of equal length", (len(self.lo), len(self.hi)))
        self.dim = len(self.lo)
        self.label = f"Box({_text(self.lo)}, {_text(self.hi)})"

    def _segments(self) -> list[list[tuple[sp.Expr, ...]]]:
        zero = sp.Integer(0)
        return [
            [tuple(end if j == i else zero for j in range(self.dim)) for end in (self.lo[i], self.hi[i])]
            for i in range(self.dim)
        ]

    def support(self):
        return _Support(self.dim, [(f"{self.label} axis {i + 1}", s) for i, s in enumerate(self._segments())])

    def polytope(self):
        return _cartesian_sum(self._segments(), self.label)

    def formulas(self, psi):
        return [sp.Add(*(_segment_formula((lo,), (hi,), (p,)) for lo, hi, p in zip(self.lo, self.hi, psi)))]


class Ball(Set):
    """The ball B_r(c) = {c + r·v: ‖v‖ ≤ 1}: c(B, ψ) = ⟨c, ψ⟩ + r‖ψ‖ (paper Remark 5.1)."""

    def __init__(self, center: Any, radius: Any) -> None:
        self.center = _vector(center, "Ball center")
        self.radius = _smooth(radius, "Ball radius")
        if self.radius.is_number and self.radius < 0:
            raise SetStructureError(f"Ball({_text(self.center)}, {self.radius})", "a radius ≥ 0")
        self.dim = len(self.center)
        self.label = f"B({_text(self.center)}, {_s(self.radius)})"

    def support(self):
        if self.dim == 1:
            return super().support()
        return _Support(self.dim, mins=[(self.label, self.formulas(_psi(self.dim)))])

    def polytope(self):
        if self.dim == 1:  # in R a ball is a segment
            return [(self.center[0] - self.radius,), (self.center[0] + self.radius,)]
        raise _NotHere("a ball (its support function is not a max of linear functions of ψ)")

    def formulas(self, psi):
        return [_dot(self.center, psi) + self.radius * _norm(psi)]


class Ellipse(Set):
    """An ellipse (ellipsoid) with center c and either semi-axes a_i along the coordinate axes,
    c(E, ψ) = ⟨c, ψ⟩ + sqrt(Σ a_i² ψ_i²), or a shape matrix Q ⪰ 0, c(E, ψ) = ⟨c, ψ⟩ + sqrt(ψᵀQψ)."""

    def __init__(self, center: Any, semi_axes: Any = None, *, matrix: Any = None) -> None:
        self.center = _vector(center, "Ellipse center")
        self.dim = len(self.center)
        if (semi_axes is None) == (matrix is None):
            raise SetStructureError("Ellipse", "exactly one of semi_axes=(a_1, …, a_k) or matrix=Q")
        if semi_axes is not None:
            axes = _vector(semi_axes, "Ellipse semi-axes")
            if len(axes) != self.dim:
                raise SetStructureError("Ellipse semi-axes", f"{self.dim} formulas", len(axes))
            self.quadratic = sp.diag(*[a**2 for a in axes])
            shape = _text(axes)
        else:
            q = sp.Matrix(matrix)
            if q.shape != (self.dim, self.dim):
                raise SetStructureError("Ellipse matrix", f"a {self.dim}×{self.dim} matrix", q.shape)
            self.quadratic = q.applyfunc(lambda v: _smooth(v, "Ellipse matrix"))
            shape = str(q.tolist())
        self.label = f"E({_text(self.center)}, {shape})"

    def support(self):
        return _Support(self.dim, mins=[(self.label, self.formulas(_psi(self.dim)))])

    def formulas(self, psi):
        p = sp.Matrix(psi)
        return [_dot(self.center, psi) + sp.sqrt(sp.expand((p.T * self.quadratic * p)[0, 0]))]


class Sgn(Set):
    """Filippov's set-valued sign Sgn(s(y)) ⊂ [−1, 1]; ``a * Sgn(s)`` is a·Sgn(s) (paper Section 5).

    band: the solver uses the whole interval near s = 0, shrinking smoothly (C¹) to
    sign(s) at |s| = band (:class:`~qdframe.model.SignTerm`); ``band=float('inf')`` keeps the
    whole interval everywhere (Filippov's set on its own surface, enforced by the model's
    surface). One-coordinate blocks only.
    """

    def __init__(self, switch: Any, band: float = 1e-3) -> None:
        self.switch = _smooth(switch, "Sgn switch")
        if not (float(band) >= 0):
            raise SetStructureError(f"Sgn({self.switch}) band", "a number ≥ 0 (inf allowed)", band)
        self.band = float(band)
        self.label = f"Sgn({_s(self.switch)})"

    def support(self):
        return _Support(1, signs=[(self.label, sp.Integer(1), self.switch, self.band)])

    def polytope(self):
        raise _NotHere("a Filippov sign term (its set jumps with sign(s))")

    def formulas(self, psi):
        raise _NotHere("a Filippov sign term (its set jumps with sign(s))")


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

    def formulas(self, psi):
        parts = [_role(s, "formulas", self.label, psi) for s in self.sets]
        if int(np.prod([len(p) for p in parts])) > 64:
            raise _NotHere("a sum of intersections with more than 64 combinations")
        return [sp.Add(*combo) for combo in itertools.product(*parts)]


def _role(s: Set, role: str, parent: str, *args):
    try:
        return getattr(s, role)(*args)
    except _NotHere as exc:
        raise _NotHere(f"{exc.what} ({s.label} in {parent})") from None


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
            out.signs = [(label, sp.Abs(c) * a, sp.sign(c) * s, band) for label, a, s, band in inner.signs]
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


# ------------------------------------------------------------------- scalar groups
def _scalar_groups(expr: sp.Expr, where: str, allow_min: bool) -> tuple[list[list[sp.Expr]], list[list[sp.Expr]]]:
    """expr = Σ max-groups + Σ min-groups: smooth terms (one piece), c·|e|, c·Max(…), c·Min(…)."""
    terms = sp.Add.make_args(sp.expand(expr, deep=False))
    smooth: list[sp.Expr] = []
    maxes: list[list[sp.Expr]] = []
    mins: list[list[sp.Expr]] = []
    allowed = "smooth terms, c·|e| and c·Max(e_1, …)" + (", c·Min(e_1, …)" if allow_min else " with c > 0")
    for term in terms:
        if not any(term.has(f) for f in _NONSMOOTH):
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
        grads = [[sp.diff(e, s) for s in symbols] for e in exprs]
        self.entries = [(q, j) for q in range(self.count) for j in range(self.width) if grads[q][j] != 0]
        outputs = list(exprs) + [grads[q][j] for q, j in self.entries]
        self.function = sp.lambdify(list(symbols) + list(self.psi), outputs, modules="numpy", cse=True)

    def __call__(self, y: np.ndarray, psi: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        rows = y.shape[0]
        args = [y[:, i] for i in range(self.width)]
        if self.psi:
            args += [psi[:, j] for j in range(len(self.psi))]  # type: ignore[index]
        with np.errstate(all="ignore"):  # NaN/inf are reported by the functional's checks
            out = self.function(*args)
        values = np.empty((rows, self.count))
        for q in range(self.count):
            values[:, q] = out[q]
        grads = np.zeros((rows, self.count, self.width))
        for (q, j), value in zip(self.entries, out[self.count :]):
            grads[:, q, j] = value
        return values, grads


def _max_pieces(vertices: list[tuple[sp.Expr, ...]], symbols) -> Callable:
    k = len(vertices[0])
    flat = _Vectorized([v for vertex in vertices for v in vertex], symbols)
    m = len(vertices)

    def pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values, grads = flat(y)
        return values.reshape(-1, m, k), grads.reshape(-1, m, k, flat.width)

    return pieces


def _min_pieces(formulas: list[sp.Expr], symbols, dim: int) -> Callable:
    vectorized = _Vectorized(formulas, symbols, _psi(dim))
    return lambda y, psi: vectorized(y, psi)


def _scalar_pieces(exprs: list[sp.Expr], symbols) -> Callable:
    vectorized = _Vectorized(exprs, symbols)
    return lambda y: vectorized(y)


def _switch(expr: sp.Expr, symbols) -> Callable:
    """s(y) and ∇s; one callable per distinct expression, so that sign terms on the same
    surface share one Filippov selection (:class:`~qdframe.functional.Functional`)."""
    return _switch_cached(expr, tuple(symbols))


@lru_cache(maxsize=None)
def _switch_cached(expr: sp.Expr, symbols: tuple) -> Callable:
    vectorized = _Vectorized([expr], symbols)

    def switch(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values, grads = vectorized(y)
        return values[:, 0], grads[:, 0, :]

    return switch


# ------------------------------------------------------------------- compilation
@dataclass(frozen=True)
class Compiled:
    """A model's sets, surface and cost as low-level qdframe objects."""

    blocks: tuple[SetBlock, ...]
    surface: Surface | None
    cost: Cost | None


def _sign_term(label: str, amplitude: sp.Expr, switch: sp.Expr, band: float, symbols, where: str) -> SignTerm:
    amplitude = sp.sympify(amplitude)
    if amplitude.is_number:
        a = float(amplitude)
        value: float | tuple = abs(a)
        switch = switch if a >= 0 else -switch
        if a == 0:
            value = 0.0
    else:
        terms = sp.Add.make_args(sp.expand(amplitude, deep=False))
        if all(t.as_coeff_Mul()[0] < 0 for t in terms):  # −a·Sgn(s) = a·Sgn(−s)
            amplitude, switch = -amplitude, -switch
        maxes, _ = _scalar_groups(amplitude, f"{where}: amplitude of {label}", allow_min=False)
        value = tuple(_scalar_pieces(group, symbols) for group in maxes)
    name = label if amplitude == 1 else f"({_s(amplitude)})·{label}" if amplitude.is_Add else f"{_s(amplitude)}·{label}"
    return SignTerm(value, _switch(sp.expand(switch), symbols), band, name)


def compile_sets(
    sets: Mapping[Any, Any],
    states: Sequence[sp.Symbol],
    controls: Sequence[sp.Symbol] = (),
    surface: Any = None,
    cost: Any = None,
    weight: float = 1.0,
    model: str = "model",
) -> Compiled:
    """Compile {state or tuple of states: set} (+ surface formulas, cost integrand) to qdframe's pieces."""
    symbols = tuple(states) + tuple(controls)
    index = {s: i for i, s in enumerate(states)}
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
        f = as_set(value)
        if f.dim != len(coords):
            raise SetStructureError(f"{model} {name} = {f.label}", f"a set in R^{len(coords)}", f"a set in R^{f.dim}")
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
        min_groups = tuple(MinGroup(_min_pieces(gs, symbols, f.dim), label) for label, gs in support.mins)
        signs = tuple(_sign_term(label, a, s, band, symbols, f"{model} {name}") for label, a, s, band in support.signs)
        blocks.append(SetBlock(tuple(coords), max_groups, min_groups, name, signs))
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
    if cost is not None:
        maxes, mins = _scalar_groups(_expr(cost, f"{model} cost"), f"{model} cost", allow_min=True)
        compiled_cost = Cost(
            tuple(_scalar_pieces(g, symbols) for g in maxes), tuple(_scalar_pieces(g, symbols) for g in mins), weight
        )
    return Compiled(tuple(blocks), compiled_surface, compiled_cost)


def _all_exprs(support: _Support) -> list[sp.Expr]:
    out = [v for _, vs in support.polytopes for vertex in vs for v in vertex]
    out += [g for _, gs in support.mins for g in gs]
    out += [e for _, a, s, _ in support.signs for e in (sp.sympify(a), s)]
    return out


# ------------------------------------------------------------------------ models
def _names(value: Any) -> tuple[str, ...]:
    return tuple(value.replace(",", " ").split()) if isinstance(value, str) else tuple(value)


class SetModel(InclusionModel):
    """An :class:`~qdframe.model.InclusionModel` written with sets of formulas.

    Class attributes as for InclusionModel, plus:

    - ``state_names`` / ``control_names`` may be one string, ``"x1 x2"``;
    - ``default_xT = {"x2": 1.0}`` fixes x_j(T) by name (instead of ``end_indices`` and
      ``default_end_values``);
    - ``penalty``: λ of the objective ∫cost + λ·I when there is a running cost.

    Implement :meth:`sets`; optionally :meth:`surface_equations` and :meth:`running_cost`.
    Each receives the states and then the controls as SymPy symbols, in order. The sets
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

    # -- the InclusionModel interface
    @classmethod
    def symbols(cls) -> tuple[tuple[sp.Symbol, ...], tuple[sp.Symbol, ...]]:
        """The states and controls as real SymPy symbols."""
        return (tuple(sp.Symbol(n, real=True) for n in cls.state_names),
                tuple(sp.Symbol(n, real=True) for n in cls.control_names))

    def compiled(self) -> Compiled:
        cls = type(self)
        cached = cls.__dict__.get("_compiled_sets")
        if cached is None:
            states, controls = cls.symbols()
            args = states + controls
            cached = compile_sets(
                self.sets(*args), states, controls,
                surface=self.surface_equations(*args), cost=self.running_cost(*args),
                weight=float(cls.penalty), model=cls.name or cls.__name__,
            )
            cls._compiled_sets = cached  # type: ignore[attr-defined]
        return cached

    def blocks(self) -> tuple[SetBlock, ...]:
        return self.compiled().blocks

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
