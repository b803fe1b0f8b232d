"""Dry friction and sliding with exact Filippov selections: a block that stops and sticks.

    python examples/friction.py [--nodes 101 1001 10001] [--scheme implicit-euler]

Solves `block-stop-stick` (v' ∈ 1 − 3·Sgn(v), v(0) = 2: stops at t = 1, sticks until
T = 3) from the default start and prints, per grid, how the run ended, the velocity in
the stick phase, the friction selection there (exact: Sgn(v) ∋ 1/3, coded as λ = −1/3 of
Sgn(−v)) and the error against the exact motion.
"""

from __future__ import annotations

import argparse

import numpy as np

import qdframe


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--nodes", type=int, nargs="+", default=[101, 1001, 10001])
    parser.add_argument("--scheme", default=None, help="default: the model's (implicit-euler)")
    args = parser.parse_args()
    print("| N | status | iterations | time (s) | max |v| stuck | λ stuck | error vs exact |")
    print("|---|---|---|---|---|---|---|")
    missed = []
    for nodes in args.nodes:
        result = qdframe.solve("block-stop-stick", nodes=nodes, scheme=args.scheme)
        stuck = result.t > 1.05  # after the stop at t = 1
        lam = result.selections[stuck, 0]
        print(f"| {nodes} | {result.status} | {result.iterations} | {result.wall_time_s:.2f} "
              f"| {np.max(np.abs(result.x[stuck, 1])):.1e} | {lam.min():.6f}…{lam.max():.6f} "
              f"| {result.solution_error:.2e} |", flush=True)
        # docs/friction.md: the discrete problem solved, |v| ≤ 1e-8 in the stick phase, λ = −1/3 there
        if not result.converged or np.max(np.abs(result.x[stuck, 1])) > 1e-8 or np.max(np.abs(lam + 1 / 3)) > 1e-6:
            missed.append(f"N = {nodes}")
    if missed:
        raise SystemExit(f"expected the discrete problem solved, |v| ≤ 1e-8 and λ = −1/3 when stuck: {', '.join(missed)}")


if __name__ == "__main__":
    main()
