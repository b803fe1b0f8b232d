"""The Scheme interface: how a solve discretizes x' = z on [0, T].

A scheme places the time points t_p, the quadrature weights w_p of the integral terms
(φ, ω, υ and the selections' term, paper (3.13)–(3.17)) and the local integration rule

    Z_p = Z_{base(p)} + Σ_j A_pj z_j,   Z_0 = 0,

where base(p) is the last *mesh* point before p and Z_p approximates ∫_0^{t_p} z.
x_p − x0 − Z_p is then the consistency residual of υ. The trapezoid rule (the paper's),
implicit Euler and Radau IIA are such rules; :class:`~qdframe.grid.Grid` turns any of
them into the cumulative integral, its adjoint and the sparse recursion used by
gauss-newton. A third scheme is one small class registered under the entry-point
group ``qdframe.schemes``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import scipy.sparse as sp


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

    @abstractmethod
    def layout(self, T: float, nodes: int) -> Layout:
        """The layout with `nodes` points in all (the number of unknown x, z rows)."""

    def check_nodes(self, nodes: int) -> None:
        """Raise InputError when `nodes` does not fit the scheme (default: any ≥ 2)."""


def uniform_layout(T: float, nodes: int, lower: float, diagonal: float, ends: tuple[float, float]) -> Layout:
    """A one-step rule on a uniform mesh, Z_k = Z_{k−1} + h·(lower·z_{k−1} + diagonal·z_k),
    with weights h at the interior points and h·ends at t_0 and t_N."""
    t = np.linspace(0.0, T, nodes)
    h = T / (nodes - 1)
    k = np.arange(1, nodes)
    rows = np.concatenate([k, k])
    cols = np.concatenate([k, k - 1])
    vals = np.concatenate([np.full(k.size, h * diagonal), np.full(k.size, h * lower)])
    keep = vals != 0
    increments = sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(nodes, nodes))
    weights = np.full(nodes, h)
    weights[[0, -1]] = h * np.asarray(ends)
    return Layout(t, weights, np.arange(nodes), increments)
