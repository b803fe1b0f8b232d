"""The shortest time to move a block between two rest states: a time-optimal problem
(docs/guide.md, "Free end time and parameters").

    p' = v,   v' ∈ [−2, 2] − Sgn(v),   x(0) = (0, 0),   x(T) = (1, 0),   minimize T

A force |u| ≤ 2 against Coulomb friction 1, written as a set: v' ∈ [−2, 2] − Sgn(v).
`free_T = True` makes T an unknown; the running cost 1 makes the cost ∫1 dt = T, so the
solve minimizes T over the trajectories (qdframe/solve/optimum.py: the penalty λ of T + λ·I is
raised until the optimality gap and every pointwise check are within the target). The
answer is bang-bang: full force forward until t = √1.5 (v' = 1), then full force back
(v' = −3) until T* = (4/3)·√1.5 ≈ 1.633. Writes time_optimal.png.

Run: python examples/time_optimal.py
"""

from __future__ import annotations

import numpy as np

import qdframe
from qdframe.sets import Interval, SetModel, Sgn

T_STAR = 4 / 3 * np.sqrt(1.5)


class FastestMove(SetModel):
    """p' = v, v' ∈ [−2, 2] − Sgn(v) from rest at 0 to rest at 1, in the least time."""

    name = "fastest-move"
    state_names = "p v"
    default_x0 = (0.0, 0.0)
    default_xT = {"p": 1.0, "v": 0.0}
    default_T = 2.0  # a guess
    free_T = True

    def sets(self, p, v):
        return {p: v, v: Interval(-2, 2) - Sgn(v)}

    def running_cost(self, p, v):
        return 1.0 + 0 * p  # ∫1 dt = T


def main() -> None:
    result = qdframe.solve(FastestMove())
    print(f"{result.status}: T = {result.T:.12f} (exact {T_STAR:.12f}, |T − T*| = {abs(result.T - T_STAR):.1e}), "
          f"error estimate {result.error_estimate:.1e} on {result.nodes} points, "
          f"penalty λ = {result.options['penalty']:.0e}")
    result.plot("time_optimal.png")
    print("wrote time_optimal.png")
    tol = result.accuracy * max(1.0, abs(result.x).max())  # what `solved` promises, T included
    if result.status != "solved" or abs(result.T - T_STAR) > tol:
        raise SystemExit(f"expected `solved` with |T − T*| ≤ {tol:.0e}, got {result.status}, T = {result.T}")


if __name__ == "__main__":
    main()
