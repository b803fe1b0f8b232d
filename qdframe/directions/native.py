"""The `native` direction: the paper's min-norm problems, solved exactly in NumPy."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import MinNormDirection
from .minnorm import min_norm_point


@dataclass(frozen=True)
class NativeDirection(MinNormDirection):
    """Exact batched solver of the direction subproblem (no QP library).

    Vectorized over all nodes and vertices: see :func:`qdframe.directions.minnorm.min_norm_point`.
    """

    name = "native"

    def min_norm(self, center: np.ndarray, generators: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return min_norm_point(center, generators, mask)
