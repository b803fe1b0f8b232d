"""Filippov simulation: the reaching phase of Example 7.3 onto the surface x4 = 0.

From x(−0.2) = (−1, 1, −1, −1, 1, 1) with u = 0 the trajectory reaches x4 = 0 and then
slides on it; its end is the x(0) of paper-7.3 (the paper's rounded numbers:
−1.053, 1.099, −0.787, 0, 0.026, 1.119). Writes reaching-phase.png into --out (default .).

    python examples/simulate_reaching.py [--out DIR]
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import qdframe  # noqa: E402
from qdframe.simulate import simulate  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", type=Path, default=Path("."), help="output folder (created; default: the current one)")
out = parser.parse_args().out
out.mkdir(parents=True, exist_ok=True)

start = (-1.0, 1.0, -1.0, -1.0, 1.0, 1.0)
PAPER = (-1.053, 1.099, -0.787, 0.0, 0.026, 1.119)  # the paper's x(0), rounded
model = qdframe.load_model("paper-7.3", x0=start)
run = simulate(model, -0.2, 0.0, start, dt=1e-4)
print("x(0) =", ", ".join(f"{name} {value:.4f}" for name, value in zip(run.state_names, run.x[-1])))

fig, ax = plt.subplots(figsize=(6, 3.5), constrained_layout=True)
for i, name in enumerate(run.state_names):
    ax.plot(run.t, run.x[:, i], label=name)
ax.set(xlabel="t", title="reaching phase: x4 hits the surface x4 = 0 and slides")
ax.legend(ncol=3)
fig.savefig(out / "reaching-phase.png", dpi=110)
print(f"wrote {out / 'reaching-phase.png'}")
if max(abs(value - paper) for value, paper in zip(run.x[-1], PAPER)) > 1e-3:  # to the paper's last digit
    raise SystemExit(f"x(0) misses the paper's {PAPER} by more than 1e-3")
