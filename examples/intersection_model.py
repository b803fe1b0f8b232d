"""An intersection of sets by hand: x' ∈ B_r(x)((−0.5, 0)) ∩ B_r(x)((0.5, 0)), r(x) = 1 + x1²/2,
from x(0) = (0, 0) to x(1) = (0, 0.8).

The support function of a disc of radius r about c is ⟨c, ψ⟩ + r‖ψ‖; for an intersection
the solver uses c̃ = the min over the discs (paper Remark 5.1), a min-group on a block of two
coordinates, whose ψ* is searched on the circle S_2. `pieces` gives the discs' values with
their x-gradients (∂/∂x1 = x1‖ψ‖); `values` gives the values alone, which is all the search
needs (it evaluates them a hundred times or more per node). The model check compares both
with finite differences and with each other, and a solve compares them once more before
its first search.
"""

import numpy as np

import qdframe
from qdframe import InclusionModel, MinGroup, SetBlock
from qdframe.authoring import check_model

CENTERS = np.array([[-0.5, 0.0], [0.5, 0.0]])  # one disc per row


def values(x: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """g_p(x, ψ) = ⟨c_p, ψ⟩ + r(x)‖ψ‖ for both discs: (N, 2)."""
    radius = 1.0 + 0.5 * x[:, 0] ** 2
    return psi @ CENTERS.T + (radius * np.linalg.norm(psi, axis=1))[:, None]


def pieces(x: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The values and their x-gradients (N, 2, n): r'(x1) = x1, the same for both discs."""
    grads = np.zeros((x.shape[0], 2, x.shape[1]))
    grads[:, :, 0] = (x[:, 0] * np.linalg.norm(psi, axis=1))[:, None]
    return values(x, psi), grads


class Lens(InclusionModel):
    """x' in the lens of two discs whose radius grows with x1."""

    name = "lens"
    state_names = ("x1", "x2")
    default_x0 = (0.0, 0.0)
    end_indices = (0, 1)
    default_end_values = (0.0, 0.8)

    def blocks(self) -> tuple[SetBlock, ...]:
        return (SetBlock((0, 1), min_groups=(MinGroup(pieces, "two discs", values=values),), name="F"),)


if __name__ == "__main__":
    report = check_model(Lens())
    print(report.table())
    result = qdframe.solve(Lens(), nodes=101)
    print(result.summary())
    if not report.ok or result.status != "solved":  # docs/guide.md: it checks the model and solves with it
        raise SystemExit(f"expected a checked model and `solved`, got {len(report.failures)} failed pieces "
                         f"and {result.status}")
