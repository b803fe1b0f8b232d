"""The solve_bvp peer (qdframe.bench.solve_bvp_peer): its statements and what they cost.

Measured (scipy 1.17.1, ε = tol, 11-node uniform start, x0 held constant, max_nodes 1e5):

* solve_bvp succeeds at tol = 1e-3 on block-breakaway, slide-after-reaching,
  two-surface-sliding, coulomb-block and stick-slip-oscillator, and at tol = 1e-2 on
  every model tried; at tol = 1e-4 and below it fails on every model (max_nodes exceeded:
  the nodes pile up over the stick/sliding phases, where the regularized f has slope a/ε
  and Lobatto IIIA, not L-stable, leaves the stiff component undamped unless h ≲ ε; 3e6
  nodes did not suffice at tol = 1e-6 either).
* where it succeeds, the error against the exact Filippov solution is the
  regularization's O(ε), with the constants predicted below (block-breakaway 1.70ε,
  slide-after-reaching 0.41ε, two-surface-sliding 0.47ε, stick-slip 0.25ε at ε = 1e-3).

So the error-against-tol check runs where solve_bvp solves (tol 1e-2 → 1e-3), and the
check at tol = 1e-6 is a strict xfail: it records the requirement and fails loudly the day
solve_bvp (or this statement) starts solving there.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from qdframe.bench import problems
from qdframe.bench.solve_bvp_peer import boundary_conditions, run_solve_bvp, statement
from qdframe.models.exact_friction import OSC_FRICTION as STICK_SLIP_FRICTION  # p' = v, v' ∈ −p − 0.1·Sgn(v)
from qdframe.registry import load_model
from qdframe.errors import InputError
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.model import InclusionModel, SetBlock, SignTerm
from qdframe.ready_pieces import affine, coordinate


# ------------------------------------------------- a stand-in for stick-slip-oscillator
STICK_SLIP_NAME = "stick-slip-oscillator"


def stick_slip_motion(t: np.ndarray, p0: float = 5.0, mu: float = STICK_SLIP_FRICTION) -> np.ndarray:
    """Exact Filippov solution of p' = v, v' ∈ −p − μ·Sgn(v), v(0) = 0: half cycles of length π
    about the centre c = μ·sign(p_k) (the friction opposes the motion towards −sign(p_k)),
    p_{k+1} = 2c − p_k, until |p_k| ≤ μ, then at rest. From p0 = 5: 25 half cycles, rest at
    p = 0 from t = 25π ≈ 78.54."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    starts, turns, centres = [], [], []
    p, time = p0, 0.0
    while abs(p) > mu:
        centre = mu * np.sign(p)
        starts.append(time), turns.append(p), centres.append(centre)
        p, time = 2 * centre - p, time + np.pi
    out = np.tile([p, 0.0], (t.size, 1))
    moving = t < time
    k = np.floor(t[moving] / np.pi).astype(int)
    s = t[moving] - np.asarray(starts)[k]
    amplitude = np.asarray(turns)[k] - np.asarray(centres)[k]
    out[moving] = np.stack([np.asarray(centres)[k] + amplitude * np.cos(s), -amplitude * np.sin(s)], axis=1)
    return out


class StickSlipStandIn(InclusionModel):
    """p' = v, v' ∈ −p − 0.1·Sgn(v) (coded 0.1·Sgn(−v)), p(0) = 5, v(0) = 0, T = 100: the
    colleague's model as the brief states it, for the checks here only."""

    name = STICK_SLIP_NAME
    state_names = ("position", "velocity")
    default_T = 100.0
    default_x0 = (5.0, 0.0)

    def blocks(self):
        return (
            SetBlock.equation(0, coordinate(1, 2), "p' = v"),
            SetBlock.equation(1, affine({0: -1.0}, 2), "v' ∈ −p − μ·Sgn(v)",
                              (SignTerm(STICK_SLIP_FRICTION, affine({1: -1.0}, 2), name="μ·Sgn(−v)"),)),
        )

    def exact_solution(self, t):
        return stick_slip_motion(t)


def _model(name: str) -> InclusionModel:
    return StickSlipStandIn() if name == STICK_SLIP_NAME else load_model(name)


def _run(model, tol):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # solve_bvp's overflow warnings on the failing runs
        return run_solve_bvp(model, tol)


def _error(model, run) -> float:
    return float(np.max(np.abs(run.x - model.exact_solution(run.t))))


def test_stand_in_exact_solution_is_a_filippov_solution():
    """The reference for stick-slip is itself right: in the set (λ = sign(−v) off v = 0, the
    equivalent λ = p/μ ∈ [−1, 1] at rest) and consistent with x' = z (trapezoid rule)."""
    model = StickSlipStandIn()
    functional = Functional(model, Grid(model.T, 20001), signs="exact")
    t = functional.grid.t
    x = stick_slip_motion(t)
    # λ ∈ Sgn(−v): sign(−v) while moving; at v = 0 (t = 0, and at rest) the one that moves or
    # holds it, clip(p/μ, −1, 1) (at t = 0: 1, v then turns negative)
    lam = np.where(x[:, 1] != 0, np.sign(-x[:, 1]), np.clip(x[:, 0] / STICK_SLIP_FRICTION, -1.0, 1.0))
    z = np.stack([x[:, 1], -x[:, 0] + STICK_SLIP_FRICTION * lam], axis=1)
    residuals = functional.residuals(functional.pack(x, z, selections=lam[:, None]))
    assert residuals.inclusion_residual < 1e-12 and residuals.selection_residual < 1e-12
    assert residuals.consistency_error < 2e-3  # trapezoid rule, h = 5e-3: h²/12·T·max|x'''| ≈ 1e-3 (measured 5e-4)
    assert np.isclose(x[-1, 0], 0.0, atol=1e-12)  # 5 − 25·0.2 = 0: at rest at p = 0 from 25π


