"""Optimal control with friction: a least effort under a control bound, the same under a speed
limit, and a terminal cost (docs/guide.md, "Optimal control").

    p' = v,   v' ∈ u − 0.5·Sgn(v),   x(0) = (0, 0),   x(2) = (1, 0),   |u| ≤ 1.5,   minimize ∫u² dt

A block under Coulomb friction pushed from rest at 0 to rest at 1. While it moves forward the
friction is the constant −0.5, so Pontryagin's principle gives u* = clip(α − βt, −1.5, 1.5):
the bound binds on [0, 1/2], and J* = 37/18 (qdframe/models/optimal_references.py derives it).
The second replaces the control bound by a speed limit, a state bound v ≤ 0.6 that binds on
[1/2, 3/2] (the unbounded optimum peaks at 0.75): u* = 0.5 + 4.8·(1/2 − t) up to 1/2, 0.5 on the
limit, and J* = 2.42 (`least_effort_speed_bounded` there).
The third has no end values but a terminal cost: the double integrator from rest,
minimize ∫u² dt + 50·((p(1) − 2)² + v(1)²), J* = 850/23 (by the controllability Gramian).

All three are solved by the method of multipliers (docs/method.md, "Optimal control"): the
inclusion's residuals are the constraints, λ stays at most 1e6. Prints each cost against
its exact value and its own estimate of the distance (`result.cost_estimate`), and exits
non-zero where one misses what `solved` promises.

Run: python examples/optimal_control.py
"""

from __future__ import annotations

import numpy as np

import qdframe
from qdframe.sets import SetModel, Sgn


class BoundedPush(SetModel):
    """The least ∫u² that moves a Coulomb block from rest at 0 to rest at 1 in T = 2, |u| ≤ 1.5."""

    state_names = "p v"
    control_names = "u"
    default_x0 = (0.0, 0.0)
    default_xT = {"p": 1.0, "v": 0.0}
    default_T = 2.0
    control_bounds = {"u": (-1.5, 1.5)}

    def sets(self, p, v, u):
        return {p: v, v: u - 0.5 * Sgn(v)}

    def running_cost(self, p, v, u):
        return u**2


class SpeedLimit(BoundedPush):
    """The same push with u free and the speed held to v ≤ 0.6 (a path constraint)."""

    control_bounds = {}
    state_bounds = {"v": (-np.inf, 0.6)}


class Aim(SetModel):
    """The double integrator from rest: ∫u² dt + 50·((p(1) − 2)² + v(1)²), no end values."""

    state_names = "p v"
    control_names = "u"
    default_x0 = (0.0, 0.0)

    def sets(self, p, v, u):
        return {p: v, v: u}

    def running_cost(self, p, v, u):
        return u**2

    def terminal_cost(self, p, v):
        return 50 * ((p - 2) ** 2 + v**2)


def main() -> None:
    failures = []
    for model, exact in ((BoundedPush(), 37 / 18), (SpeedLimit(), 2.42), (Aim(), 850 / 23)):
        result = qdframe.solve(model)
        u = np.asarray(result.u)[1:, 0]  # (the first point's u is not in Radau IIA's rule)
        print(f"{type(model).__name__}: {result.status}, J = {result.cost:.10f} (exact {exact:.10f}, "
              f"|J − J*| = {abs(result.cost - exact):.1e}, its estimate {result.cost_estimate:.1e}), error "
              f"estimate {result.error_estimate:.1e} on {result.nodes} points, max|u| = {np.max(np.abs(u)):.6f}, "
              f"λ = {result.options['penalty']:.0e}")
        if result.status != "solved" or not abs(result.cost - exact) <= result.cost_estimate <= 1e-6 * max(1.0, exact):
            failures.append(f"{type(model).__name__}: expected `solved` with |J − J*| ≤ its estimate ≤ 1e-6·max(1, J*), "
                            f"got {result.status}, J = {result.cost}, estimate {result.cost_estimate}")
    if failures:
        raise SystemExit("; ".join(failures))


if __name__ == "__main__":
    main()
