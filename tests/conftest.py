"""Shared checks for the tests."""

from __future__ import annotations

import numpy as np
import pytest

RESIDUAL_TOL = 1e-8  # solve's default residual_tol


def check_certified(result, residual_tol: float = RESIDUAL_TOL) -> None:
    """What `solved` certifies pointwise (README, "How a run ends"), read from the result's
    own residuals rather than from its `checks`: the boundary, consistency and surface errors
    within residual_tol · max(1, max|x|), the inclusion within residual_tol · max(1, max|z|),
    the selections within residual_tol and inside [−1, 1]. The discrete problem is solved:
    the status is `solved`, or `uncertified` where its error estimate does not meet the
    target (a fixed grid is not meant to meet 1e-6)."""
    assert result.converged, result.message
    scale_x = max(1.0, float(np.max(np.abs(result.x))))
    scale_z = max(1.0, float(np.max(np.abs(result.z))))
    assert result.boundary_error <= residual_tol * scale_x
    assert result.consistency_error <= residual_tol * scale_x
    assert result.inclusion_residual <= residual_tol * scale_z
    if result.surface_error is not None:
        assert result.surface_error <= residual_tol * scale_x
    if result.selections is not None:
        assert result.selection_residual <= residual_tol
        assert np.all(np.abs(result.selections) <= 1.0 + residual_tol)


@pytest.fixture
def certified():
    """:func:`check_certified`, for tests in any folder."""
    return check_certified
