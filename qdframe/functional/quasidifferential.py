"""Batched convex polytopes: the per-node sub- and superdifferentials (A_k, B_k).

Every set the method builds (paper (4.5), (4.555), (4.44)-(4.55)) is a point plus a
Minkowski sum of convex hulls of a few vectors, so one type serves both:

    P_k = center_k + Σ_g co{ generators[k, g, p] : mask[k, g, p] }.

Arrays are (nodes, ...) throughout; d is the per-node dimension of the unknowns.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SimplexSum:
    """A batch of polytopes center + Σ_g co{generators[:, g, mask]}.

    center: (N, d); generators: (N, G, m, d); mask: (N, G, m) bool. A group whose
    mask is all False contributes nothing (it is stored as the single vector 0).
    """

    center: np.ndarray
    generators: np.ndarray
    mask: np.ndarray

    def __post_init__(self) -> None:
        n, d = self.center.shape
        if self.generators.ndim != 4 or self.generators.shape[0] != n or self.generators.shape[3] != d:
            raise ValueError(f"generators: expected shape ({n}, G, m, {d}), got {self.generators.shape}")
        if self.mask.shape != self.generators.shape[:3]:
            raise ValueError(f"mask: expected shape {self.generators.shape[:3]}, got {self.mask.shape}")
        empty = ~self.mask.any(axis=2)
        if empty.any():  # an empty group is the single vector 0
            generators = self.generators.copy()
            mask = self.mask.copy()
            generators[empty] = 0.0
            mask[empty, 0] = True
            object.__setattr__(self, "generators", generators)
            object.__setattr__(self, "mask", mask)

    @classmethod
    def point(cls, center: np.ndarray) -> "SimplexSum":
        """Singletons {center_k}."""
        n, d = center.shape
        return cls(center, np.zeros((n, 0, 1, d)), np.zeros((n, 0, 1), dtype=bool))

    @property
    def nodes(self) -> int:
        return self.center.shape[0]

    @property
    def dim(self) -> int:
        return self.center.shape[1]

    def support(self, direction: np.ndarray) -> np.ndarray:
        """max_{v ∈ P_k} <v, direction_k> for every node: (N,)."""
        values = np.einsum("kgpd,kd->kgp", self.generators, direction)
        values = np.where(self.mask, values, -np.inf)
        group_max = values.max(axis=2) if values.shape[1] else np.zeros((self.nodes, 0))
        return np.einsum("kd,kd->k", self.center, direction) + group_max.sum(axis=1)

    def lower_support(self, direction: np.ndarray) -> np.ndarray:
        """min_{v ∈ P_k} <v, direction_k> for every node: (N,)."""
        return -self.support(-direction)

    def vertices(self) -> tuple[np.ndarray, np.ndarray]:
        """Candidate vertices of every P_k: (N, V, d) and a validity mask (N, V).

        The candidates are all sums center + Σ_g generators[g, p_g] over one active
        generator per group; they include every vertex of P_k (and maybe more points
        of P_k, which is harmless for a maximum of a convex function).
        """
        n, groups, width, d = self.generators.shape
        if groups == 0:
            return self.center[:, None, :], np.ones((n, 1), dtype=bool)
        live = [g for g in range(groups) if self.mask[:, g, 1:].any()] if width > 1 else []
        base = self.center + sum(
            (self.generators[:, g, 0, :] for g in range(groups) if g not in live), np.zeros((n, d))
        )
        if not live:
            return base[:, None, :], np.ones((n, 1), dtype=bool)
        choices = list(itertools.product(range(width), repeat=len(live)))
        picks = np.array(choices)  # (V, len(live))
        live_generators = self.generators[:, live]  # (N, L, m, d)
        live_mask = self.mask[:, live]  # (N, L, m)
        rows = np.arange(len(live))
        points = base[:, None, :] + live_generators[:, rows, picks, :].sum(axis=2)  # (N, V, d)
        valid = live_mask[:, rows, picks].all(axis=2)  # (N, V)
        return points, valid

    def compact(self) -> "SimplexSum":
        """The same polytopes, smaller: one-generator groups folded into the center,
        active generators first in each group, widths trimmed to the largest count."""
        n, groups, width, d = self.generators.shape
        if groups == 0:
            return self
        counts = self.mask.sum(axis=2)
        single = (counts <= 1).all(axis=0)
        # a one-generator group's point is its first active generator (its first, where none is):
        # gathered alone, without reordering the whole (N, G, m, d) array
        first = np.argmax(self.mask[:, single], axis=2).ravel()  # (N·S,)
        rows = (np.arange(n)[:, None] * groups + np.flatnonzero(single)[None, :]).ravel()
        picked = self.generators.reshape(n * groups, width, d)[rows, first]  # (N·S, d)
        center = self.center + picked.reshape(n, -1, d).sum(axis=1)
        keep = ~single
        if not keep.any():
            return SimplexSum(center, self.generators[:, :0, :1], self.mask[:, :0, :1])
        order = np.argsort(~self.mask[:, keep], axis=2, kind="stable")
        mask = np.take_along_axis(self.mask[:, keep], order, axis=2)
        generators = np.take_along_axis(self.generators[:, keep], order[..., None], axis=2)
        new_width = int(counts[:, keep].max())
        return SimplexSum(center, generators[:, :, :new_width], mask[:, :, :new_width])

    def scaled(self, factor: float | np.ndarray) -> "SimplexSum":
        """factor_k · P_k for a scalar or per-node factor ≥ 0."""
        f = np.asarray(factor, dtype=float)
        fc = f if f.ndim == 0 else f[:, None]
        fg = f if f.ndim == 0 else f[:, None, None, None]
        return SimplexSum(self.center * fc, self.generators * fg, self.mask)

    def __add__(self, other: "SimplexSum") -> "SimplexSum":
        """Minkowski sum (groups are concatenated; widths padded with masked zeros)."""
        width = max(self.generators.shape[2], other.generators.shape[2])
        return SimplexSum(
            self.center + other.center,
            np.concatenate([_pad(self.generators, width), _pad(other.generators, width)], axis=1),
            np.concatenate([_pad(self.mask, width), _pad(other.mask, width)], axis=1),
        )


def _pad(array: np.ndarray, width: int) -> np.ndarray:
    extra = width - array.shape[2]
    if extra == 0:
        return array
    pad = [(0, 0)] * array.ndim
    pad[2] = (0, extra)
    return np.pad(array, pad)


@dataclass(frozen=True)
class Quasidifferential:
    """Per-node quasidifferential [A_k, B_k] in the L² metric (paper (11.10), (11.400))."""

    sub: SimplexSum  # A_k, the subdifferential
    sup: SimplexSum  # B_k, the superdifferential

    def directional_derivative(self, direction: np.ndarray, weights: np.ndarray) -> float:
        """(11.10): Σ_k w_k (max_{v∈A_k} <v, g_k> + min_{w∈B_k} <w, g_k>)."""
        per_node = self.sub.support(direction) + self.sup.lower_support(direction)
        return float(weights @ per_node)
