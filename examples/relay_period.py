"""The period of a relay oscillation: a free end time with periodic conditions.

    x1' = x2,   x2' ∈ −Sgn(x1),   x(0) = (1, 0),   x(T) = x(0),   T unknown

The orbit through (1, 0) is four parabolas; its period is T* = 4√2 ≈ 5.657. T is started
from a guess: the motion from x(0) is integrated once over [T/2, 2T] and the T that comes
back nearest to x(0) starts the solve (from T/2 up: near T = 0 a constant x is "periodic"
too). Each guess below finds T*. Writes relay_period.png.

Run: python examples/relay_period.py
"""

from __future__ import annotations

import numpy as np

import qdframe
from qdframe.sets import SetModel, Sgn


class Relay(SetModel):
    """x1' = x2, x2' ∈ −Sgn(x1) through (1, 0), periodic: what is its period?"""

    name = "relay"
    state_names = "x1 x2"
    default_x0 = (1.0, 0.0)
    periodic = ("x1", "x2")
    default_T = 5.0
    free_T = True

    def sets(self, x1, x2):
        return {x1: x2, x2: -Sgn(x1)}


def main() -> None:
    exact = 4 * np.sqrt(2)
    missed = []
    for guess in (3.0, 5.0, 7.0):
        result = qdframe.solve(Relay(T=guess))
        print(f"guess T = {guess}: {result.status}, T = {result.T:.12f} (|T − 4√2| = {abs(result.T - exact):.1e}), "
              f"crossings at t = {', '.join(f'{t:.6f}' for t in result.switch_times)}")
        tol = result.accuracy * max(1.0, abs(result.x).max())  # what `solved` promises, T included
        if result.status != "solved" or abs(result.T - exact) > tol:
            missed.append(f"guess {guess}: {result.status}, T = {result.T}")
    result.plot("relay_period.png")
    print("wrote relay_period.png")
    if missed:
        raise SystemExit(f"expected `solved` with T = 4√2 from every guess: {'; '.join(missed)}")


if __name__ == "__main__":
    main()
