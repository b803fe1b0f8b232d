"""The Scheme interface: how a solve discretizes x' = z on a mesh 0 = τ_0 < … < τ_K = T.

A scheme places the time points t_p (the mesh points and `stages − 1` stage points inside
each mesh interval), the quadrature weights w_p of the integral terms (φ, ω, υ and the
selections' term, paper (3.13)–(3.17)) and the local integration rule

    Z_p = Z_{base(p)} + Σ_j A_pj z_j,   Z_0 = 0,

where base(p) is the last *mesh* point before p and Z_p approximates ∫_0^{t_p} z.
x_p − x0 − Z_p is then the consistency residual of υ. The trapezoid rule (the paper's),
implicit Euler and Radau IIA are such rules; :class:`~qdframe.schemes.grid.Grid` turns any of
them into the cumulative integral, its adjoint and the sparse recursion used by
gauss-newton. The mesh need not be uniform: adaptive solves (`accuracy=`) refine it
where the error estimate is large and place mesh points on switch times. A new scheme
is one small class registered under the entry-point group ``qdframe.schemes``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sp

from ..errors import InputError


@dataclass(frozen=True)
class Layout:
    """A scheme's points on [0, T].

    t (M,) the points, weights (M,) positive quadrature weights (also the L² metric of the
    directions), mesh (indices of the mesh points, the first 0 and the last M − 1),
    increments (M, M) sparse: row p holds A_p· (row 0 is empty).
    """

    t: np.ndarray
    weights: np.ndarray
    mesh: np.ndarray
    increments: sp.csr_matrix


class Scheme(ABC):
    """A discretization of x' = z: points, weights and the integration rule."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    order: ClassVar[int] = 1  # classical order at the mesh points for smooth solutions
    stages: ClassVar[int] = 1  # points per mesh interval: `nodes` = stages·K + 1 for K intervals
    # the points of a mesh interval whose z the rule integrates there (0: the interval's first
    # mesh point, `stages`: its last): x' on the interval is the polynomial through them
    velocity_points: ClassVar[tuple[int, ...]] = (0, 1)

    @abstractmethod
    def layout(self, mesh: np.ndarray) -> Layout:
        """The layout on the mesh times `mesh` (K + 1 increasing values from 0 to T), with
        stages·K + 1 points in all (the number of unknown x, z rows)."""

    def velocity(self, t: np.ndarray, mesh: np.ndarray, values: np.ndarray, times: np.ndarray) -> np.ndarray:
        """The rule's own x'(t) at `times` from `values` (z, or anything sampled like it) at the
        points t (mesh: the indices of the mesh points): on each mesh interval the polynomial
        through the values at its `velocity_points` — constant for implicit Euler, linear for
        the trapezoid rule and for Radau IIA (through its two stages)."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        interval = np.clip(np.searchsorted(t[mesh], times, side="right") - 1, 0, mesh.size - 2)
        points = mesh[interval][:, None] + np.asarray(self.velocity_points)[None, :]  # (K, q)
        out = np.zeros((times.size,) + values.shape[1:])
        for i in range(points.shape[1]):  # Lagrange basis through the q points
            basis = np.ones(times.size)
            for j in range(points.shape[1]):
                if j != i:
                    basis *= (times - t[points[:, j]]) / (t[points[:, i]] - t[points[:, j]])
            out += basis.reshape((-1,) + (1,) * (values.ndim - 1)) * values[points[:, i]]
        return out

    def check_nodes(self, nodes: int) -> None:
        """Raise InputError when `nodes` does not fit the scheme (stages·K + 1, K ≥ 1)."""
        if (nodes - 1) % self.stages:
            raise InputError("nodes", f"{self.stages}·K + 1 points (K intervals of {self.stages} points) "
                             f"for {self.name}", nodes)


def one_step_layout(mesh: np.ndarray, lower: float, diagonal: float, ends: tuple[float, float]) -> Layout:
    """A one-step rule on the mesh τ, Z_k = Z_{k−1} + h_k·(lower·z_{k−1} + diagonal·z_k),
    h_k = τ_k − τ_{k−1}, with weights w_k = diagonal·h_k + lower·h_{k+1} at the interior
    points (the rule's own quadrature) and ends[0]·h_1, ends[1]·h_K at τ_0 and τ_K."""
    t = np.asarray(mesh, dtype=float)
    nodes = t.size
    h = np.diff(t)
    k = np.arange(1, nodes)
    rows = np.concatenate([k, k])
    cols = np.concatenate([k, k - 1])
    vals = np.concatenate([h * diagonal, h * lower])
    keep = vals != 0
    increments = sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(nodes, nodes))
    weights = np.empty(nodes)
    weights[1:-1] = diagonal * h[:-1] + lower * h[1:]
    weights[0], weights[-1] = ends[0] * h[0], ends[1] * h[-1]
    return Layout(t, weights, np.arange(nodes), increments)


def uniform_layout(T: float, nodes: int, lower: float, diagonal: float, ends: tuple[float, float]) -> Layout:
    """:func:`one_step_layout` on the uniform mesh of `nodes` points on [0, T]."""
    return one_step_layout(np.linspace(0.0, T, nodes), lower, diagonal, ends)
