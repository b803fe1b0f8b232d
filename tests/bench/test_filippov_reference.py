"""The independent Filippov statements (qdframe.bench.replay_statements, through the catalogue
qdframe.bench.problems) integrated by the event-driven integrator, against closed forms.

Every model with an exact solution that `statement` covers: the reference motion agrees
with it to 1e-9 at 2001 times and its mode changes happen at the model's switch times.
The input-driven problems (no exact solution) are checked against motions worked out by
hand: a bang-bang force on the Coulomb block, the zero input on the two nonlinear surfaces.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import qdframe
from qdframe.bench.problems import reference, statement
from qdframe.certificates.filippov import FilippovError, FilippovSystem, integrate
from qdframe.models.exact_friction import FRICTION_MODELS
from qdframe.models.paper_73 import Paper73

EXACT = sorted(FRICTION_MODELS) + ["coulomb-block", "sliding-mode"]
TOL = 1e-9


def _model(name: str):
    # stick-slip-oscillator is new: the installed entry points may not name it yet
    return FRICTION_MODELS[name]() if name in FRICTION_MODELS else qdframe.load_model(name)


@pytest.fixture(scope="module")
def references():
    return {name: reference(_model(name)) for name in EXACT}


def test_the_covered_models_include_two_switch_sliding_and_a_stick_release():
    assert {"two-surface-sliding", "block-breakaway", "stick-slip-oscillator"} <= set(EXACT)


@pytest.mark.parametrize("name", EXACT)
def test_reference_agrees_with_the_exact_solution(references, name):
    model = _model(name)
    t = np.linspace(0.0, model.T, 2001)
    x = references[name](t)
    assert x.shape == (t.size, model.n_states)
    error = np.max(np.abs(x - model.exact_solution(t)))
    print(f"{name}: max |x − x*| = {error:.2e}, {references[name].seconds:.3f} s")
    assert error <= TOL


@pytest.mark.parametrize("name", EXACT)
def test_reference_switch_times_are_the_models(references, name):
    """A model that names no switch times has none: sliding-mode slides on its surface from
    t = 0 to T, one Filippov mode throughout."""
    expected = getattr(_model(name), "switch_times", ())
    found = references[name].switch_times
    assert len(found) == len(expected), (found, expected)
    if expected:
        offset = np.max(np.abs(np.array(found) - np.array(expected)))
        print(f"{name}: switch offset {offset:.1e}")
        assert offset <= TOL


def test_two_surface_sliding_slides_on_x2_then_on_both(references):
    """Modes (Sgn x1, Sgn x2): (+1, −1), then sliding on x2 = 0 at 0.4, on both at 1.04."""
    modes = references["two-surface-sliding"].modes
    assert [m for _, m in modes] == [(1, -1), (1, 0), (0, 0)]
    assert [t for t, _ in modes][1:] == pytest.approx([0.4, 1.04], abs=TOL)


def test_block_breakaway_sticks_then_releases_forward(references):
    modes = references["block-breakaway"].modes
    assert [m for _, m in modes] == [(0,), (1,)]
    assert modes[1][0] == pytest.approx(1.0, abs=TOL)


def test_stick_slip_oscillator_turning_points_by_hand(references):
    """|p| shrinks by 2μ = 0.2 per half cycle: p(kπ) = (−1)^k·(5 − 0.2k); stuck at p = 0 from 25π."""
    run = references["stick-slip-oscillator"]
    k = np.arange(0, 26)
    x = run(k * np.pi)
    assert np.max(np.abs(x[:, 0] - (-1.0) ** k * (5.0 - 0.2 * k))) <= TOL
    assert np.max(np.abs(x[:, 1])) <= TOL
    tail = run(np.linspace(25 * np.pi, 100.0, 50))
    assert np.max(np.abs(tail)) <= TOL
    assert [m for _, m in run.modes][-2:] == [(-1,), (0,)]  # the last arc, from p_24 = 0.2, moves down; then it sticks


def test_statement_returns_none_for_what_it_cannot_state():
    assert statement(qdframe.load_model("paper-7.2")) is None
    for name in ("coulomb-rest-to-rest", "sliding-mode-terminal"):  # an unknown input: nothing to integrate
        assert statement(qdframe.load_model(name)) is None
        assert reference(qdframe.load_model(name)) is None
    assert statement(Paper73(x0=(-1.0, 1.0, -1.0, 0.0, 1.0, 1.0))) is None


def _bang_bang_by_hand(t: np.ndarray) -> np.ndarray:
    """u = 2 then −2 at t = 1, F = 1, from rest: v' = 1 (v = t) to t = 1; v' = −3 until v = 0 at 4/3,
    p = 2/3; then |u| > F: it reverses, v' = −1: v = −(t − 4/3), p = 2/3 − (t − 4/3)²/2."""
    s, r = t - 1.0, t - 4.0 / 3.0
    p = np.where(t < 1, t**2 / 2, np.where(t < 4 / 3, 0.5 + s - 1.5 * s**2, 2 / 3 - r**2 / 2))
    v = np.where(t < 1, t, np.where(t < 4 / 3, 1 - 3 * s, -r))
    return np.stack([p, v], axis=1)


