"""The paper's Example 7.3: three masses, dry friction, a sliding mode on x4 = 0.

    x1' = x4,  x2' = x5,  x3' = x6
    x4' ∈ −x1 + (x2 − x1) − x4 − 1.05·|x|·Sgn(x4)
    x5' ∈ (x1 − x2) + (x3 − x2) − x5 − 0.3·Sgn(x5)
    x6' ∈ (x2 − x3) − x6 − 0.3·Sgn(x6) + u

|x| is the l1 norm Σ|x_i| (Section 5 writes it as Σ max{a x_i ψ, −a x_i ψ}). The sign
terms are Filippov's set-valued Sgn. The trajectory must stay on the surface x4 = 0
and bring the third mass to x3(1) = 0; u(t) is an unknown control. x(0) is the end
of the reaching phase on [−0.2, 0] with u = 0 from x(−0.2) = (−1, 1, −1, −1, 1, 1),
computed by the Filippov simulator once and kept as data (:data:`REACHING_END`; not the
paper's rounded numbers).

:class:`Paper73` is the registered ``paper-7.3``, and :class:`Paper73Reduced` (the
paper's reduction) derives from it. The set-language form ``paper_sets.Paper73Sets`` has
the same functional and quasidifferential to rounding but, the solution not being unique,
the default solve takes another path to another solution: registering it would change
published results.
tests/bench/test_filippov_reference.py and qdframe/bench/replay_statements.py state the reference
Filippov system from this module.
"""

from __future__ import annotations

import numpy as np

from ..ready_pieces import abs_sum, affine
from ..model import InclusionModel, SetBlock, SignTerm, Surface

REACHING_START = (-1.0, 1.0, -1.0, -1.0, 1.0, 1.0)
REACHING_TIME = 0.2
# x(0): the state where the reaching phase [−REACHING_TIME, 0] from REACHING_START with u = 0
# ends, by the event-driven Filippov simulation (qdframe.simulate, on this model); the model
# takes it as data, and tests/test_masses_and_signs.py simulates it again and holds these
# digits to it
REACHING_END = (-1.052416998365643, 1.099387196129389, -0.787251438817487, 6.637353512715934e-21,
                0.026497008046283743, 1.119553755053641)
FRICTION = 0.3
GAIN = 1.05
WIDTH = 7  # y = (x1, …, x6, u)


def _on_surface(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    jac = np.zeros((x.shape[0], 1, 6))
    jac[:, 0, 3] = 1.0
    return x[:, 3:4], jac


class Paper73(InclusionModel):
    """Example 7.3: three masses with dry friction sliding on x4 = 0, control u, x3(1) = 0."""

    name = "paper-7.3"
    description = "Example 7.3: three masses, dry friction, sliding on x4 = 0, unknown control u"
    state_names = ("x1", "x2", "x3", "x4", "x5", "x6")
    control_names = ("u",)
    default_T = 1.0
    end_indices = (2,)
    default_end_values = (0.0,)
    band = 1e-3  # the band β of the friction sign terms Sgn(x5), Sgn(x6)
    # On the surface x4 = 0 the paper takes x4' ∈ … + 1.05|x|·[−1, 1] (Filippov's set):
    # band inf; the surface term ω enforces x4 = 0, where this is exact.
    surface_band = float("inf")

    def __init__(self, T=None, x0=None, end_values=None) -> None:
        """Without `x0`, x(0) is the end of the reaching phase (:data:`REACHING_END`)."""
        super().__init__(T, REACHING_END if x0 is None else x0, end_values)

    def blocks(self) -> tuple[SetBlock, ...]:
        beta = self.band
        return (
            SetBlock.equation(0, affine({3: 1.0}, WIDTH), "x1' = x4"),
            SetBlock.equation(1, affine({4: 1.0}, WIDTH), "x2' = x5"),
            SetBlock.equation(2, affine({5: 1.0}, WIDTH), "x3' = x6"),
            # each switch is s = −v (a·Sgn(−v) = −a·Sgn(v))
            SetBlock.equation(3, affine({0: -2.0, 1: 1.0, 3: -1.0}, WIDTH), "x4'",
                              (SignTerm(abs_sum(range(6), GAIN, WIDTH), affine({3: -1.0}, WIDTH), self.surface_band,
                                        "1.05|x|Sgn(x4)"),)),
            SetBlock.equation(4, affine({0: 1.0, 1: -2.0, 2: 1.0, 4: -1.0}, WIDTH), "x5'",
                              (SignTerm(FRICTION, affine({4: -1.0}, WIDTH), beta, "0.3 Sgn(x5)"),)),
            SetBlock.equation(5, affine({1: 1.0, 2: -1.0, 5: -1.0, 6: 1.0}, WIDTH), "x6'",
                              (SignTerm(FRICTION, affine({5: -1.0}, WIDTH), beta, "0.3 Sgn(x6)"),)),
        )

    def surface(self) -> Surface:
        return Surface(_on_surface)

    def initial_guess(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The paper's first approximation: x, z, u ≡ 0 (x(0) = x0 is fixed)."""
        return np.zeros((t.size, 6)), np.zeros((t.size, 6))


class Paper73Reduced(Paper73):
    """Example 7.3 with the paper's reduction: x1' = x4, x2' = x5, x3' = x6 are resolved
    (z1..z3 are x4..x6 themselves, no sets, no residuals for them)."""

    name = "paper-7.3-reduced"
    description = "Example 7.3 with the resolved states x1..x3 eliminated from the unknowns z"
    resolved = {0: 3, 1: 4, 2: 5}

    def blocks(self) -> tuple[SetBlock, ...]:
        return super().blocks()[3:]
