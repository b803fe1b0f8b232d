"""A modeling layer that reads like the paper: sets of formulas compile to support-function pieces.

An author writes the sets F_b(x) of x' ∈ F(x) with SymPy formulas in the states and
controls — points, intervals, hulls (unions), intersections, Minkowski sums, scalings,
Filippov sign terms a·Sgn(s) and the vector sign Sgn(v1, v2) of isotropic friction (v/|v|, the
unit ball at v = 0), balls and ellipses, a switched field's modes as nosnoc states them
(:func:`Modes`) — and never a derivative::

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

Modules: :mod:`~qdframe.sets.expressions` (formulas: checks, ψ, support formulas),
:mod:`~qdframe.sets.modes` (Stewart's modes and switching functions to sign terms),
:mod:`~qdframe.sets.algebra` (:class:`Set`, its normal form, :class:`Point`, and the
combinators its operators build: sum, hull, intersection, scaling),
:mod:`~qdframe.sets.primitives` (Interval, Box, Ball, Ellipse, Sgn and its vector form),
:mod:`~qdframe.sets.compiler` (sets to :class:`~qdframe.model.SetBlock` pieces) and
:mod:`~qdframe.sets.set_model` (:class:`SetModel`, :func:`define_model`).
"""

from sympy import Abs, Max, Min, sqrt  # re-exported for model authors

# the classes behind the operators, as_set and Compiled are importable too (not in __all__, as before)
from .algebra import Hull, Intersection, Point, Scaled, Set, Sum, as_set, hull, intersection, minkowski_sum, union
from .compiler import Compiled, compile_sets
from .expressions import SetStructureError, norm1
from .modes import Modes
from .primitives import Ball, Box, Ellipse, Interval, Sgn, VectorSgn
from .set_model import SetModel, define_model

__all__ = [
    "Abs",
    "Ball",
    "Box",
    "Ellipse",
    "Interval",
    "Max",
    "Min",
    "Modes",
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
