"""Filippov inclusions with a bounded input: two problems that qdframe and an optimal-control
peer (nosnoc) can both state (the benchmarks' peer problems, `qdframe bench run --peers`).

Each is a Filippov inclusion with a bounded input written as a set, so qdframe sees a
plain boundary-value problem x' ∈ F(x) and nosnoc the equivalent optimal-control
problem with the input u as a bounded control (Filippov's lemma: the trajectories of
x' ∈ f(x) + B·U are those of x' = f(x) + B·u with measurable u(t) ∈ U):

* ``coulomb-rest-to-rest``: a unit mass under Coulomb friction F·Sgn(v), pushed by a
  force bounded by U, moved from rest at position 0 to rest at position 1:

      p' = v,   v' ∈ [−U, U] − F·Sgn(v),   x(0) = (0, 0),  x(T) = (1, 0),

  U = 2, F = 1, T = 2. The block starts and ends on the switching surface v = 0.

* ``sliding-mode-terminal``: the sliding-mode optimal-control problem of the FESD paper
  (Nurkanović et al., Numer. Math. 2024; nosnoc's ``sliding_mode_ocp`` example), with
  two switching surfaces c1 = x1 + 0.15·x2² and c2 = x2 − 0.05·x1³ and a terminal state:

      x1' ∈ v1 − Sgn(c1),  x2' ∈ v2 − Sgn(c2),  v1' ∈ [−10, 10],  v2' ∈ [−10, 10],
      x(0) = (2π/3, π/3, 0, 0),  x1(4) = −π/6,  x2(4) = −π/4.

The sign terms are qdframe's Filippov terms with band β = 1e-3 (the whole interval on
the surface, a·sign(s) for |s| ≥ β). Neither problem has a unique solution, so neither
has an ``exact_solution``: runs are judged by their residuals.
"""

from __future__ import annotations

import numpy as np

from ..model import InclusionModel, MaxGroup, SetBlock, SignTerm
from ..ready_pieces import affine, coordinate, repeated

BAND = 1e-3


def _interval(lower: float, upper: float, width: int) -> MaxGroup:
    """co{lower, upper}: two constant pieces (paper (supf))."""
    bounds = np.array([[lower], [upper]])

    def pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values = repeated(bounds, y.shape[0])
        return values, np.zeros((y.shape[0], 2, 1, width))

    pieces.formulas = lambda symbols: [lower, upper]  # the optional hook of qdframe.model: one compiled call
    return MaxGroup(pieces, f"[{lower:g}, {upper:g}]")


class CoulombRestToRest(InclusionModel):
    """A block under Coulomb friction moved by a bounded force from rest at 0 to rest at 1."""

    name = "coulomb-rest-to-rest"
    description = "Coulomb-friction block moved by a force |u| ≤ 2 between two rest states (peer: nosnoc)"
    state_names = ("position", "velocity")
    default_T = 2.0
    default_x0 = (0.0, 0.0)
    end_indices = (0, 1)
    default_end_values = (1.0, 0.0)
    force_bound = 2.0  # U
    friction = 1.0  # F = μ·m·g
    band = BAND

    def blocks(self) -> tuple[SetBlock, ...]:
        return (
            SetBlock.equation(0, coordinate(1, 2), "p' = v"),
            SetBlock(
                (1,),
                max_groups=(_interval(-self.force_bound, self.force_bound, 2),),
                name="v' ∈ [−U, U] − F·Sgn(v)",
                signs=(SignTerm(self.friction, affine({1: -1.0}, 2), self.band, "F·Sgn(v)"),),  # F·Sgn(−v) = −F·Sgn(v)
            ),
        )

    def initial_guess(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rest at x0 (z ≡ 0): the first iterate is the start state held still."""
        return np.tile(self.x0, (t.size, 1)), np.zeros((t.size, 2))


SLIDING_X0 = (2 * np.pi / 3, np.pi / 3, 0.0, 0.0)
SLIDING_TARGET = (-np.pi / 6, -np.pi / 4)
SLIDING_A, SLIDING_B = 0.15, -0.05  # c1 = x1 + a·x2², c2 = x2 + b·x1³


class SlidingModeTerminal(InclusionModel):
    """Two switching surfaces with sliding modes, bounded v', and a terminal state (FESD paper's OCP)."""

    name = "sliding-mode-terminal"
    description = "Sliding modes on two surfaces, |v'| ≤ 10, terminal x(4) (nosnoc's sliding_mode_ocp; peer: nosnoc)"
    state_names = ("x1", "x2", "v1", "v2")
    default_T = 4.0
    default_x0 = SLIDING_X0
    end_indices = (0, 1)
    default_end_values = SLIDING_TARGET
    input_bound = 10.0
    band = BAND

    def blocks(self) -> tuple[SetBlock, ...]:
        def minus_c1(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            gradient = np.zeros_like(y)
            gradient[:, 0], gradient[:, 1] = -1.0, -2 * SLIDING_A * y[:, 1]
            return -(y[:, 0] + SLIDING_A * y[:, 1] ** 2), gradient

        def minus_c2(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            gradient = np.zeros_like(y)
            gradient[:, 0], gradient[:, 1] = -3 * SLIDING_B * y[:, 0] ** 2, -1.0
            return -(y[:, 1] + SLIDING_B * y[:, 0] ** 3), gradient

        minus_c1.formulas = lambda y: [-(y[0] + SLIDING_A * y[1] ** 2)]  # the optional hook of qdframe.model
        minus_c2.formulas = lambda y: [-(y[1] + SLIDING_B * y[0] ** 3)]
        bound = self.input_bound
        return (
            SetBlock.equation(0, coordinate(2, 4), "x1' ∈ v1 − Sgn(c1)", (SignTerm(1.0, minus_c1, self.band, "Sgn(c1)"),)),
            SetBlock.equation(1, coordinate(3, 4), "x2' ∈ v2 − Sgn(c2)", (SignTerm(1.0, minus_c2, self.band, "Sgn(c2)"),)),
            SetBlock((2,), max_groups=(_interval(-bound, bound, 4),), name="v1' ∈ [−10, 10]"),
            SetBlock((3,), max_groups=(_interval(-bound, bound, 4),), name="v2' ∈ [−10, 10]"),
        )


BENCH_MODELS: dict[str, type[InclusionModel]] = {
    CoulombRestToRest.name: CoulombRestToRest,
    SlidingModeTerminal.name: SlidingModeTerminal,
}
