"""Solve Example 7.1 from Python with the paper's method, read the result, write JSON and a figure.

The paper's method (direction "native", golden line search) on 101 nodes, as in the
paper's Section 7: it ends `stationary`, the paper's own stopping rule, with the summary
saying which conditions are left unmet and by how much; `qdframe.solve(model)` with the
default direction (gauss-newton) solves it (README, "The paper's method against gauss-newton").

    python examples/solve_paper.py [--out DIR]    (DIR: where the files go; default .)
"""

import argparse
from pathlib import Path

import qdframe
from qdframe.plotting import plot_result

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", type=Path, default=Path("."), help="output folder (created; default: the current one)")
out = parser.parse_args().out
out.mkdir(parents=True, exist_ok=True)

model = qdframe.load_model("paper-7.1")
result = qdframe.solve(model, nodes=101, direction="native", line_search="golden")
print(result.summary())
print("x1 stays near 0:", abs(result.x[:, 0]).max())
result.to_json(out / "paper-7.1.json")
plot_result(result, out / "paper-7.1.png")
print(f"wrote {out / 'paper-7.1.json'} and {out / 'paper-7.1.png'}")
# the paper's stopping rule, within the paper's accuracy (objective ≤ 1e-3, boundary error ≤ 5e-3)
if result.status != "stationary" or result.objective > 1e-3 or result.boundary_error > 5e-3:
    raise SystemExit(f"expected `stationary` within the paper's accuracy, got {result.status}, "
                     f"objective {result.objective:.1e}, boundary error {result.boundary_error:.1e}")
