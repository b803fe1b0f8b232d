"""Radau IIA collocation: stiffly accurate, order 2s − 1 at the mesh points with s stages.

`radau-iia` has two stages (order 3), `radau-iia5` three (order 5): long smooth arcs (a
stick-slip oscillator's 25 swings) need far fewer points to a tight accuracy with it.

Two stages:

On each mesh interval [t_k, t_k + h] (h may vary from interval to interval) the stages sit at c = (1/3, 1); the second stage is
the next mesh point. With A = [[5/12, −1/12], [3/4, 1/4]]:

    Z(t_k + h/3) = Z_k + h·(5/12·z_{k,1} − 1/12·z_{k+1}),
    Z_{k+1}      = Z_k + h·(3/4·z_{k,1} + 1/4·z_{k+1}).

`nodes` counts all points, mesh and stage: 2K + 1 for K intervals (so it is odd). The
weights are the Radau quadrature b = (3/4, 1/4)·h at the stage points; z at t_0 is not
used by the rule and is kept (weight h/4) as a velocity in F(x_0).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from .base import Layout, Scheme

A = np.array([[5 / 12, -1 / 12], [3 / 4, 1 / 4]])
C = np.array([1 / 3, 1.0])
B = A[1]
_R6 = np.sqrt(6.0)
A3 = np.array([[(88 - 7 * _R6) / 360, (296 - 169 * _R6) / 1800, (-2 + 3 * _R6) / 225],
               [(296 + 169 * _R6) / 1800, (88 + 7 * _R6) / 360, (-2 - 3 * _R6) / 225],
               [(16 - _R6) / 36, (16 + _R6) / 36, 1 / 9]])
C3 = np.array([(4 - _R6) / 10, (4 + _R6) / 10, 1.0])


class RadauIIA(Scheme):
    name = "radau-iia"
    description = "Radau IIA collocation, 2 stages, order 3 (stiffly accurate)"
    order = 3
    stages = 2
    velocity_points = (1, 2)  # x' is linear through the two stages
    tableau, abscissae = A, C

    def check_nodes(self, nodes: int) -> None:
        if (nodes - 1) % self.stages or nodes < self.stages + 1:
            parity = "an odd number of points, " if self.stages == 2 else ""
            raise InputError("nodes", f"{parity}{self.stages}·K + 1 (K intervals of {self.stages} stages) for "
                             f"{self.name}", nodes)

    def layout(self, mesh: np.ndarray) -> Layout:
        """The stages of every interval at τ_k + c_i·h, Z at each from the interval's base:
        Z(τ_k + c_i h) = Z_k + h·Σ_j A_ij z_{k,j}; the weights b = A's last row times h."""
        tau = np.asarray(mesh, dtype=float)
        s, A, c = self.stages, self.tableau, self.abscissae
        intervals = tau.size - 1
        nodes = s * intervals + 1
        h = np.diff(tau)
        points = s * np.arange(intervals + 1)
        t = np.empty(nodes)
        t[0] = tau[0]
        stage = points[:-1, None] + 1 + np.arange(s)[None, :]  # (K, s): the stage points of each interval
        t[stage] = tau[:-1, None] + c[None, :] * h[:, None]
        t[points[1:]] = tau[1:]  # the last stage is the mesh point itself, exactly
        rows = np.repeat(stage, s, axis=1).ravel()  # row (k, i) for every j
        cols = np.tile(stage, (1, s)).ravel()
        vals = (h[:, None, None] * A[None, :, :]).reshape(intervals, s * s).ravel()
        increments = sp.csr_matrix((vals, (rows, cols)), shape=(nodes, nodes))
        weights = np.empty(nodes)
        weights[stage] = A[-1][None, :] * h[:, None]
        weights[0] = A[-1, -1] * h[0]
        return Layout(t, weights, points, increments)


class RadauIIA5(RadauIIA):
    name = "radau-iia5"
    description = "Radau IIA collocation, 3 stages, order 5 (stiffly accurate)"
    order = 5
    stages = 3
    velocity_points = (1, 2, 3)  # x' is quadratic through the three stages
    tableau, abscissae = A3, C3
