"""nosnoc's statement of an :class:`~.ocp_problems.OcpProblem`, and one run of it.

As nosnoc's own examples state an optimal-control problem (its motor with friction, its
cart-pole): the control u with box bounds ``lbu``/``ubu``, the state bounds ``lbx``/``ubx``,
the stage cost ``f_q`` = c(x, u), ``f_terminal`` = M(x), the end values as the terminal
equality constraint ``g_terminal``, and the contact in Stewart's form, one subsystem with the
modes g − b(x) (where c = x_j > 0) and g + b(x) (x_j < 0), b = a·e_j for a force on x_j' alone. A smooth problem is one subsystem whose two modes are both g.
`stages` control stages of `elements` finite elements each, u constant on a stage; Radau IIA
with n_s = 2, FESD, complementarity tolerance 1e-9 (the settings of
:func:`.nosnoc_peer.run_nosnoc`). The run's control is its stagewise u
(``u_traj`` on ``t_grid_u``), which :mod:`.ocp` replays.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from ..status import Status
from .nosnoc_peer import TWO_MODES, nosnoc_available, settings, solve_quietly
from .ocp_problems import OcpProblem
from .peer import package_version


@dataclass
class OcpRun:
    """One nosnoc run: its status, its control (constant on each stage), its own cost and end state."""

    status: Status
    stage_times: np.ndarray  # (S + 1,) the control stages' ends, from 0 to T
    controls: np.ndarray  # (S, m) u on each stage
    own_cost: float
    own_end: np.ndarray
    wall_time_s: float
    message: str


def statement(problem: OcpProblem, ca, nosnoc) -> tuple[object, object]:
    """nosnoc's model and OCP of `problem`."""
    x = ca.SX.sym("x", problem.n)
    u = ca.SX.sym("u", 1)
    g = ca.vertcat(*problem.field(x, u))
    if problem.friction is not None:
        push = ca.vertcat(*problem.push(x))
        modes, switch = ca.horzcat(g - push, g + push), x[problem.friction[0]]
    else:
        modes, switch = ca.horzcat(g, g), x[0]
    model = nosnoc.NosnocModel(x=x, F=[modes], c=[switch], S=[TWO_MODES], x0=np.array(problem.x0, dtype=float), u=u)
    extra = {}
    if problem.u_bounds is not None:
        extra.update(lbu=np.array([problem.u_bounds[0]]), ubu=np.array([problem.u_bounds[1]]))
    if problem.x_bounds:
        lbx, ubx = np.full(problem.n, -np.inf), np.full(problem.n, np.inf)
        for i, (lo, hi) in problem.x_bounds.items():
            lbx[i], ubx[i] = lo, hi
        extra.update(lbx=lbx, ubx=ubx)
    if problem.end:
        index = sorted(problem.end)
        extra["g_terminal"] = ca.vertcat(*[x[i] - problem.end[i] for i in index])
    if problem.terminal is not None:
        extra["f_terminal"] = problem.terminal(x)
    return model, nosnoc.NosnocOcp(f_q=problem.running(x, u), **extra)


def run(problem: OcpProblem, stages: int, elements: int) -> OcpRun:
    """nosnoc on `problem`: `stages` control stages × `elements` finite elements each."""
    reason = nosnoc_available()
    if reason is not None:
        return OcpRun(Status.FAILED, np.zeros(0), np.zeros((0, 1)), float("nan"), np.full(problem.n, np.nan), 0.0,
                      reason)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import casadi as ca
        import nosnoc

    start = time.perf_counter()
    model, ocp = statement(problem, ca, nosnoc)
    opts = settings(nosnoc, problem.T, stages, elements)
    _, results, setup, wall, _ = solve_quietly(nosnoc, opts, model, ocp, start)
    success = results["status"] == nosnoc.Status.SUCCESS
    iterations = int(sum(i for i in results["nlp_iter"] if i is not None))
    outcome = "success" if success else f"IPOPT did not converge ({getattr(results['status'], 'name', results['status'])})"
    message = (f"nosnoc {package_version('nosnoc')}: {outcome}, {iterations} IPOPT iterations, own cost "
               f"{float(results['cost_val']):.10g}; setup {setup:.2f} s")
    return OcpRun(Status.SOLVED if success else Status.FAILED, np.asarray(results["t_grid_u"], dtype=float).reshape(-1),
                  np.asarray(results["u_traj"], dtype=float).reshape(stages, -1), float(results["cost_val"]),
                  np.asarray(results["x_traj"], dtype=float)[-1], wall, message)
