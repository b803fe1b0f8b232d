"""What `solved` certifies: pointwise checks of the trajectory the user gets.

A small I is necessary but not enough: I weighs node k by w_k, so I ≤ tol allows a
residual √(2·tol/w_k) there. `solved` therefore also requires every check below, each a
max over the nodes against an absolute tolerance scaled to the problem's states:

========================  ==========================================  =====================
check                     value                                       tolerance
========================  ==========================================  =====================
boundary                  max |x_j(T) − xT_j|, |x_i(T) − x_i(0)| (P)  residual_tol·scale_x
inclusion                 max_k dist(z_k, F(x_k, u_k)) (φ's h_b)      residual_tol·scale_z
selection                 max |λ − clip(λ + s, −1, 1)| (λ ∈ Sgn(s))   residual_tol
consistency               max_k |x_k − x(t_0) − ∫_0^{t_k} z|          residual_tol·scale_x
surface                   max_k |e(x_k)|                              residual_tol·scale_x
bounds                    max_k max(0, y_j − hi_j, lo_j − y_j)        residual_tol·scale_y
========================  ==========================================  =====================

(A vector sign's selection λ ∈ B, isotropic friction, has λ − P_B(λ + s), P_B the projection
onto the unit ball, in place of the clip.) scale_x = max(1, max |x|) and scale_z = max(1,
max |z|) over the trajectory (scale_y = max(1, max |y_j|) of the bounded states and controls,
``state_bounds`` and ``control_bounds``): a problem
whose states are of size 1e3 gets tolerances 1e3 times larger, one of size 1e-3 keeps
the absolute tolerance. x(t_0) = x0 holds exactly (x0 is data, not an unknown).

A periodic condition x_P(T) = x_P(0) met within its tolerance by a motion that does not
turn back is met by the tolerance, not by the dynamics: over a short enough T every
trajectory ends within the tolerance of its start (a free T can shrink towards 0, as
:mod:`qdframe.unknowns` warns). :func:`closed_by_tolerance` names such a result (its gap
more than half the distance x_P travels and above round-off); an equilibrium, x constant,
has no gap and is not named.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..functional import Functional

# a descent with I ≤ tol but a pointwise check failing goes on while the worst check's ratio to
# its tolerance shrinks by at least this factor in a window of iterations (qdframe.descent.loop)
CERTIFY_SHRINK = 4.0
# a periodic gap below this (relative to max(1, max|x|)) is round-off: x is at rest
ROUND_OFF = 1e-13


@dataclass(frozen=True)
class Check:
    """One pointwise check: its value (a max over the nodes) and its tolerance."""

    name: str
    value: float
    tol: float

    @property
    def passed(self) -> bool:
        return bool(self.value <= self.tol)

    @property
    def ratio(self) -> float:
        """value / tol: above 1 the check fails; the largest ratio is the binding check."""
        return self.value / self.tol


def scaled_tol(residual_tol: float, values: np.ndarray) -> float:
    """residual_tol·max(1, max|values|): a check's tolerance on the scale of x, z or y."""
    return residual_tol * max(1.0, float(np.max(np.abs(values), initial=0.0)))


def checks(functional: Functional, xi: np.ndarray, residual_tol: float) -> list[Check]:
    """The pointwise checks of the iterate ξ (the table in this module's docstring)."""
    residuals = functional.residuals(xi)
    x, z = functional.split(xi)
    tol_x, tol_z = scaled_tol(residual_tol, x), scaled_tol(residual_tol, z)
    out = [Check("boundary", residuals.boundary_error, tol_x),
           Check("inclusion", residuals.inclusion_residual, tol_z)]
    if residuals.selection_residual is not None:
        out.append(Check("selection", residuals.selection_residual, residual_tol))
    out.append(Check("consistency", residuals.consistency_error, tol_x))
    if residuals.surface_error is not None:
        out.append(Check("surface", residuals.surface_error, tol_x))
    if functional.bounds is not None:
        y = functional.arguments(xi)[:, functional.bounds.columns]
        violation = float(np.max(np.maximum(functional.values.bound_sides(functional.arguments(xi)), 0.0)))
        out.append(Check("bounds", violation, scaled_tol(residual_tol, y)))
    return out


def failures(found: list[Check]) -> str:
    """The failed checks as one clause ("inclusion 3.1e-06 > 1.0e-08, …"), empty if none."""
    return ", ".join(f"{check.name} {check.value:.2e} > {check.tol:.1e}" for check in found if not check.passed)


def binding(found: list[Check]) -> str:
    """The name of the check closest to (or furthest past) its tolerance."""
    return max(found, key=lambda check: check.ratio).name


def closed_by_tolerance(functional: Functional, x: np.ndarray) -> str:
    """Why the periodic conditions of `x` (N, ≥ n) hold only within their tolerance (the
    module docstring), or empty: |x_P(T) − x_P(0)| > ½·Σ_k |x_P(t_{k+1}) − x_P(t_k)| (max
    norms) and above round-off."""
    periodic = np.asarray(functional.periodic, dtype=int)
    if periodic.size == 0:
        return ""
    path = x[:, periodic]
    gap = float(np.max(np.abs(path[-1] - path[0])))
    travelled = float(np.sum(np.max(np.abs(np.diff(path, axis=0)), axis=1)))
    if gap <= 0.5 * travelled or gap <= ROUND_OFF * max(1.0, float(np.max(np.abs(x)))):
        return ""
    return (f"the periodic condition holds only within its tolerance: x does not turn back (it ends "
            f"{gap:.1e} from its start, {gap / travelled:.0%} of the {travelled:.1e} it travels), so over a "
            f"horizon this short any motion would pass")
