"""Grid: trapezoid weights, cumulative integral and its adjoint, against dense matrices."""

from __future__ import annotations

import math

import numpy as np
import pytest

from qdframe.errors import InputError
from qdframe.schemes.grid import Grid


def dense_cumulative_matrix(nodes: int, T: float) -> np.ndarray:
    """C with (C z)_k = Σ_{m<k} h (z_m + z_{m+1}) / 2, built entry by entry."""
    h = T / (nodes - 1)
    C = np.zeros((nodes, nodes))
    for k in range(nodes):
        for m in range(k):  # interval [t_m, t_{m+1}] lies in [0, t_k]
            C[k, m] += h / 2
            C[k, m + 1] += h / 2
    return C


def trapezoid(values: np.ndarray, T: float) -> np.ndarray:
    """Plain trapezoid rule, interval by interval, along axis 0."""
    nodes = values.shape[0]
    h = T / (nodes - 1)
    total = np.zeros(values.shape[1:])
    for m in range(nodes - 1):
        total = total + h * (values[m] + values[m + 1]) / 2
    return total


SIZES = [2, 3, 4, 7, 10]


@pytest.mark.parametrize("nodes", SIZES)
@pytest.mark.parametrize("T", [1.0, 2.5])
def test_nodes_and_weights(nodes, T):
    grid = Grid(T, nodes)
    h = T / (nodes - 1)
    assert grid.step == pytest.approx(h, rel=1e-15)
    np.testing.assert_allclose(grid.t, [k * h for k in range(nodes)], rtol=0, atol=1e-14)
    assert grid.t[0] == 0.0 and grid.t[-1] == pytest.approx(T, rel=1e-15)
    expected = np.array([h / 2 if k in (0, nodes - 1) else h for k in range(nodes)])
    np.testing.assert_allclose(grid.weights, expected, rtol=1e-14)
    assert grid.weights.sum() == pytest.approx(T, rel=1e-14)


@pytest.mark.parametrize("nodes", SIZES)
@pytest.mark.parametrize("T", [1.0, 2.5])
def test_cumulative_matches_dense_matrix(nodes, T):
    rng = np.random.default_rng(nodes)
    grid = Grid(T, nodes)
    C = dense_cumulative_matrix(nodes, T)
    z1 = rng.standard_normal(nodes)
    np.testing.assert_allclose(grid.cumulative(z1), C @ z1, rtol=1e-13, atol=1e-14)
    z2 = rng.standard_normal((nodes, 3))
    Z2 = grid.cumulative(z2)
    assert Z2.shape == z2.shape
    np.testing.assert_allclose(Z2, C @ z2, rtol=1e-13, atol=1e-14)
    assert np.all(Z2[0] == 0.0)
    # the last row is the full integral
    np.testing.assert_allclose(Z2[-1], trapezoid(z2, T), rtol=1e-13, atol=1e-14)


def test_cumulative_is_exact_for_linear_functions():
    grid = Grid(2.0, 9)
    t = grid.t
    z = np.stack([np.ones_like(t), 3.0 * t - 1.0], axis=1)
    expected = np.stack([t, 1.5 * t**2 - t], axis=1)
    np.testing.assert_allclose(grid.cumulative(z), expected, rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("nodes", SIZES)
@pytest.mark.parametrize("T", [1.0, 0.3])
def test_cumulative_adjoint_is_transpose(nodes, T):
    rng = np.random.default_rng(100 + nodes)
    grid = Grid(T, nodes)
    C = dense_cumulative_matrix(nodes, T)
    y1 = rng.standard_normal(nodes)
    np.testing.assert_allclose(grid.cumulative_adjoint(y1), C.T @ y1, rtol=1e-13, atol=1e-14)
    y2 = rng.standard_normal((nodes, 4))
    out = grid.cumulative_adjoint(y2)
    assert out.shape == y2.shape
    np.testing.assert_allclose(out, C.T @ y2, rtol=1e-13, atol=1e-14)
    # adjoint identity <C z, y> = <z, Cᵀ y>
    z2 = rng.standard_normal((nodes, 4))
    assert np.sum(grid.cumulative(z2) * y2) == pytest.approx(np.sum(z2 * out), rel=1e-12, abs=1e-14)


@pytest.mark.parametrize("nodes", SIZES)
def test_cumulative_adjoint_basis_vectors(nodes):
    """Cᵀ e_k column by column equals row k of C."""
    grid = Grid(1.7, nodes)
    C = dense_cumulative_matrix(nodes, 1.7)
    for k in range(nodes):
        e = np.zeros(nodes)
        e[k] = 1.0
        np.testing.assert_allclose(grid.cumulative_adjoint(e), C[k], rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("nodes", SIZES)
def test_integral_is_trapezoid_rule(nodes):
    rng = np.random.default_rng(200 + nodes)
    T = 1.3
    grid = Grid(T, nodes)
    v1 = rng.standard_normal(nodes)
    assert grid.integral(v1) == pytest.approx(float(trapezoid(v1, T)), rel=1e-13, abs=1e-14)
    v3 = rng.standard_normal((nodes, 2, 3))
    out = grid.integral(v3)
    assert out.shape == (2, 3)
    np.testing.assert_allclose(out, trapezoid(v3, T), rtol=1e-13, atol=1e-14)
    # exact for affine integrands: ∫_0^T (2 − 3t) dt
    assert grid.integral(2.0 - 3.0 * grid.t) == pytest.approx(2 * T - 1.5 * T**2, rel=1e-13)
    assert grid.integral(np.ones(nodes)) == pytest.approx(T, rel=1e-14)


@pytest.mark.parametrize("nodes", [1, 0, -3, 2.5, 2.0, True, False, "5", None])
def test_bad_nodes_raise_input_error(nodes):
    with pytest.raises(InputError) as info:
        Grid(1.0, nodes)
    assert info.value.field == "nodes"
    assert str(info.value).startswith("nodes:")


@pytest.mark.parametrize("T", [0, 0.0, -1, -1.0, math.nan, math.inf, -math.inf])
def test_bad_T_raises_input_error(T):
    with pytest.raises(InputError) as info:
        Grid(T, 5)
    assert info.value.field == "T"
    assert str(info.value).startswith("T:")


def test_input_error_is_a_value_error():
    with pytest.raises(ValueError):
        Grid(1.0, 1)


def test_cumulative_of_integer_array_is_not_truncated():
    grid = Grid(1.0, 3)
    C = dense_cumulative_matrix(3, 1.0)
    z = np.array([1, 2, 3])
    np.testing.assert_allclose(grid.cumulative(z), C @ z.astype(float), rtol=1e-14)
