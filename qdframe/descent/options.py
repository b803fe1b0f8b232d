"""The options of one descent (:class:`DescentOptions`, the paper's δ, ε, γ̄ and the stopping
rules' tolerances) and the progress callback's type."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..result import IterationRecord

ProgressCallback = Callable[[IterationRecord], None]
EPS_FLOOR = 1e-12  # the smallest ε of a certified solve (solve's eps_floor=None where the mesh is refined)


@dataclass(frozen=True)
class DescentOptions:
    """The method's parameters; the paper's defaults δ = 1e-3, ε = 1e-2, γ̄ = 1 (Section 7).

    eps_floor: where every node's deviation is ≤ ε but the iterate is not solved, ε and δ
    shrink together by EPS_SHRINK and the descent goes on, down to ε = eps_floor (the
    paper's method carried to convergence); eps_floor = eps keeps ε and δ fixed."""

    max_iter: int = 500
    tol: float = 1e-10
    delta: float = 1e-3
    eps: float = 1e-2
    gamma_max: float = 1.0
    residual_tol: float = 1e-8  # pointwise, scaled to the states: see :mod:`qdframe.descent.checks`
    eps_floor: float = 1e-12  # EPS_FLOOR

    def __post_init__(self) -> None:
        if isinstance(self.max_iter, bool) or not isinstance(self.max_iter, (int, np.integer)) or self.max_iter < 0:
            raise InputError("max_iter", "an integer ≥ 0", self.max_iter)
        for field_name in ("tol", "delta", "eps", "gamma_max", "residual_tol", "eps_floor"):
            value = getattr(self, field_name)
            if not isinstance(value, (int, float, np.floating)) or not np.isfinite(value) or value <= 0:
                raise InputError(field_name, "a positive finite number", value)
        if self.eps_floor > self.eps:
            raise InputError("eps_floor", f"a number ≤ eps = {self.eps:g} (eps_floor = eps: ε and δ fixed)",
                             self.eps_floor)
