"""A requested accuracy: the error estimate, the located switch times and the mesh they give.

    python examples/accuracy.py [--models block-breakaway slide-after-reaching] [--accuracy 1e-6]

For each model (each has an exact solution), solves it twice: by the default call (refined
from the model's motion until its estimate meets the default target 1e-6·max(1, |x|)), and
with `accuracy=` (radau-iia from 21 points, mesh points moved onto the switch times, refined
where the local error is large). Prints the points, the error estimate against the true
error max |x − x*|, and the switch times.
"""

from __future__ import annotations

import argparse

import qdframe


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=["block-breakaway", "slide-after-reaching"])
    parser.add_argument("--accuracy", type=float, default=1e-6)
    args = parser.parse_args()
    print("| model | solve | points | status | error estimate | true error | switch times | time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    missed = []
    for name in args.models:
        for label, result in (("default call", qdframe.solve(name)),
                              (f"accuracy={args.accuracy:g}", qdframe.solve(name, accuracy=args.accuracy))):
            estimate = "—" if result.error_estimate is None else f"{result.error_estimate:.1e}"
            times = ", ".join(f"{t:.10g}" for t in result.switch_times) or "—"
            print(f"| {name} | {label} | {result.nodes} | {result.status} | {estimate} "
                  f"| {result.solution_error:.1e} | {times} | {result.wall_time_s:.2f} |", flush=True)
            # each ends `solved`, its true error within its error estimate
            if result.status != "solved" or result.solution_error > result.error_estimate:
                missed.append(f"{name}, {label}")
    if missed:
        raise SystemExit(f"expected `solved` with the true error within the estimate: {'; '.join(missed)}")


if __name__ == "__main__":
    main()
