"""A new inclusion in a few lines: x' ∈ [−1, 1]·|x| + 1, from x(0) = 0 to x(1) = 1.5.

F(x) = [1 − |x|, 1 + |x|] has the support function c(F, ψ) = ψ + max{xψ, −xψ}·|ψ|,
i.e. for ψ = ±1 one constant piece and one max-group over {x, −x} (paper (supf)).
"""

import numpy as np

import qdframe
from qdframe import InclusionModel, MaxGroup, SetBlock


def pieces(x):
    """f_q(x) for the max-group co{1 + x, 1 − x}: values (N, 2, 1), Jacobians (N, 2, 1, 1)."""
    values = np.stack([1 + x[:, 0], 1 - x[:, 0]], axis=1)[:, :, None]
    jac = np.zeros((x.shape[0], 2, 1, 1))
    jac[:, 0, 0, 0], jac[:, 1, 0, 0] = 1.0, -1.0
    return values, jac


class Spreading(InclusionModel):
    """x' ∈ [1 − |x|, 1 + |x|]."""

    name = "spreading"
    state_names = ("x",)
    default_x0 = (0.0,)
    end_indices = (0,)
    default_end_values = (1.5,)

    def blocks(self):
        return (SetBlock((0,), max_groups=(MaxGroup(pieces, "1 ± x"),)),)


if __name__ == "__main__":
    result = qdframe.solve(Spreading())
    print(result.summary())
    if result.status != "solved":
        raise SystemExit(f"expected `solved`, got {result.status}")
