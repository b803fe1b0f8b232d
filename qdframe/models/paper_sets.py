"""The paper's Examples 7.1–7.3 in the set language (:mod:`qdframe.sets`): the form to read.

They compile to the same pieces as the hand-written models in ``paper.py`` and
``paper_73.py`` (tests/sets/test_paper_examples.py compares functional values,
quasidifferentials and solves). The registry serves the hand-written ones as
``paper-7.1``, ``paper-7.2`` and ``paper-7.3``: the published results were computed with
them, and on ``paper-7.3``, whose solution is not unique, this form's default solve takes
another path (``paper_73.py`` says more). These are not registered: import them, or see
docs/authoring.md.
"""

from __future__ import annotations

import numpy as np

from ..sets import Abs, Ball, Ellipse, Interval, SetModel, Sgn, intersection, norm1, sqrt
from .paper_73 import FRICTION, GAIN, REACHING_END


class Paper71Sets(SetModel):
    """Example 7.1: x1' ∈ [x1, x2] ∩ [x2 − 1, x2 + 1], x2' = x1 + 1, cost ∫|x1|, λ = 10."""

    name = "paper-7.1-sets"
    default_scheme = "trapezoid"  # the paper's discretization (Section 7)
    state_names = "x1 x2"
    default_x0 = (0.0, 0.0)
    default_xT = {"x2": 1.0}
    penalty = 10.0

    def sets(self, x1, x2):
        return {x1: intersection(Interval(x1, x2), Interval(x2 - 1, x2 + 1)), x2: x1 + 1}

    def running_cost(self, x1, x2):
        return Abs(x1)

    def initial_guess(self, t):
        return np.tile([-1.0, -2.0], (t.size, 1)), np.zeros((t.size, 2))

    def exact_solution(self, t):
        return np.stack([np.zeros_like(t), t], axis=1)


class Paper72Sets(SetModel):
    """Example 7.2: x' ∈ B_1(0) ∩ E(x), E(x) = {(a, b): (a − 2)²/(x1² + 3) + b² ≤ 1}, ψ ∈ S_2."""

    name = "paper-7.2-sets"
    default_scheme = "trapezoid"  # the paper's discretization (Section 7)
    state_names = "x1 x2"
    default_x0 = (0.0, 0.0)
    default_xT = {"x1": 0.75, "x2": 0.5}

    def sets(self, x1, x2):
        return {(x1, x2): intersection(Ball((0, 0), 1), Ellipse((2, 0), semi_axes=(sqrt(x1**2 + 3), 1)))}

    def initial_guess(self, t):
        return np.stack([t, t], axis=1), np.ones((t.size, 2))


class Paper73Sets(SetModel):
    """Example 7.3: three masses with dry friction sliding on x4 = 0, control u, x3(1) = 0."""

    name = "paper-7.3-sets"
    state_names = "x1 x2 x3 x4 x5 x6"
    control_names = "u"
    default_xT = {"x3": 0.0}
    band = 1e-3  # of the friction terms Sgn(x5), Sgn(x6)

    def __init__(self, T=None, x0=None, end_values=None):
        super().__init__(T, REACHING_END if x0 is None else x0, end_values)

    def sets(self, x1, x2, x3, x4, x5, x6, u):
        # Filippov's set on the surface x4 = 0: the whole 1.05|x|·[−1, 1] (band inf)
        return {
            x1: x4,
            x2: x5,
            x3: x6,
            x4: -x1 + (x2 - x1) - x4 - GAIN * norm1(x1, x2, x3, x4, x5, x6) * Sgn(x4, band=float("inf")),
            x5: (x1 - x2) + (x3 - x2) - x5 - FRICTION * Sgn(x5, band=self.band),
            x6: (x2 - x3) - x6 - FRICTION * Sgn(x6, band=self.band) + u,
        }

    def surface_equations(self, x1, x2, x3, x4, x5, x6, u):
        return x4

    def initial_guess(self, t):
        return np.zeros((t.size, 6)), np.zeros((t.size, 6))
