"""Radau IIA with two stages: stiffly accurate collocation, order 3 at the mesh points.

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


class RadauIIA(Scheme):
    name = "radau-iia"
    description = "Radau IIA collocation, 2 stages, order 3 (stiffly accurate)"
    order = 3
    stages = 2
    velocity_points = (1, 2)  # x' is linear through the two stages

    def check_nodes(self, nodes: int) -> None:
        if nodes % 2 == 0:
            raise InputError("nodes", "an odd number of points (2K + 1: K intervals of two stages) for radau-iia", nodes)

    def layout(self, mesh: np.ndarray) -> Layout:
        tau = np.asarray(mesh, dtype=float)
        intervals = tau.size - 1
        nodes = 2 * intervals + 1
        h = np.diff(tau)
        points = 2 * np.arange(intervals + 1)
        t = np.empty(nodes)
        t[points] = tau
        t[points[:-1] + 1] = tau[:-1] + C[0] * h
        stage, end = points[:-1] + 1, points[1:]  # the two stage points of every interval
        rows = np.concatenate([stage, stage, end, end])
        cols = np.concatenate([stage, end, stage, end])
        vals = np.concatenate([A[0, 0] * h, A[0, 1] * h, A[1, 0] * h, A[1, 1] * h])
        increments = sp.csr_matrix((vals, (rows, cols)), shape=(nodes, nodes))
        weights = np.empty(nodes)
        weights[stage], weights[end] = B[0] * h, B[1] * h
        weights[0] = B[1] * h[0]
        return Layout(t, weights, points, increments)
