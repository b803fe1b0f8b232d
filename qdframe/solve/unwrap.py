"""A solve's result of a model with T or parameters unknown (:class:`qdframe.unknowns.Unknowns`,
the model on s = t/T with constant states) mapped back to the model's own time and states:
t = s·T, x = X, z = X'/T, ``result.T`` and ``result.parameters`` (:func:`unwrap`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from ..model import InclusionModel
from ..result import SolveResult, UnknownsRecord
from ..status import Status
from ..unknowns import Unknowns

SHRUNK = 1e-3  # an unsolved period found below this fraction of its guess is named as drawn to T = 0


def _solution_error(model: InclusionModel, t: np.ndarray, x: np.ndarray, T: float,
                    parameters: Mapping[str, float]) -> float | None:
    """max |x − x*| at the user's times, and |T − T*| and |p_i − p_i*| where the model knows
    them (``exact_T``, ``exact_parameters``); None without a known solution."""
    exact = model.exact_solution(t)
    if exact is None:
        return None
    gaps = [float(np.max(np.abs(x - exact)))]
    if model.free_T and model.exact_T is not None:
        gaps.append(abs(T - model.exact_T))
    gaps += [abs(parameters[name] - value) for name, value in model.exact_parameters.items()]
    return max(gaps)


def unwrap(wrapper: Unknowns, result: SolveResult) -> SolveResult:
    """The result in the model's own time and states. A replay keeps the T found, so its
    estimate, of X and the σ's, is multiplied by 1 + max_s |X'(s)|: to first order an error ΔT
    moves every point by |ΔT|/T·s·|X'|."""
    n = wrapper.n
    T, parameters = wrapper.found(np.asarray(result.x, float))
    factor = T if wrapper.scaled else 1.0
    speed = float(np.max(np.abs(result.z[:, :n]))) if result.z.size else 0.0
    estimate = result.error_estimate
    if estimate is not None and wrapper.scaled and result.certificate != "bisection":
        estimate *= 1.0 + speed  # a replay keeps T: what an error ΔT/T moves the points by
    set_bounds = [None if b is None else {**b, "lower": b["lower"] / factor, "upper": b["upper"] / factor}
                  for b in result.set_bounds if b is None or b["coordinate"] < n]
    t, x = np.asarray(result.t, float) * factor, result.x[:, :n]
    out = dataclasses.replace(
        result, T=T, t=t, x=x, z=result.z[:, :n] / factor, state_names=tuple(wrapper.inner.state_names),
        error_estimate=estimate, switch_times=np.asarray(result.switch_times, float) * factor, parameters=parameters,
        set_bounds=set_bounds, solution_error=_solution_error(wrapper.inner, t, x, T, parameters),
        unknowns=UnknownsRecord(wrapper.scaled, wrapper.T_guess, wrapper.T0,
                                dict(zip(wrapper.inner.parameter_names, map(float, wrapper.inner.parameters)))),
    )
    if estimate is not None and out.status == Status.SOLVED and out.accuracy is not None:
        bound = out.accuracy * max(1.0, float(np.max(np.abs(out.x))))
        if estimate > bound:
            out.status = Status.UNCERTIFIED
            out.remarks = [*out.remarks, f"the scaled problem is certified, but with T free the error at the "
                                         f"model's times, estimate {estimate:.1e}, exceeds the target {bound:.1e}"]
    if wrapper.scaled and wrapper.periodic and out.status != Status.SOLVED and T < SHRUNK * wrapper.T_guess:
        out.remarks = [*out.remarks, f"T shrank from the guess {wrapper.T_guess:g} to {T:.2g}, towards the trivial "
                                     f"period T = 0 of a constant x: bound T from below (T_bounds) or guess it nearer"]
    return out
