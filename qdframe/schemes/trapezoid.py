"""The trapezoid rule, the paper's discretization (Section 7): second order.

Z_k = Z_{k−1} + h/2·(z_{k−1} + z_k), trapezoid weights. For friction problems beware its
alternating null mode: z_k = (−1)^k·c leaves every x_k unchanged, so a stuck block's
velocity (and its friction selection) is not determined by the scheme.
"""

from __future__ import annotations

import numpy as np

from .base import Layout, Scheme, one_step_layout


class Trapezoid(Scheme):
    name = "trapezoid"
    description = "trapezoid rule (the paper's), order 2"
    order = 2

    def layout(self, mesh: np.ndarray) -> Layout:
        return one_step_layout(mesh, lower=0.5, diagonal=0.5, ends=(0.5, 0.5))
