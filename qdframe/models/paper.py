"""The paper's Examples 7.1 and 7.2 (Section 7), with hand-written pieces and gradients.

These are the registered ``paper-7.1`` and ``paper-7.2``: every published result (README,
the benchmarks' references, the solver tests) was computed with them. The same examples
in the set language are ``paper_sets.py``, the form to read; the two are kept on purpose,
as two independent codings that check each other: tests/sets/test_paper_examples.py
asserts the same functional and quasidifferential at random points and the same iterates,
which tests the set compiler against pieces written by hand.
"""

from __future__ import annotations

import numpy as np

from ..model import Cost, InclusionModel, MinGroup, SetBlock


class Paper71(InclusionModel):
    """Example 7.1: x1' ∈ [x1, x2] ∩ [x2 − 1, x2 + 1], x2' = x1 + 1, cost ∫|x1|, λ = 10.

    c(F1, ψ) = min{ (x1 + x2)/2·ψ + |x1 − x2|/2,  x2·ψ + 1 },  c(F2, ψ) = (x1 + 1)·ψ.
    Known solution x1 = 0, x2 = t. First iterate (x, z) = (−1, −2, 0, 0).
    """

    name = "paper-7.1"
    default_scheme = "trapezoid"  # the paper's discretization (Section 7)
    description = "Example 7.1: intersection of intervals, cost ∫|x1|, λ = 10"
    state_names = ("x1", "x2")
    default_T = 1.0
    default_x0 = (0.0, 0.0)
    end_indices = (1,)
    default_end_values = (1.0,)
    penalty = 10.0

    def blocks(self) -> tuple[SetBlock, ...]:
        return (
            SetBlock((0,), min_groups=(MinGroup(_f1_pieces, "[x1,x2] ∩ [x2-1,x2+1]"),), name="F1"),
            SetBlock.equation(1, _f2_rhs, name="F2"),
        )

    def cost(self) -> Cost:
        return Cost(max_groups=(_abs_x1,), weight=self.penalty)

    def initial_guess(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.tile([-1.0, -2.0], (t.size, 1)), np.zeros((t.size, 2))

    def exact_solution(self, t: np.ndarray) -> np.ndarray:
        return np.stack([np.zeros_like(t), t], axis=1)


def _f1_pieces(x: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x1, x2, p = x[:, 0], x[:, 1], psi[:, 0]
    sign = np.sign(x1 - x2)
    hull = 0.5 * (x1 + x2) * p + 0.5 * np.abs(x1 - x2)  # c([x1, x2], ψ)
    band = x2 * p + 1.0  # c([x2 − 1, x2 + 1], ψ)
    grads = np.stack(
        [np.stack([0.5 * p + 0.5 * sign, 0.5 * p - 0.5 * sign], axis=1), np.stack([0 * p, p], axis=1)], axis=1
    )
    return np.stack([hull, band], axis=1), grads


def _f2_rhs(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    gradient = np.zeros_like(x)
    gradient[:, 0] = 1.0
    return x[:, 0] + 1.0, gradient


def _abs_x1(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    grads = np.zeros((x.shape[0], 2, 2))
    grads[:, 0, 0], grads[:, 1, 0] = 1.0, -1.0
    return np.stack([x[:, 0], -x[:, 0]], axis=1), grads


class Paper72(InclusionModel):
    """Example 7.2: x' ∈ B_2 ∩ E_2(x), E_2(x) = {(a, b): (a − 2)²/(x1² + 3) + b² ≤ 1}.

    ψ ∈ S_2 and c̃(F, ψ) = min{ 1,  sqrt((x1² + 3)ψ1² + ψ2²) + 2ψ1 } (Remark 5.1).
    Boundary x(0) = (0, 0), x(1) = (0.75, 0.5); the constant z = (0.75, 0.5) is one
    solution of many (no `exact_solution`: an error against it would mean nothing).
    First iterate x = (t, t), z = (1, 1).
    """

    name = "paper-7.2"
    default_scheme = "trapezoid"  # the paper's discretization (Section 7)
    description = "Example 7.2: unit disc ∩ ellipse(x1), ψ ∈ S_2"
    state_names = ("x1", "x2")
    default_T = 1.0
    default_x0 = (0.0, 0.0)
    end_indices = (0, 1)
    default_end_values = (0.75, 0.5)

    def blocks(self) -> tuple[SetBlock, ...]:
        group = MinGroup(_disc_and_ellipse, "B2 ∩ E2(x)", values=_disc_and_ellipse_values)
        return (SetBlock((0, 1), min_groups=(group,), name="F"),)

    def initial_guess(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.stack([t, t], axis=1), np.ones((t.size, 2))



def _disc_and_ellipse(x: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x1, p1 = x[:, 0], psi[:, 0]
    values, root = _disc_and_ellipse_root(x, psi)
    grads = np.zeros((x.shape[0], 2, 2))
    grads[:, 1, 0] = x1 * p1**2 / root
    return values, grads


def _disc_and_ellipse_values(x: np.ndarray, psi: np.ndarray) -> np.ndarray:
    return _disc_and_ellipse_root(x, psi)[0]


def _disc_and_ellipse_root(x: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(‖ψ‖, sqrt((x1² + 3)ψ1² + ψ2²) + 2ψ1) as (N, 2), and the square root."""
    x1, p1, p2 = x[:, 0], psi[:, 0], psi[:, 1]
    root = np.sqrt((x1**2 + 3.0) * p1**2 + p2**2)
    values = np.empty((x.shape[0], 2))
    values[:, 0] = np.sqrt(p1**2 + p2**2)
    np.add(root, 2.0 * p1, out=values[:, 1])
    return values, root
