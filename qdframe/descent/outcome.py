"""What a descent returns: the :class:`~qdframe.result.SolveResult` of its last iterate
with its residuals, pointwise checks and diagnosis, and a model's NaN/inf named with its
piece, node, t and state (:func:`located`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import checks
from .diagnosis import unmet_conditions
from ..errors import ModelOutputError
from ..functional import Functional
from ..registry import plugin_code
from ..result import DescentRecord, IterationRecord, SolveResult
from .options import DescentOptions
from ..status import Status

if TYPE_CHECKING:
    from ..directions.base import DirectionSolver
    from ..line_searches.base import LineSearch


def located(functional: Functional, xi: np.ndarray, error: ModelOutputError, where: str,
             why: str = "") -> ModelOutputError:
    """`error` (a model's NaN/inf or wrong shape) as one line naming the piece, the node, t and
    the state (x, u) of the iterate `xi` at that node, as `check-model` names its points."""
    name = functional.model.name
    if not error.nonfinite or error.label is None:
        return ModelOutputError(f"{error} (at {where})" + (f"; {why}" if why else ""), label=error.label,
                                node=error.node, nonfinite=error.nonfinite)
    text = f"model {name!r}: {error.label} is non-finite"
    if error.node is not None:
        node = error.node
        names = list(functional.model.state_names) + list(functional.model.control_names)
        state = ", ".join(f"{label} = {value:.6g}" for label, value in zip(names, functional.arguments(xi)[node]))
        text += f" at node {node} (t = {functional.grid.t[node]:.6g}) of {where}, where ({state})"
    else:
        text += f" at {where}"
    return ModelOutputError(text + (f"; {why}" if why else ""), label=error.label, node=error.node, nonfinite=True)


def residuals_disagree(functional: Functional, residuals, I: float) -> str:
    """What I ≤ tol implies for each residual, checked (empty when all agree).

    χ ≤ I gives |x0 + ∫z − xT| ≤ √(2I); φ, υ, ω ≤ I give, at any node k,
    h, |x − x0 − ∫z|, ‖e‖ ≤ √(2I/w_k); the boundary error read from x adds υ's at T.
    """
    slack = 1.0 + 1e-6
    pointwise = np.sqrt(2.0 * I / np.min(functional.weights)) * slack + 1e-300
    checks = [
        ("boundary error", residuals.boundary_error, np.sqrt(2.0 * I) * slack + pointwise),
        ("inclusion residual", residuals.inclusion_residual, pointwise),
        ("consistency error", residuals.consistency_error, pointwise),
        ("surface error", residuals.surface_error or 0.0, pointwise),
        # σ's natural map with scale c bounds the one with c = 1: min(1, c)·|r_1| ≤ |r_c|
        ("selection residual", residuals.selection_residual or 0.0, pointwise / min(1.0, functional.selection_scale)),
    ]
    return ", ".join(f"{name} {value:.2e} > {bound:.2e}" for name, value, bound in checks if value > bound)


def result_of(functional: Functional, solver: DirectionSolver, search: LineSearch, options: DescentOptions,
              xi: np.ndarray, status: Status, reason: str, remarks: list[str], history: list[IterationRecord],
              elapsed: float) -> SolveResult:
    """The result of a descent that ended at ξ with `status`: its terms, residuals and
    pointwise checks; `solved` becomes `failed` where I ≤ tol contradicts a residual
    (:func:`residuals_disagree`), and a stop short of I ≤ tol names the unmet conditions."""
    model = functional.model
    terms = functional.terms(xi)
    residuals = functional.residuals(xi)
    if status == Status.SOLVED:
        disagreement = residuals_disagree(functional, residuals, terms.I)
        if disagreement:
            status, reason = Status.FAILED, f"I = {terms.I:.2e} ≤ tol but {disagreement}: an internal inconsistency"
    found = checks.checks(functional, xi, options.residual_tol)
    if status != Status.SOLVED and terms.objective <= options.tol and terms.I <= options.tol:
        remarks = [*remarks, f"I = {terms.I:.1e} ≤ tol but not pointwise: {checks.failures(found)}"]
    if status in (Status.STATIONARY, Status.MAX_ITER) and terms.I > options.tol:  # I bounded away from 0: name where it sits
        diagnosis = unmet_conditions(functional, xi, options.residual_tol)
        remarks = [*remarks, diagnosis] if diagnosis else remarks
    x, z = functional.split(xi)
    with plugin_code(model, "exact_solution()"):
        exact = model.exact_solution(functional.grid.t)
    solution_error = None if exact is None else float(np.max(np.abs(x - exact)))
    bounds = [
        None if b is None else {"coordinate": block.coords[0], "lower": b[0], "upper": b[1]}
        for block, b in zip(functional.blocks, functional.set_bounds(xi))
    ]
    return SolveResult(
        model=model.name,
        direction=getattr(solver, "label", solver.name),
        line_search=search.name,
        nodes=functional.grid.nodes,
        T=model.T,
        status=status,
        reason=reason,
        remarks=list(remarks),
        iterations=len(history) - 1,
        wall_time_s=elapsed,
        objective=terms.objective,
        I=terms.I,
        terms={"phi": terms.phi, "chi": terms.chi, "omega": terms.omega, "upsilon": terms.upsilon, "sigma": terms.sigma},
        cost=functional.values.cost_value(x, functional.arguments(xi), quadrature=True) if functional.cost is not None
        else None,
        boundary_error=residuals.boundary_error,
        inclusion_residual=residuals.inclusion_residual,
        surface_error=residuals.surface_error,
        consistency_error=residuals.consistency_error,
        selection_residual=residuals.selection_residual,
        solution_error=solution_error,
        t=functional.grid.t,
        x=x,
        z=z,
        u=functional.controls(xi) if functional.m else None,
        selections=functional.selections(xi) if functional.p else None,
        selection_names=list(functional.selection_names),
        selection_written=tuple(functional.selection_written),
        state_names=tuple(model.state_names),
        control_names=tuple(model.control_names),
        set_bounds=bounds,
        descent=DescentRecord(functional.grid.scheme.name, options.max_iter, options.tol, options.delta, options.eps,
                              options.gamma_max, options.residual_tol),
        history=list(history),
        checks={check.name: {"value": check.value, "tol": check.tol} for check in found},
        binding_check=checks.binding(found),
    )
