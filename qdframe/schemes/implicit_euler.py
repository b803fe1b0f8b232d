"""Implicit Euler, the standard scheme for complementarity systems: first order, L-stable.

Z_k = Z_{k−1} + h·z_k: x_k − x_{k−1} = h·z_k with z_k ∈ F(x_k), as Moreau–Jean time
stepping and the Filippov simulator. z_0 is not used by the rule; it is kept (weight
h/2) as a velocity in F(x_0), so every reported z_k is checked against F.
"""

from __future__ import annotations

import numpy as np

from .base import Layout, Scheme, one_step_layout


class ImplicitEuler(Scheme):
    name = "implicit-euler"
    description = "implicit Euler, order 1, the complementarity systems' standard"
    order = 1
    velocity_points = (1,)  # x' on (t_k, t_{k+1}] is z_{k+1}

    def layout(self, mesh: np.ndarray) -> Layout:
        return one_step_layout(mesh, lower=0.0, diagonal=1.0, ends=(0.5, 1.0))
