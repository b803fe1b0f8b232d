"""When does a thrown block reach a mark? A free end time (docs/guide.md, "Free end time and parameters").

    p' = v,   v' ∈ −2·Sgn(v),   p(0) = 0, v(0) = 2,   p(T) = 0.75,   T unknown

`free_T = True` makes T an unknown found with x; `default_T` is only its first guess. The
block decelerates at 2, so p = 2t − t² and the answer is T* = 0.5. The result's t runs to
the T found; `result.T` is it. Writes stopping_time.png.

Run: python examples/stopping_time.py
"""

from __future__ import annotations

import qdframe
from qdframe.sets import SetModel, Sgn


class ThrownBlock(SetModel):
    """p' = v, v' ∈ −2 Sgn(v) from (0, 2): when is p = 0.75?"""

    name = "thrown-block"
    state_names = "p v"
    default_x0 = (0.0, 2.0)
    default_xT = {"p": 0.75}
    default_T = 1.0  # a guess
    free_T = True

    def sets(self, p, v):
        return {p: v, v: -2 * Sgn(v)}


def main() -> None:
    result = qdframe.solve(ThrownBlock())
    print(f"{result.status}: T = {result.T:.12f} (exact 0.5, |T − T*| = {abs(result.T - 0.5):.1e}), "
          f"error estimate {result.error_estimate:.1e} on {result.nodes} points")
    result.plot("stopping_time.png")
    print("wrote stopping_time.png")
    tol = result.accuracy * max(1.0, abs(result.x).max())  # what `solved` promises, T included
    if result.status != "solved" or abs(result.T - 0.5) > tol:
        raise SystemExit(f"expected `solved` with |T − 0.5| ≤ {tol:.0e}, got {result.status}, T = {result.T}")


if __name__ == "__main__":
    main()
