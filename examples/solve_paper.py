"""Solve Example 7.1 from Python, read the result, write JSON and a figure."""

import qdframe

model = qdframe.load_model("paper-7.1")
result = qdframe.solve(model, nodes=101, direction="native", line_search="golden")
print(result.summary())
print("x1 stays near 0:", abs(result.x[:, 0]).max())
result.to_json("paper-7.1.json")

from qdframe.plotting import plot_result  # noqa: E402

plot_result(result, "paper-7.1.png")
