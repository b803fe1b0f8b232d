"""Judge your own solves against a reference: the yardstick of `qdframe bench run`, from Python.

    python examples/work_precision.py [--model sliding-mode-terminal] [--nodes 11 101 1001] [--accuracy 1e-3 1e-6]

Solves one model on a ladder of uniform grids and with `accuracy=` targets, and judges
every result by `qdframe.bench.references.judge`: the max over the result's own points
of |x − x_ref|. For a model with one solution x_ref is its closed form; for one whose
solutions form a set (here, a bounded input to choose) x_ref is the true Filippov motion
that the result's own input drives, and the error also counts how far that motion misses
the end conditions. Prints wall time against error, and whether each `solved` holds up.
"""

from __future__ import annotations

import argparse

import qdframe
from qdframe.bench.references import judge
from qdframe.bench.execution import scheme_velocity


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="sliding-mode-terminal")
    parser.add_argument("--nodes", type=int, nargs="+", default=[11, 101, 1001])
    parser.add_argument("--accuracy", type=float, nargs="+", default=[1e-3, 1e-6])
    args = parser.parse_args()
    model = qdframe.load_model(args.model)
    runs = [(f"N = {n}", dict(nodes=n, estimate=False)) for n in args.nodes]
    runs += [(f"accuracy = {e:g}", dict(accuracy=e)) for e in args.accuracy]
    print(f"{args.model}: reference = the model's {'closed form' if model.exact_solution([0.0]) is not None else 'replayed motion'}")
    print("| solve | points | status | time (s) | error | end error | target | `solved` holds up |")
    print("|---|---|---|---|---|---|---|---|")
    broken = []
    for label, options in runs:
        result = qdframe.solve(model, **options)
        verdict = judge(model, result.t, result.x, result.z, result.u, switch_times=result.switch_times,
                        velocity=scheme_velocity(result), selections=result.selections)
        tol = result.accuracy * max(1.0, float(abs(result.x).max()))  # the promise: accuracy·max(1, max|x|)
        holds = "—" if result.status != "solved" else ("yes" if verdict.error <= tol else f"no (> {tol:g})")
        print(f"| {label} | {result.nodes} | {result.status} | {result.wall_time_s:.2f} | {verdict.error:.1e} "
              f"| {verdict.end_error:.1e} | {tol:.1e} | {holds} |")
        if holds.startswith("no"):
            broken.append(label)
    if broken:
        raise SystemExit(f"`solved` does not hold up against the reference: {', '.join(broken)}")


if __name__ == "__main__":
    main()
