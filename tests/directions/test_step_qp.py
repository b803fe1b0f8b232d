"""directions/step_qp.py: gauss-newton's step QP on every offered backend gives the default's
result; a raw backend step is held to the KKT conditions; bad names are one-line errors."""

import json

import numpy as np
import pytest
import scipy.sparse as sp

import qdframe
from qdframe.cli import main
from qdframe.registry import make_direction
from qdframe.directions.base import with_options
from qdframe.directions.step_qp import SparseQP, make_step_qp, step_qp_names
from qdframe.errors import InputError

BACKENDS = [name for name in step_qp_names() if name != "active-set"]


def gauss_newton(**options):
    return with_options(make_direction("gauss-newton"), {key: str(value) for key, value in options.items()})


def fixed_grid(model, direction="gauss-newton"):
    """A fixed grid from the model's own start (no simulated motion): every step is a QP step."""
    return qdframe.solve(model, nodes=41, direction=direction, simulate_start=False, estimate=False)


@pytest.fixture(scope="module")
def defaults():
    return {model: fixed_grid(model) for model in ("paper-7.1", "block-stop-stick-bvp", "slide-after-reaching")}


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("model", ["paper-7.1", "block-stop-stick-bvp", "slide-after-reaching"])
def test_every_backend_gives_the_default_result(backend, model, defaults):
    """7.1's hinges and cost max-groups, and the sign terms' natural map of two friction models."""
    reference = defaults[model]
    result = fixed_grid(model, gauss_newton(qp=backend))
    assert reference.status == result.status == "uncertified"  # the discrete problem solved, no estimate asked
    assert "discrete problem is solved" in result.message
    assert np.max(np.abs(result.x - reference.x)) <= 1e-8


@pytest.mark.parametrize("backend", ["clarabel", "osqp", "cvxpy"])
def test_raw_steps_without_the_polish_solve_paper_71(backend, defaults):
    result = fixed_grid("paper-7.1", gauss_newton(qp=backend, qp_polish=False))
    assert "discrete problem is solved" in result.message
    assert np.max(np.abs(result.x - defaults["paper-7.1"].x)) <= 1e-8


def test_the_default_call_with_a_backend_is_certified():
    result = qdframe.solve("paper-7.1", direction=gauss_newton(qp="osqp"))
    assert result.status == "solved" and result.solution_error <= 1e-6


def small_qp():
    """min ½(v1² + v2²) − v1 − v2 s.t. v1 − v2 = 0, v1 ≤ 0.5: v = (0.5, 0.5), y = −0.5, z = 1."""
    return SparseQP(P=sp.identity(2, format="csc"), q=np.array([-1.0, -1.0]), A=sp.csc_matrix([[1.0, -1.0]]),
                    b=np.zeros(1), G=sp.csc_matrix([[1.0, 0.0]]), h=np.array([0.5]))


def test_kkt_error_is_zero_at_the_solution_and_not_elsewhere():
    qp = small_qp()
    v, y, z = np.array([0.5, 0.5]), np.array([-0.5]), np.array([1.0])
    assert qp.kkt_error(v, y, z) <= 1e-15
    assert qp.kkt_error(np.array([0.6, 0.6]), y, z) > 1e-2  # infeasible and off stationarity
    assert qp.kkt_error(v, y, -z) > 1e-2  # a negative multiplier
    assert qp.kkt_error(np.array([np.nan, 0.5]), y, z) == np.inf


@pytest.mark.parametrize("backend", BACKENDS)
def test_each_backend_returns_a_kkt_point_of_a_small_qp(backend):
    qp = small_qp()
    solution = make_step_qp(backend).solve(qp)
    assert solution.solved, solution.status
    assert np.allclose(solution.v, [0.5, 0.5], atol=1e-6)
    assert qp.kkt_error(solution.v, solution.y, solution.z) <= 1e-6


def test_unknown_and_refused_backends_are_one_line_errors():
    with pytest.raises(InputError, match="qp=<a step-QP backend.*osqp"):
        gauss_newton(qp="osqq")
    with pytest.raises(InputError, match="qpsolvers:daqp.*dense"):
        make_step_qp("qpsolvers:daqp")


def test_list_shows_the_step_qp_backends(capsys):
    assert main(["list", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert {"active-set", "clarabel", "osqp", "cvxpy", "qpsolvers:"} <= {e["name"] for e in data["step_qps"]}


def test_option_errors_say_why_and_suggest():
    from qdframe.directions.gauss_newton import GaussNewton

    with pytest.raises(InputError, match="did you mean osqp"):
        GaussNewton(qp="OSQP")
    with pytest.raises(InputError, match="qpsolvers:daqp is not offered: a dense solver"):
        GaussNewton(qp="qpsolvers:daqp")
    with pytest.raises(InputError, match="qp_polish: expected True or False"):
        GaussNewton(qp_polish="false")


def test_a_backend_instance_of_ones_own_and_the_result_names_it():
    from qdframe.directions.gauss_newton import GaussNewton
    from qdframe.directions.step_qp import ClarabelStep

    class Counting(ClarabelStep):
        calls = 0

        def solve(self, qp, warm=None):
            Counting.calls += 1
            return super().solve(qp, warm)

    result = qdframe.solve("paper-7.1", nodes=41, direction=GaussNewton(qp=Counting("counting")), estimate=False,
                           simulate_start=False)
    assert Counting.calls == result.iterations >= 1 and "discrete problem is solved" in result.message
    assert result.direction == "gauss-newton[qp=counting]"
    assert qdframe.solve("paper-7.1", nodes=11, estimate=False).direction == "gauss-newton"
