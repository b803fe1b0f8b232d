"""Dry friction in the plane: the vector sign Sgn(v1, v2) (docs/authoring.md, section 2).

A puck pulled along d = (0.6, 0.8) by a force F that ramps up (F' = 1/4), with isotropic
Coulomb friction μ = 1/2, launched across the pull:

    p' = v,   v' ∈ F·d − μ·Sgn(v1, v2),   Sgn(v) = v/|v| (v ≠ 0), the closed unit disc (v = 0).

It slides on a curve, stops at t = 1, sticks while F ≤ μ and breaks away at t = 2 (the
registered model `isotropic-puck`, with an independent reference). This script:

1. solves it by the default call and judges the result against the reference;
2. shows what the formula v/|v| gets (refused: undefined at rest), what μ·Ball((0, 0), 1)
   means (the whole disc at every velocity: not friction), and what two scalar signs
   Sgn(v1), Sgn(v2) mean (a box law, another motion).

Run: python examples/isotropic_friction.py
"""

from __future__ import annotations

import time

import numpy as np

import qdframe
from qdframe.ready_pieces import affine, ball_switch, coordinate
from qdframe.model import InclusionModel, SetBlock, SignTerm
from qdframe.models.planar_friction import IsotropicPuck, sled_phase
from qdframe.sets import SetModel, Sgn
from qdframe.sets import Ball, SetStructureError, sqrt  # the ways below that are refused or mean something else


class Puck(SetModel):
    """p' = v, v' ∈ F·d − μ·Sgn(v1, v2), F' = 1/4: slides on a curve, stops, sticks, breaks away."""

    name = "puck"
    state_names = "p1 p2 v1 v2 F"
    default_T = 2.7
    default_x0 = (0.0, 0.0, -0.3597313038160854, 0.2697984778620640, 0.0)  # launched across the pull

    def sets(self, p1, p2, v1, v2, F):
        S = Sgn(v1, v2)  # v/|v|, the closed unit disc at v = 0
        return {p1: v1, p2: v2, v1: 0.6 * F - 0.5 * S[0], v2: 0.8 * F - 0.5 * S[1], F: 0.25}


class HandPuck(InclusionModel):
    """p' = v, v' ∈ 0.5·d − Sgn(v1, v2) with d = (0.6, 0.8): slides on a curve, stops, sticks."""

    name = "hand-puck"
    state_names = ("p1", "p2", "v1", "v2")
    default_x0 = (0.0, 0.0, -0.8, 0.6)
    default_T = 2.0

    def blocks(self):
        S = ball_switch([2, 3], 4, name="Sgn(v1, v2)")  # s = (v1, v2): columns 2, 3 of y = (p1, p2, v1, v2)
        return (SetBlock.equation(0, coordinate(2, 4)), SetBlock.equation(1, coordinate(3, 4)),
                SetBlock.equation(2, affine({}, 4, 0.3), signs=(SignTerm(1.0, S, sense=-1.0, component=0),)),
                SetBlock.equation(3, affine({}, 4, 0.4), signs=(SignTerm(1.0, S, sense=-1.0, component=1),)))


class NormWritten(Puck):
    """v/|v| as a formula: undefined at v = 0, where the puck sticks."""

    name = "norm-written"

    def sets(self, p1, p2, v1, v2, F):
        speed = sqrt(v1**2 + v2**2)
        return {p1: v1, p2: v2, v1: 0.6 * F - 0.5 * v1 / speed, v2: 0.8 * F - 0.5 * v2 / speed, F: 0.25}


class WholeDisc(Puck):
    """f − μ·Ball((0, 0), 1): every force of the disc at every velocity (a set, not a law)."""

    name = "whole-disc"

    def sets(self, p1, p2, v1, v2, F):
        return {p1: v1, p2: v2, (v1, v2): (0.6 * F, 0.8 * F) - 0.5 * Ball((0, 0), 1), F: 0.25}


class BoxLaw(Puck):
    """−μ·(Sgn(v1), Sgn(v2)): friction against each axis separately, the box [−μ, μ]²."""

    name = "box-law"

    def sets(self, p1, p2, v1, v2, F):
        return {p1: v1, p2: v2, v1: 0.6 * F - 0.5 * Sgn(v1), v2: 0.8 * F - 0.5 * Sgn(v2), F: 0.25}


