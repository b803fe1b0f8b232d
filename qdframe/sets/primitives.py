"""The primitive sets: Interval, Box, Ball, Ellipse and Filippov's Sgn, scalar and vector (a formula is a Point).

Each gives its support function c(F, ψ) in the paper's form: vertices for a polytope
(paper (supf)), one formula g(y, ψ) for a ball or an ellipse (paper (subf), Remark 5.1),
a sign term for Sgn (paper Section 5); the vector sign Sgn(v1, …, vk) (isotropic friction)
one sign term per coordinate on a shared selection vector λ ∈ B.

``Ball(c, r)`` is the set {c + r·w: |w| ≤ 1} at every y: in a friction law, f − μ·Ball((0, 0), 1)
allows every friction force of the disc whatever the velocity (also one that pushes the
motion along), which is not Coulomb's law; the law is f − μ·Sgn(v1, v2).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from .algebra import Hull, Set, _cartesian_sum, _NotHere, _Support
from .expressions import SetStructureError, _dot, _expr, _norm, _psi, _s, _segment_formula, _smooth, _text, _vector


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

    def component(self, index: int) -> Set:
        return Interval(self.lo[index], self.hi[index])


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

    With two or more arguments, ``Sgn(v1, v2, …)`` is the vector sign (:class:`VectorSgn`):
    v/|v| for v ≠ 0 and the closed unit ball at v = 0 (isotropic friction).
    """

    def __new__(cls, *switches: Any, band: float = 1e-3, matrix: Any = None) -> "Set":
        if len(switches) == 1 and matrix is None and not isinstance(switches[0], _SEQUENCES):
            return super().__new__(cls)
        return VectorSgn(*switches, band=band, matrix=matrix)

    def __init__(self, switch: Any, band: float = 1e-3, matrix: Any = None) -> None:
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


_SEQUENCES = (list, tuple, np.ndarray, sp.MatrixBase)


@dataclass(frozen=True)
class BallArgument:
    """The switch of a vector sign's component in a sign term of the normal form: λ_j of the
    selection λ ∈ Sgn(s) ⊂ B of the vector switch s (a tuple of formulas)."""

    switch: tuple[sp.Expr, ...]
    component: int

    @property
    def free_symbols(self) -> set:
        return set().union(*(e.free_symbols for e in self.switch))


@dataclass(frozen=True)
class WholeVectorSign:
    """A vector sign in a block of several coordinates, in the normal form: the compiler
    splits the block into its coordinates (:meth:`Set.component`)."""

    sign: "VectorSgn"

    @property
    def free_symbols(self) -> set:
        return set().union(*(e.free_symbols for e in self.sign.switch))


