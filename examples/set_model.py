"""A model written with the set layer (qdframe.sets): formulas, no derivatives.

A room θ warmed by a heater whose power lies anywhere in [0, 5], and its wall w:
θ' ∈ 0.3·(w − θ) + 0.1·(5 − θ) + [0, 5],  w' = 0.2·(θ − w),  θ(0) = 15, w(0) = 12, θ(2) = 17.
"""

import numpy as np

import qdframe
from qdframe.authoring import check_model
from qdframe.sets import Interval, SetModel


class HeatedRoom(SetModel):
    """Room θ and wall w with an uncertain heater power in [0, 5]."""

    name = "heated-room"
    state_names = "theta wall"
    default_T = 2.0
    default_x0 = (15.0, 12.0)
    default_xT = {"theta": 17.0}

    def sets(self, theta, wall):
        return {
            theta: 0.3 * (wall - theta) + 0.1 * (5 - theta) + Interval(0, 5),
            wall: 0.2 * (theta - wall),
        }

    def initial_guess(self, t):
        line = 15.0 + 2.0 * t / self.T
        return np.stack([line, np.full_like(t, 12.0)], axis=1), np.zeros((t.size, 2))


if __name__ == "__main__":
    model = HeatedRoom()
    report = check_model(model)
    print(report.table())
    result = qdframe.solve(model)
    print(result.summary())
    if not report.ok or result.status != "solved":  # docs/authoring.md: checked, and `solved`
        raise SystemExit(f"expected a checked model and `solved`, got {len(report.failures)} failed pieces "
                         f"and {result.status}")
