"""The uniform time grid: trapezoid weights and the cumulative integral ∫_0^t z."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InputError


@dataclass(frozen=True)
class Grid:
    """N uniform nodes on [0, T] with trapezoid weights w_k (Σ w_k = T)."""

    T: float
    nodes: int
    t: np.ndarray = field(init=False, repr=False)
    weights: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if isinstance(self.nodes, bool) or not isinstance(self.nodes, (int, np.integer)) or self.nodes < 2:
            raise InputError("nodes", "an integer ≥ 2", self.nodes)
        if isinstance(self.T, bool) or not isinstance(self.T, (int, float, np.integer, np.floating)) or not (
            np.isfinite(self.T) and self.T > 0
        ):
            raise InputError("T", "a positive finite number", self.T)
        t = np.linspace(0.0, self.T, self.nodes)
        w = np.full(self.nodes, self.step)
        w[[0, -1]] = self.step / 2
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "weights", w)

    @property
    def step(self) -> float:
        return self.T / (self.nodes - 1)

    def integral(self, values: np.ndarray) -> np.ndarray:
        """∫_0^T by the trapezoid rule along axis 0."""
        return np.tensordot(self.weights, values, axes=(0, 0))

    def cumulative(self, z: np.ndarray) -> np.ndarray:
        """Z_k = ∫_0^{t_k} z by the cumulative trapezoid rule (Z_0 = 0), shape of z."""
        z = np.asarray(z, dtype=float)
        out = np.zeros_like(z)
        np.cumsum(0.5 * self.step * (z[1:] + z[:-1]), axis=0, out=out[1:])
        return out

    def cumulative_adjoint(self, y: np.ndarray) -> np.ndarray:
        """Cᵀy for the matrix C of :meth:`cumulative` (Z = C z), without forming C."""
        h = self.step
        y = np.asarray(y, dtype=float)
        tail = np.zeros_like(y)  # tail_m = Σ_{k>m} y_k
        tail[:-1] = np.cumsum(y[::-1], axis=0)[::-1][1:]
        out = 0.5 * h * y + h * tail
        out[0] = 0.5 * h * tail[0]
        return out
