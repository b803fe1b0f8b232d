"""The outer loop of a solve: `solve()` (:mod:`.solving`), the grids and the continuation
between them (:mod:`.continuation`), the starts a grid chooses from (:mod:`.start`), the
rounds of a cost whose least value is not 0 (:mod:`.optimum`), and the verdict
(:mod:`.verdict`) with its refinement to an accuracy (:mod:`.adaptive`)."""

from .solving import solve

__all__ = ["solve"]
