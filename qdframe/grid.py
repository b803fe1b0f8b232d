"""The time grid of a solve: a scheme's points, weights and cumulative integral ∫_0^t z.

A :class:`~qdframe.schemes.Scheme` gives the points t_p, the quadrature weights w_p and
the local rule Z_p = Z_{base(p)} + Σ_j A_pj z_j (base(p): the last mesh point before p).
The grid turns that into the cumulative integral Z = C z, its adjoint Cᵀy (the L²
gradient of υ and χ, paper (4.44), (4.55)) and the sparse recursion gauss-newton keeps
as constraints, all vectorized over the points.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .errors import InputError
from .schemes import Scheme


def make_scheme(scheme: "str | Scheme") -> Scheme:
    """A scheme by registered name, or the instance itself."""
    if isinstance(scheme, Scheme):
        return scheme
    from .registry import lookup

    return lookup("schemes", str(scheme)).obj()


@dataclass(frozen=True)
class Grid:
    """`nodes` points on [0, T] laid out by `scheme` (default: the trapezoid rule)."""

    T: float
    nodes: int
    scheme: "str | Scheme" = "trapezoid"
    t: np.ndarray = field(init=False, repr=False)
    weights: np.ndarray = field(init=False, repr=False)
    mesh: np.ndarray = field(init=False, repr=False)
    increments: sp.csr_matrix = field(init=False, repr=False)
    integral_weights: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if isinstance(self.nodes, bool) or not isinstance(self.nodes, (int, np.integer)) or self.nodes < 2:
            raise InputError("nodes", "an integer ≥ 2", self.nodes)
        if isinstance(self.T, bool) or not isinstance(self.T, (int, float, np.integer, np.floating)) or not (
            np.isfinite(self.T) and self.T > 0
        ):
            raise InputError("T", "a positive finite number", self.T)
        scheme = make_scheme(self.scheme)
        scheme.check_nodes(int(self.nodes))
        layout = scheme.layout(float(self.T), int(self.nodes))
        object.__setattr__(self, "scheme", scheme)
        for name in ("t", "weights", "mesh", "increments"):
            object.__setattr__(self, name, getattr(layout, name))
        # the mesh position of every point's anchor: the point itself on the mesh, else its base
        anchor = np.searchsorted(self.mesh, np.arange(self.nodes), side="right") - 1
        object.__setattr__(self, "_anchor", anchor)
        object.__setattr__(self, "_off_mesh", np.setdiff1d(np.arange(self.nodes), self.mesh))
        last = np.zeros(self.nodes)
        last[-1] = 1.0
        object.__setattr__(self, "integral_weights", self.cumulative_adjoint(last))

    @property
    def step(self) -> float:
        """The largest mesh step h."""
        return float(np.max(np.diff(self.t[self.mesh])))

    @property
    def base(self) -> np.ndarray:
        """base(p) for p ≥ 1: the last mesh point before p."""
        return self.mesh[np.searchsorted(self.mesh, np.arange(1, self.nodes), side="left") - 1]

    def integral(self, values: np.ndarray) -> np.ndarray:
        """∫_0^T by the scheme's rule along axis 0 (= the cumulative integral at T)."""
        return np.tensordot(self.integral_weights, values, axes=(0, 0))

    def cumulative(self, z: np.ndarray) -> np.ndarray:
        """Z_p = ∫_0^{t_p} z by the scheme's rule (Z_0 = 0), shape of z."""
        z = np.asarray(z, dtype=float)
        increments = self.increments @ z.reshape(self.nodes, -1)
        on_mesh = np.cumsum(increments[self.mesh], axis=0)  # increments[0] = 0
        out = on_mesh[self._anchor]
        out[self._off_mesh] += increments[self._off_mesh]
        return out.reshape(z.shape)

    def cumulative_adjoint(self, y: np.ndarray) -> np.ndarray:
        """Cᵀy for the matrix C of :meth:`cumulative` (Z = C z), without forming C."""
        y = np.asarray(y, dtype=float)
        flat = y.reshape(self.nodes, -1)
        gathered = np.zeros((self.mesh.size, flat.shape[1]))
        np.add.at(gathered, self._anchor, flat)
        weights = np.empty_like(flat)
        weights[self.mesh] = np.cumsum(gathered[::-1], axis=0)[::-1]
        weights[self._off_mesh] = flat[self._off_mesh]
        return (self.increments.T @ weights).reshape(y.shape)

    def recursion(self) -> tuple[np.ndarray, np.ndarray, sp.csr_matrix]:
        """The rule as constraints for p ≥ 1: Z_p − Z_{base(p)} − (A z)_p = 0, returned as
        (p, base(p), A restricted to rows p ≥ 1)."""
        points = np.arange(1, self.nodes)
        return points, self.base, self.increments[1:]
