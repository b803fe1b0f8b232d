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

from ..errors import InputError
from . import Scheme


def make_scheme(scheme: "str | Scheme") -> Scheme:
    """A scheme by registered name, or the instance itself."""
    if isinstance(scheme, Scheme):
        return scheme
    from ..registry import lookup

    return lookup("schemes", str(scheme)).obj()


def check_mesh(tau: np.ndarray, T: float) -> None:
    """InputError naming the first mesh time that is not finite, not increasing, or not 0
    first and `T` last (a flat array `tau` of at least two times; the field is ``mesh[i]``)."""
    horizon = f"mesh times increase from 0 to T = {T:g}"
    bad = np.flatnonzero(~np.isfinite(tau))
    if bad.size:
        raise InputError(f"mesh[{bad[0]}]", "a finite mesh time (not NaN or inf)", float(tau[bad[0]]))
    if tau[0] != 0.0:
        raise InputError("mesh[0]", f"0 ({horizon})", float(tau[0]))
    if tau[-1] != T:
        raise InputError(f"mesh[{tau.size - 1}]", f"T = {T:g}, the last time ({horizon})", float(tau[-1]))
    back = np.flatnonzero(np.diff(tau) <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise InputError(f"mesh[{i}]", f"a time > mesh[{i - 1}] = {tau[i - 1]:g} ({horizon})", float(tau[i]))


@dataclass(frozen=True)
class Grid:
    """`nodes` points on [0, T] laid out by `scheme` (default: the trapezoid rule), on a
    uniform mesh or on the given mesh times `mesh_times` (see :meth:`from_mesh`).

    `switches` are the switch times the mesh was laid out for (:mod:`qdframe.solve.adaptive` pins a
    mesh point on each); `left_limits` (indices) are the mesh points among them where the
    scheme's rule integrates z over the interval before only (Radau IIA, implicit Euler; not
    the trapezoid rule, whose z at a mesh point serves both intervals): there a Filippov
    selection is the interval's own, λ_k = λ_{k−1} (:meth:`Functional.left_limits`)."""

    T: float
    nodes: int
    scheme: "str | Scheme" = "trapezoid"
    mesh_times: np.ndarray | None = field(default=None, compare=False, repr=False)
    switches: tuple[float, ...] = field(default=(), compare=False, repr=False)
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
        intervals = (int(self.nodes) - 1) // scheme.stages
        if self.mesh_times is None:
            tau = np.linspace(0.0, float(self.T), intervals + 1)
        else:
            tau = np.asarray(self.mesh_times, dtype=float)
            if tau.ndim != 1 or tau.size != intervals + 1:
                raise InputError("mesh", f"{intervals + 1} mesh times for {self.nodes} points of {scheme.name}",
                                 f"shape {tau.shape}")
            check_mesh(tau, float(self.T))
        object.__setattr__(self, "mesh_times", tau)
        layout = scheme.layout(tau)
        object.__setattr__(self, "scheme", scheme)
        for name in ("t", "weights", "mesh", "increments"):
            object.__setattr__(self, name, getattr(layout, name))
        # the mesh position of every point's anchor: the point itself on the mesh, else its base
        anchor = np.searchsorted(self.mesh, np.arange(self.nodes), side="right") - 1
        object.__setattr__(self, "_anchor", anchor)
        off_mesh = np.ones(self.nodes, dtype=bool)  # the points that are not mesh points (a mask: no sort)
        off_mesh[self.mesh] = False
        object.__setattr__(self, "_off_mesh", np.flatnonzero(off_mesh))
        # the mesh points on a switch time whose z belongs to the interval before them alone
        # (the rule does not integrate an interval's first z): their selections are the left
        # limits, the point before's (Functional.left_limits)
        on_switch = np.isin(tau[1:-1], np.asarray(self.switches, dtype=float))
        left = self.mesh[1:-1][on_switch] if 0 not in scheme.velocity_points else np.zeros(0, dtype=int)
        object.__setattr__(self, "left_limits", left)
        last = np.zeros(self.nodes)
        last[-1] = 1.0
        object.__setattr__(self, "integral_weights", self.cumulative_adjoint(last))

    @classmethod
    def from_mesh(cls, mesh: np.ndarray, scheme: "str | Scheme" = "trapezoid",
                  switches: "tuple[float, ...] | np.ndarray" = ()) -> "Grid":
        """The grid of `scheme` on the mesh times `mesh` (increasing, from 0 to T); `switches`:
        switch times, those on a mesh point make it a left-limit point (:attr:`left_limits`)."""
        tau = np.asarray(mesh, dtype=float)
        if tau.ndim != 1 or tau.size < 2:
            raise InputError("mesh", "at least two increasing mesh times from 0 to T", f"shape {tau.shape}")
        stages = make_scheme(scheme).stages
        try:
            times = np.asarray(switches, dtype=float).ravel()
        except (TypeError, ValueError):
            times = np.array([np.nan])
        if not np.all(np.isfinite(times)):
            raise InputError("switches", "finite switch times (numbers)", switches)
        return cls(float(tau[-1]), stages * (tau.size - 1) + 1, scheme, tau, tuple(times.tolist()))

    @property
    def step(self) -> float:
        """The largest mesh step h."""
        return float(np.max(np.diff(self.mesh_times)))

    @property
    def uniform(self) -> bool:
        """Whether the mesh steps are equal (to rounding)."""
        h = np.diff(self.mesh_times)
        return bool(np.ptp(h) <= 1e-12 * self.T)

    def bisected(self) -> "Grid":
        """The same scheme on the mesh with every interval halved (its points include this
        grid's mesh points): the companion solve of the error estimate."""
        tau = self.mesh_times
        finer = np.empty(2 * tau.size - 1)
        finer[::2], finer[1::2] = tau, 0.5 * (tau[:-1] + tau[1:])
        finer[-1] = tau[-1]
        return Grid.from_mesh(finer, self.scheme, self.switches)

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