class BangBang:
    """u(t) = 2 for t < 1, −2 after; `breaks` tells the integrator where it jumps."""

    breaks = (1.0,)

    def __call__(self, t: float) -> float:
        return 2.0 if t < 1.0 else -2.0


@pytest.mark.parametrize("force, tol", [(BangBang(), 1e-13), (lambda t: 2.0 if t < 1.0 else -2.0, TOL)],
                         ids=["with-breaks", "without-breaks"])
def test_coulomb_rest_to_rest_under_a_bang_bang_force(force, tol):
    run = reference(qdframe.load_model("coulomb-rest-to-rest"), force)
    t = np.array([0.25, 0.5, 1.0, 1.2, 4 / 3, 1.5, 2.0])
    assert np.max(np.abs(run(t) - _bang_bang_by_hand(t))) <= tol
    assert run(np.array([2.0]))[0] == pytest.approx([4 / 9, -2 / 3], abs=tol)  # p(2) = 2/3 − 2/9
    assert run.switch_times == pytest.approx([4 / 3], abs=tol)
    assert [m for _, m in run.modes] == [(1,), (-1,)]  # the start is a release, the stop at 4/3 a reversal


def test_sliding_mode_terminal_with_zero_input_by_hand():
    """w = 0 keeps v = 0: x1' = −1, x2' = −1 until c2 = x2 − 0.05·x1³ = 0; then sliding on c2 = 0
    with x1' = −1 (x2 = 0.05·x1³) until x1 = 0 at 2π/3, then at rest on both surfaces."""
    model = qdframe.load_model("sliding-mode-terminal")
    run = reference(model, lambda t: np.zeros(2))
    x10, x20 = model.x0[:2]
    reach = brentq(lambda t: (x20 - t) - 0.05 * (x10 - t) ** 3, 0.0, 2.0, xtol=1e-15)
    assert run.switch_times == pytest.approx([reach, x10], abs=TOL)
    t = np.linspace(0.0, model.T, 801)
    x1 = np.maximum(x10 - t, 0.0)
    x2 = np.where(t < reach, x20 - t, 0.05 * x1**3)
    assert np.max(np.abs(run(t)[:, :2] - np.stack([x1, x2], axis=1))) <= TOL
    assert np.max(np.abs(run(t)[:, 2:])) == 0.0


def test_paper_73_slides_on_x4_under_an_input():
    """From x4 = 0 with x4's base force 3 below the gain 1.05·|x|_1 = 5.25: sliding on x4 = 0."""
    model = Paper73(x0=(-1.0, 1.0, -1.0, 0.0, 1.0, 1.0))
    run = reference(model, lambda t: np.sin(3 * t))
    assert run.modes[0][1][0] == 0
    sliding_until = next((t for t, m in run.modes if m[0] != 0), model.T)
    t = np.linspace(0.0, sliding_until, 200)
    assert np.max(np.abs(run(t)[:, 3])) <= 1e-12


def test_a_nonfinite_start_is_a_clear_error():
    system = statement(FRICTION_MODELS["block-stop-stick"]())
    assert isinstance(system, FilippovSystem)
    with pytest.raises(FilippovError, match="finite"):
        integrate(system, [np.nan, 2.0], 1.0)
