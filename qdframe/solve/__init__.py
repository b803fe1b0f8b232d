"""The outer loop of a solve: `solve()` (:mod:`.solving`), the grids and the continuation
between them (:mod:`.continuation`), the starts a grid chooses from (:mod:`.start`), the
rounds of a cost whose least value is not 0 (:mod:`.optimum`), and the verdict
(:mod:`.verdict`) with its refinement to an accuracy (:mod:`.adaptive`)."""

from .plan import Plan, plan
from .solving import solve

solve.plan = plan  # qdframe.solve.plan(model, …): the Plan of qdframe.solve(model, …) with those arguments

__all__ = ["Plan", "plan", "solve"]
