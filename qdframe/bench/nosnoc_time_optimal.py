"""nosnoc's statement of the time-optimal block (``block-time-optimal``, T free), and one run of it.

The block p' = v, v' ∈ [−2, 2] − Sgn(v) is, in nosnoc's terms, a control u with box bounds
|u| ≤ 2 and one subsystem in Stewart's form: modes (v, u − 1) where c = v > 0 and (v, u + 1)
where c < 0; x(0) = (0, 0), the terminal equality constraint x(T) = (1, 0).

nosnoc integrates on a numerical horizon [0, T_nom] (``opts.terminal_time``; here the model's
guess T = 2, the one qdframe starts from) and makes T free by a *speed of time* s ≥ 0:
x' = s·f(x, u) in numerical time τ, so physical time runs at dt = s·dτ, and the cost
∫ s·1 dτ is the physical end time T. Two formulations (:data:`FORMULATIONS`):

- ``global``: one s for the whole horizon, T = s·T_nom. nosnoc 0.2.0's own
  ``SpeedOfTimeVariableMode.GLOBAL`` fails while it builds the problem (``NosnocProblem``
  has no ``add_variables``), so s is stated as nosnoc's global variable (``v_global``): the
  modes multiplied by s and the running cost f_q = s, which is the same NLP. The control
  stages are equal in physical time, each T/N_stages long.
- ``local``: nosnoc's ``SpeedOfTimeVariableMode.LOCAL``: one s_k per control stage, so each
  stage's physical length s_k·T_nom/N_stages is free and a stage boundary can sit on the
  switch; f_q = 1 (nosnoc multiplies it by s_k).

Both: s in [:data:`SPEED_MIN`, :data:`SPEED_MAX`], guessed 1 (T = 2); Radau IIA, n_s = 2,
complementarity tolerance 1e-9, FESD step equilibration as nosnoc's defaults (the settings
of :func:`.nosnoc_peer.run_nosnoc`). The trajectory is read as there (:func:`.nosnoc_peer.reconstruct`)
on the physical element lengths s·h_e: x and x' at nosnoc's own points.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from ..models.identification import BlockTimeOptimal
from ..status import Status
from .nosnoc_peer import (TWO_MODES, _collocation_nodes, nosnoc_available, own_times, reconstruct, settings,
                          solve_quietly)
from .peer import package_version

FORMULATIONS = ("global", "local")
FORCE_BOUND = 2.0  # |u| ≤ 2: the model's Interval(−2, 2)
FRICTION = 1.0  # the model's Sgn(v) coefficient
SPEED_MIN, SPEED_MAX = 0.1, 25.0  # s: T between 0.2 and 50 (nosnoc's default lower bound 1 would force T ≥ 2)


@dataclass
class TimeOptimalRun:
    """One nosnoc run: its status, its T, its trajectory at its own points (physical time)."""

    status: Status
    T: float
    t: np.ndarray
    x: np.ndarray
    wall_time_s: float
    setup_time_s: float
    message: str


def statement(model: BlockTimeOptimal, formulation: str, ca, nosnoc) -> tuple[object, object]:
    """nosnoc's model and OCP of `model` with T free by `formulation` (one of :data:`FORMULATIONS`)."""
    if formulation not in FORMULATIONS:
        raise ValueError(f"unknown formulation {formulation!r}; expected one of {', '.join(FORMULATIONS)}")
    position, velocity, force = ca.SX.sym("p"), ca.SX.sym("v"), ca.SX.sym("u")
    x = ca.vertcat(position, velocity)
    modes = ca.horzcat(ca.vertcat(velocity, force - FRICTION), ca.vertcat(velocity, force + FRICTION))
    end = np.zeros(2)
    end[list(model.end_indices)] = model.end_values
    bounds = {"lbu": -FORCE_BOUND * np.ones(1), "ubu": FORCE_BOUND * np.ones(1), "g_terminal": x - end}
    if formulation == "global":
        speed = ca.SX.sym("s")
        nos_model = nosnoc.NosnocModel(x=x, F=[speed * modes], c=[velocity], S=[TWO_MODES], x0=np.array(model.x0),
                                       u=force, v_global=speed)
        ocp = nosnoc.NosnocOcp(f_q=speed, lbv_global=np.array([SPEED_MIN]), ubv_global=np.array([SPEED_MAX]),
                               v_global_guess=np.ones(1), **bounds)
    else:
        nos_model = nosnoc.NosnocModel(x=x, F=[modes], c=[velocity], S=[TWO_MODES], x0=np.array(model.x0), u=force)
        ocp = nosnoc.NosnocOcp(f_q=ca.SX.ones(1), **bounds)
    return nos_model, ocp


def options(model: BlockTimeOptimal, formulation: str, stages: int, elements: int, nosnoc):
    """nosnoc's options: `stages` control stages of `elements` finite elements each on [0, model.T]."""
    opts = settings(nosnoc, model.T, stages, elements)
    if formulation == "local":
        opts.speed_of_time_variables = nosnoc.SpeedOfTimeVariableMode.LOCAL
        opts.speed_of_time_min, opts.speed_of_time_max = SPEED_MIN, SPEED_MAX
    return opts


def speeds(results: dict, formulation: str, stages: int, elements: int) -> np.ndarray:
    """The speed of time on each finite element."""
    if formulation == "global":
        return np.full(stages * elements, float(np.asarray(results["v_global"], dtype=float).reshape(-1)[0]))
    return np.repeat(np.asarray(results["sot"], dtype=float).reshape(-1), elements)


def run(formulation: str, stages: int, elements: int, model: BlockTimeOptimal | None = None) -> TimeOptimalRun:
    """Solve the time-optimal block with nosnoc: `stages` control stages × `elements` finite
    elements each; T and the trajectory in physical time."""
    model = model if model is not None else BlockTimeOptimal()
    reason = nosnoc_available()
    if reason is not None:
        return TimeOptimalRun(Status.FAILED, float("nan"), np.zeros(0), np.zeros((0, 2)), 0.0, 0.0, reason)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import casadi as ca
        import nosnoc

    start = time.perf_counter()
    nos_model, ocp = statement(model, formulation, ca, nosnoc)
    opts = options(model, formulation, stages, elements, nosnoc)
    _, results, setup, wall, _ = solve_quietly(nosnoc, opts, nos_model, ocp, start)

    physical = dict(results)
    physical["time_steps"] = np.asarray(results["time_steps"], dtype=float).reshape(-1) * speeds(
        results, formulation, stages, elements)
    T = float(np.sum(physical["time_steps"]))
    tau = _collocation_nodes(opts)
    t = own_times(physical, tau, np.array([0.0, T]))
    x, _ = reconstruct(physical, tau, t)
    success = results["status"] == nosnoc.Status.SUCCESS
    iterations = int(sum(i for i in results["nlp_iter"] if i is not None))
    steps = sum(1 for i in results["nlp_iter"] if i is not None)
    outcome = "success" if success else f"IPOPT did not converge ({getattr(results['status'], 'name', results['status'])})"
    message = (f"nosnoc {package_version('nosnoc')}: {outcome} after {steps} homotopy steps ({iterations} IPOPT "
               f"iterations), own cost {float(results['cost_val']):.10g}; setup {setup:.2f} s")
    return TimeOptimalRun(Status.SOLVED if success else Status.FAILED, T, t, x, wall, setup, message)
