"""Pieces with their gradients, for models written by hand (:mod:`qdframe.model`).

A hand-written piece maps y = (x, u), an array (N, n + m), to its values and gradients
for all nodes at once. The common ones, ready made:

- :func:`affine`: y ↦ c + Σ a_i·y_i, values (N,) and gradients (N, n + m), the
  right-hand side of :meth:`~qdframe.model.SetBlock.equation` or a sign term's switch s(y);
  :func:`constant` and :func:`coordinate` are its special cases;
- :func:`ball_switch`: the switch s(y) = W·y_J ∈ R^k of a vector sign (isotropic friction,
  :class:`~qdframe.model.BallSwitch`);
- :func:`abs_sum`: the amplitude groups of scale·Σ|y_i| for a
  :class:`~qdframe.model.SignTerm` (each |y_i| = max{y_i, −y_i}, paper Section 5);
- :func:`repeated`: a constant row at every node (a constant gradient or piece value).

Each carries the optional `formulas` hook (its values as formulas of y's symbols), with
which :func:`qdframe.certificates.model_system.model_system` evaluates a whole model at one point in
one compiled call. Models written with :mod:`qdframe.sets` need none of these: SymPy
derives their gradients.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from .model import BallSwitch

Affine = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def repeated(row: np.ndarray, count: int) -> np.ndarray:
    """`row` repeated `count` times along a new first axis, as a new array: the constant
    gradient of a piece at every node. Filled in place: at one point (the event integrator's
    calls, ~1e5 in a replay) 4 µs against 7 µs for np.broadcast_to(…).copy(); the same at 1e5."""
    out = np.empty((count,) + np.shape(row))
    out[...] = row
    return out


def affine(coefficients: Mapping[int, float], width: int, constant: float = 0.0) -> Affine:
    """y ↦ constant + Σ c_i·y_i with its gradient: values (N,), gradients (N, width)."""
    gradient = np.zeros(width)
    for index, value in coefficients.items():
        gradient[index] = value

    def rhs(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return constant + y @ gradient, repeated(gradient, y.shape[0])

    rhs.formulas = lambda symbols: [constant + sum(value * symbols[i] for i, value in coefficients.items())]
    return rhs


def constant(value: float, width: int) -> Affine:
    """y ↦ value (gradient 0)."""
    return affine({}, width, value)


def coordinate(index: int, width: int) -> Affine:
    """y ↦ y_index."""
    return affine({index: 1.0}, width)


def abs_sum(indices: Sequence[int], scale: float, width: int) -> tuple[Callable, ...]:
    """Amplitude groups for scale·Σ_{i ∈ indices} |y_i| (each |y_i| = max{y_i, −y_i});
    `width` is the number of columns of y (n + m)."""

    def group(i: int) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]:
        def pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            grads = np.zeros((y.shape[0], 2, width))
            grads[:, 0, i], grads[:, 1, i] = scale, -scale
            values = np.empty((y.shape[0], 2))  # filled in place (np.stack costs ~10 µs a call at one point)
            np.multiply(y[:, i], scale, out=values[:, 0])
            np.negative(values[:, 0], out=values[:, 1])  # −(scale·y) = (−scale)·y exactly
            return values, grads

        pieces.formulas = lambda symbols: [scale * symbols[i], -scale * symbols[i]]
        return pieces

    return tuple(group(i) for i in indices)


def ball_switch(indices: Sequence[int], width: int, matrix: Sequence[Sequence[float]] | None = None,
                name: str = "Sgn") -> BallSwitch:
    """The :class:`~qdframe.model.BallSwitch` s(y) = W·(y_i for i in indices), W the k×k
    identity unless `matrix` (k' rows) is given: Sgn(y_i, y_j) of isotropic friction on the
    velocities y_i, y_j, or Sgn(W·v) of a weighted norm |W·v| (elliptic friction)."""
    indices = list(indices)
    weights = np.eye(len(indices)) if matrix is None else np.asarray(matrix, dtype=float)
    if weights.ndim != 2 or weights.shape[1] != len(indices) or weights.shape[0] < 2:
        raise ValueError(f"ball_switch: matrix of shape (k, {len(indices)}) with k ≥ 2 expected, got {weights.shape}")
    gradient = np.zeros((weights.shape[0], width))
    gradient[:, indices] = weights

    def switch(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return y @ gradient.T, repeated(gradient, y.shape[0])

    switch.formulas = lambda symbols: [sum(w * symbols[i] for w, i in zip(row, indices)) for row in weights]
    return BallSwitch(switch, weights.shape[0], name)
