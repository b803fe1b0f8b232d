"""A force that depends on time, in the set language (docs/authoring.md, section 2).

    p' = v,   v' ∈ sin(2t) − 0.5·Sgn(v),   from rest,   T = 6

`sets` receives the states, not t: the model carries t as a clock state c (c' = 1,
c(0) = 0) and writes the force in c. The block sticks until sin(2t) exceeds the friction
0.5 (t = π/12), slides, stops and sticks again as the force swings. The default call
certifies the trajectory to 1e-6·max(1, max|x|); the clock reaches 6, so the second solve
asks for 1e-6/6 to hold p and v themselves to 1e-6.

Run: python examples/time_forcing.py
"""

from __future__ import annotations

import sympy as sp

import qdframe
from qdframe.sets import SetModel, Sgn


class ShakenBlock(SetModel):
    """p' = v, v' ∈ sin(2t) − 0.5 Sgn(v), from rest; t carried by the clock c."""

    name = "shaken-block"
    state_names = "p v c"
    default_x0 = (0.0, 0.0, 0.0)
    default_T = 6.0

    def sets(self, p, v, c):
        return {p: v, v: sp.sin(2 * c) - 0.5 * Sgn(v), c: 1}


def main() -> None:
    for accuracy in (None, 1e-6 / 6):
        result = qdframe.solve(ShakenBlock(), accuracy=accuracy)
        label = "default target" if accuracy is None else f"accuracy={accuracy:.2g}"
        switches = ", ".join(f"{t:.4f}" for t in result.switch_times)
        print(f"{label}: {result.status} on {result.nodes} points, error estimate {result.error_estimate:.1e}, "
              f"switches at t = {switches}")
        if result.status != "solved":  # certified to its target, 1e-6·max(1, max|x|) or 1e-6/6 of it
            raise SystemExit(f"{label}: expected `solved`, got {result.status}")


if __name__ == "__main__":
    main()