class VectorSgn(Set):
    """The vector sign Sgn(v1, …, vk) ⊂ R^k, the subdifferential of the Euclidean norm |v|:
    {v/|v|} for v ≠ 0 and the closed unit ball B at v = 0 (isotropic Coulomb friction in the
    plane or in space, v' ∈ f − μ·Sgn(v1, v2)). Built by ``Sgn(v1, v2, …)``.

    Use its coordinates in one-coordinate blocks, ``S = Sgn(v1, v2)`` and
    ``{v1: f1 - mu*S[0], v2: f2 - mu*S[1]}``, or the whole in a block of the k coordinates,
    ``{(v1, v2): (f1, f2) - mu*Sgn(v1, v2)}`` (the compiler splits it into those blocks). The
    solver gives it ONE selection vector λ ∈ B per node, tied by λ = P_B(λ + c·v) (the
    projection onto B: second-order-cone complementarity), shared by every coordinate and by
    every other Sgn of the same arguments up to a constant factor, their order and their
    signs (Sgn(2·v) = Sgn(v), Sgn(−v) = −Sgn(v), Sgn(v2, v1) is Sgn(v1, v2) swapped).

    ``matrix=W`` (numbers, k' × k): the subdifferential of the weighted norm |W·v|,
    Wᵀ·Sgn(W·v) ⊂ Wᵀ·B — elliptic friction, v' ∈ f − Sgn(v1, v2, matrix=diag(μ1, μ2)) is the
    friction force −(μ1·λ1, μ2·λ2) with λ = Wv/|Wv|, the ellipse of semi-axes μ1, μ2 at rest
    (maximal dissipation); principal axes at an angle θ: W = diag(μ1, μ2)·Rᵀ(θ).

    band: as for the scalar Sgn, the width of the C¹ band (:class:`~qdframe.model.SignTerm`).
    """

    def __init__(self, *switches: Any, band: float = 1e-3, matrix: Any = None) -> None:
        items = tuple(switches[0]) if len(switches) == 1 and isinstance(switches[0], _SEQUENCES) else switches
        self.argument = _vector(items, "Sgn argument")
        k = len(self.argument)
        written = f"Sgn({', '.join(_s(e) for e in self.argument)})"
        if k < 2:
            raise SetStructureError(written, "two or more arguments for a vector sign (one: the scalar Sgn(s))")
        if not (float(band) >= 0):
            raise SetStructureError(f"{written} band", "a number ≥ 0 (inf allowed)", band)
        self.band = float(band)
        if matrix is None:
            self.matrix = np.eye(k)
        else:
            try:
                self.matrix = np.array(matrix, dtype=float)
            except (TypeError, ValueError):
                raise SetStructureError(f"{written} matrix", f"a matrix of numbers with {k} columns",
                                        matrix) from None
            if self.matrix.ndim != 2 or self.matrix.shape[1] != k or self.matrix.shape[0] < 2 \
                    or not np.all(np.isfinite(self.matrix)):
                raise SetStructureError(f"{written} matrix",
                                        f"a finite k' × {k} matrix of numbers, k' ≥ 2", self.matrix.tolist())
        self.switch = tuple(sp.expand(sp.Add(*(_number(w) * v for w, v in zip(row, self.argument) if w != 0)))
                            for row in self.matrix)
        if any(e == 0 for e in self.switch):
            raise SetStructureError(f"{written} matrix", "rows that are not zero", self.matrix.tolist())
        self.dim = k
        self.label = f"Sgn({', '.join(_s(e) for e in self.switch)})" if matrix is None else \
            f"{written[:-1]}; matrix={self.matrix.tolist()})"
        self.switch_label = f"Sgn({', '.join(_s(e) for e in self.switch)})"

    def __getitem__(self, index: int) -> Set:
        return self.component(index)

    def component(self, index: int) -> Set:
        if not (isinstance(index, (int, np.integer)) and -self.dim <= index < self.dim):
            raise SetStructureError(f"{self.label}[{index!r}]", f"a coordinate index in 0..{self.dim - 1}")
        return SgnComponent(self, int(index) % self.dim)

    def support(self):
        return _Support(self.dim, signs=[(self.label, sp.Integer(1), WholeVectorSign(self), self.band)])

    def polytope(self):
        raise _NotHere("a Filippov vector sign (its set jumps with the direction of its arguments)")

    def formulas(self, psi):
        raise _NotHere("a Filippov vector sign (its set jumps with the direction of its arguments)")


class SgnComponent(Set):
    """Coordinate i of a vector sign, Σ_j W_ji·λ_j with λ ∈ Sgn(W·v) ⊂ B (λ_i for W = I): a set
    in R of one-coordinate blocks, ``S[i]`` of ``S = Sgn(v1, v2)``."""

    def __init__(self, sign: VectorSgn, index: int) -> None:
        self.sign, self.index = sign, index
        self.label = f"{sign.label}[{index}]"

    def support(self):
        sign = self.sign
        terms = [(f"{sign.switch_label}[{j}]", _number(sign.matrix[j, self.index]), BallArgument(sign.switch, j), sign.band)
                 for j in range(sign.matrix.shape[0]) if sign.matrix[j, self.index] != 0]
        return _Support(1, signs=terms)

    def polytope(self):
        raise _NotHere("a Filippov vector sign's coordinate (its set jumps with the direction of its arguments)")

    def formulas(self, psi):
        raise _NotHere("a Filippov vector sign's coordinate (its set jumps with the direction of its arguments)")


def _number(value: float) -> sp.Expr:
    """A matrix entry as SymPy: an integer where it is one (1, not 1.0, in labels)."""
    return sp.Integer(int(value)) if float(value).is_integer() else sp.Float(value)