def own_switch_times(model, result) -> np.ndarray:
    """The switch times located on the result's trajectory alone (qdframe.certificates.switches)."""
    from qdframe.solve.adaptive import iterate
    from qdframe.functional import Functional
    from qdframe.schemes.grid import Grid, make_scheme
    from qdframe.certificates.switches import switch_times

    scheme = result.options["scheme"]
    functional = Functional(model, Grid.from_mesh(result.t[:: make_scheme(scheme).stages], scheme))
    return switch_times(functional, iterate(functional, result))


def main() -> None:
    reference = IsotropicPuck()  # the registered model: the same puck, with its independent reference
    assert np.allclose(Puck.default_x0, reference.default_x0, rtol=0, atol=1e-16)
    clock = time.perf_counter()
    result = qdframe.solve(Puck())
    seconds = time.perf_counter() - clock
    error = float(np.max(np.abs(result.x - reference.exact_solution(result.t))))
    print(f"Sgn(v1, v2): {result.status} on {result.nodes} points in {seconds:.1f} s, error estimate "
          f"{result.error_estimate:.1e} ({result.certificate}), true error {error:.1e}")
    print(f"  switch times {', '.join(f'{t:.10f}' for t in result.switch_times)} (exact: 1, 2); from the "
          f"trajectory alone {', '.join(f'{t:.10f}' for t in own_switch_times(Puck(), result))} (before the "
          f"replayed motion's events polish them)")
    stuck = (result.t > 1.01) & (result.t < 1.99)
    lam = result.selections[stuck]
    print(f"  stuck: |v| ≤ {np.max(np.abs(result.x[stuck, 2:4])):.0e}, the selection λ = (F/μ)·d inside the disc "
          f"(|λ| from {np.min(np.linalg.norm(lam, axis=1)):.2f} to {np.max(np.linalg.norm(lam, axis=1)):.2f})")
    # docs/authoring.md and friction.md: `solved`, the true error within the estimate, the stop and the
    # break-away at 1 and 2 to 2e-10, λ inside the disc while it sticks
    if (result.status != "solved" or error > result.error_estimate
            or not np.allclose(result.switch_times, [1.0, 2.0], rtol=0, atol=2e-10)
            or np.max(np.linalg.norm(lam, axis=1)) > 1.0):
        raise SystemExit("Sgn(v1, v2): not the `solved` answer the docs state (above)")
    space = qdframe.solve("isotropic-slide-3d")
    truth = qdframe.load_model("isotropic-slide-3d").exact_solution(space.t)
    print(f"isotropic-slide-3d: {space.status} on {space.nodes} points, true error {np.max(np.abs(space.x - truth)):.1e}, "
          f"stop at {space.switch_times[0]:.12f} (exact: 4/3)")
    space_tol = space.accuracy * max(1.0, np.max(np.abs(space.x)))  # friction.md: `solved`, the stop to 3e-11
    if space.status != "solved" or np.max(np.abs(space.x - truth)) > space_tol or abs(space.switch_times[0] - 4 / 3) > 3e-11:
        raise SystemExit("isotropic-slide-3d: not the `solved` answer the docs state (above)")
    hand = qdframe.solve(HandPuck())
    d, n = np.array([0.6, 0.8]), np.array([-0.8, 0.6])
    along, across, v_along, v_across = sled_phase(hand.t)  # the closed form of the slide under 0.5·d
    exact = np.concatenate([np.outer(along, d) + np.outer(across, n), np.outer(v_along, d) + np.outer(v_across, n)],
                           axis=1)
    print(f"the hand-written BallSwitch: {hand.status} on {hand.nodes} points, true error "
          f"{np.max(np.abs(hand.x - exact)):.1e}, stop at {hand.switch_times[0]:.10f} (exact: 4/3)")
    try:
        qdframe.solve(NormWritten())
    except SetStructureError as refused:
        print(f"v/|v| as a formula: refused, one line: {refused}")
    else:
        raise SystemExit("v/|v| as a formula: expected refused, and it was solved")
    for model in (WholeDisc(), BoxLaw()):
        other = qdframe.solve(model, nodes=201, estimate=False)
        away = float(np.max(np.abs(other.x - reference.exact_solution(other.t))))
        print(f"{model.__doc__.splitlines()[0]}\n  {other.status} in {other.iterations} iterations, "
              f"{away:.2f} away from the puck's motion")


if __name__ == "__main__":
    main()
