"""Which friction coefficient stops a block at a mark? An unknown parameter.

    p' = v,   v' ∈ −μ·Sgn(v),   p(0) = 0, v(0) = 2,   p(1.5) = 1,   μ unknown

`parameter_names = "mu"` makes μ an unknown found with x; `sets` receives it after the
states; `default_parameters` is its first guess and `parameter_bounds` keeps it positive.
The block stops after 2/μ at p = 2/μ and sticks, so μ* = 2 (it stops at t = 1 and sticks
until T = 1.5). Writes friction_coefficient.png.

Run: python examples/friction_coefficient.py
"""

from __future__ import annotations

import numpy as np

import qdframe
from qdframe.sets import SetModel, Sgn


class BlockToMark(SetModel):
    """p' = v, v' ∈ −μ Sgn(v) from (0, 2), p(1.5) = 1: which μ?"""

    name = "block-to-mark"
    state_names = "p v"
    parameter_names = "mu"
    default_parameters = (1.0,)  # a guess
    parameter_bounds = {"mu": (0.0, np.inf)}
    default_x0 = (0.0, 2.0)
    default_xT = {"p": 1.0}
    default_T = 1.5

    def sets(self, p, v, mu):
        return {p: v, v: -mu * Sgn(v)}


def main() -> None:
    result = qdframe.solve(BlockToMark())
    mu = result.parameters["mu"]
    print(f"{result.status}: mu = {mu:.12f} (exact 2, |mu − 2| = {abs(mu - 2):.1e}), stops at t = "
          f"{result.switch_times[0]:.9f}, error estimate {result.error_estimate:.1e}")
    result.plot("friction_coefficient.png")
    print("wrote friction_coefficient.png")
    tol = result.accuracy * max(1.0, abs(result.x).max())  # what `solved` promises, μ included
    if result.status != "solved" or abs(mu - 2) > tol:
        raise SystemExit(f"expected `solved` with |mu − 2| ≤ {tol:.0e}, got {result.status}, mu = {mu}")


if __name__ == "__main__":
    main()