# ------------------------------------------------------ the statement lies in F(y)
@pytest.mark.parametrize("name", problems.with_sign_form())
def test_statement_lies_in_the_models_set_off_the_surfaces(name):
    """At random states with every coded switch |s| ≥ 0.05 (≫ ε, so sat = sign), fun(t, y) is
    the point of F(y) with λ = sign(s) (signs="exact": an equality check, which catches a
    flipped sign even where the model's band is infinite) and lies in the banded set the
    sweep judges peers by (signs="band")."""
    model = _model(name)
    n = model.n_states
    rng = np.random.default_rng(7)
    y = rng.uniform(-3.0, 3.0, size=(4000, n))
    if name == "block-breakaway":
        y[:, 2] = rng.uniform(0.0, model.T, size=y.shape[0])  # the clock
    exact = Functional(model, Grid(model.T, 2), signs="exact")
    switches = np.stack([term.switch(y)[0] for _, term in exact.selection_terms], axis=1)
    y = y[np.all(np.abs(switches) >= 0.05, axis=1)][:500]
    switches = np.stack([term.switch(y)[0] for _, term in exact.selection_terms], axis=1)
    assert y.shape[0] == 500
    z = statement(name, 1e-6, model)(np.zeros(y.shape[0]), y.T).T
    assert z.shape == y.shape
    for signs in ("exact", "band"):
        functional = Functional(model, Grid(model.T, y.shape[0]), signs=signs)
        xi = functional.pack(y, z, selections=np.sign(switches) if signs == "exact" else None)
        xi[0, :n] = y[0]  # pack puts x0 on node 0; these are states, not a trajectory
        assert functional.residuals(xi).inclusion_residual < 1e-12, signs


def test_boundary_conditions_are_the_models():
    model = load_model("block-stop-stick-bvp")  # p(0) free, v(0) = 2, p(3) = 1
    bc = boundary_conditions(model.x0, model.end_indices, model.end_values)
    assert np.allclose(bc(np.array([7.0, 2.5]), np.array([1.5, 9.0])), [0.5, 0.5])
    with pytest.raises(InputError):
        boundary_conditions((0.0, 2.0), (0,), (1.0,))  # three conditions for two states
    with pytest.raises(InputError):
        run_solve_bvp(load_model("coulomb-rest-to-rest"), 1e-3)  # a bounded input: nosnoc's


# ----------------------------------------------------- accuracy where it solves
# error ≤ bound·ε at tol = ε = 1e-3; measured 1.70ε, 0.41ε, 0.47ε, 0.25ε. Predicted:
# * block-breakaway: sticking, v' = −sat(v/ε) + t balances at v = ε·t (not 0), p = ε·t²/2;
#   at breakaway v = ε, then v' = t − 1 exactly: |Δv| = ε, |Δp| = ε/2 + ε·(T − 1) = 1.7ε at T.
# * slide-after-reaching: sliding needs sat(s/ε) = −x2'/2 = x2/2, so s = ε·x2/2, |s| ≤ ε·r
#   (r = √2 − 1, |x2| ≤ 2r), and x1' = −x1 + s relays it: |Δ| ≈ 0.41ε.
# * two-surface-sliding: on x2 = 0 sat(x2/ε) = a2 → x2 = −0.25ε; on x1 = 0 sat(x1/ε) =
#   0.375 → x1 = 0.375ε; plus the entry transients: ≈ 0.47ε.
# * stick-slip: 25 passes through v = 0, each in the layer |v| < ε for O(ε) time: 0.25ε
#   (measured; the last one ends at rest on p = 0).
BOUNDS = {"block-breakaway": 2.0, "slide-after-reaching": 0.5, "two-surface-sliding": 0.6, STICK_SLIP_NAME: 0.5}


@pytest.mark.parametrize("name", tuple(BOUNDS))
def test_error_is_the_regularizations_and_shrinks_with_tol(name):
    model = _model(name)
    coarse, fine = _run(model, 1e-2), _run(model, 1e-3)
    assert coarse.status == fine.status == "solved", (coarse.message, fine.message)
    assert fine.t.size == fine.x.shape[0] and fine.z.shape == fine.x.shape and fine.iterations > 0
    assert np.all(np.diff(fine.t) > 0) and fine.t[0] == 0.0 and fine.t[-1] == model.T
    e_coarse, e_fine = _error(model, coarse), _error(model, fine)
    assert e_fine <= BOUNDS[name] * 1e-3, e_fine
    assert e_fine < 0.2 * e_coarse, (e_coarse, e_fine)  # O(ε): ×10 in ε, ≥ ×5 in error


@pytest.mark.xfail(strict=True, reason="measured: at ε = tol = 1e-6 solve_bvp exceeds max_nodes on every "
                   "model (the stiff layer needs h ≲ ε over whole stick/sliding phases)")
@pytest.mark.parametrize("name", ("block-breakaway", "two-surface-sliding"))
def test_tol_1e6_reaches_the_regularization_error(name):
    model = _model(name)
    run = _run(model, 1e-6)
    assert run.status == "solved", run.message
    assert _error(model, run) <= BOUNDS[name] * 1e-6
