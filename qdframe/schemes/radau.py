"""Radau IIA with two stages: stiffly accurate collocation, order 3 at the mesh points.

On each mesh interval [t_k, t_k + h] the stages sit at c = (1/3, 1); the second stage is
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

    def check_nodes(self, nodes: int) -> None:
        if nodes % 2 == 0:
            raise InputError("nodes", "an odd number of points (2K + 1: K intervals of two stages) for radau-iia", nodes)

    def layout(self, T: float, nodes: int) -> Layout:
        self.check_nodes(nodes)
        intervals = (nodes - 1) // 2
        h = T / intervals
        mesh = 2 * np.arange(intervals + 1)
        t = np.empty(nodes)
        t[mesh] = h * np.arange(intervals + 1)
        t[mesh[:-1] + 1] = t[mesh[:-1]] + C[0] * h
        t[-1] = T
        stage, end = mesh[:-1] + 1, mesh[1:]  # the two stage points of every interval
        rows = np.concatenate([stage, stage, end, end])
        cols = np.concatenate([stage, end, stage, end])
        vals = h * np.concatenate([np.full(intervals, A[0, 0]), np.full(intervals, A[0, 1]),
                                   np.full(intervals, A[1, 0]), np.full(intervals, A[1, 1])])
        increments = sp.csr_matrix((vals, (rows, cols)), shape=(nodes, nodes))
        weights = np.empty(nodes)
        weights[stage], weights[end] = B[0] * h, B[1] * h
        weights[0] = B[1] * h
        return Layout(t, weights, mesh, increments)
