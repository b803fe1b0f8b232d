"""Schemes (trapezoid, implicit Euler, Radau IIA) and boundary conditions as users pose
them (free start entries, any subset of end values, periodic components)."""

from __future__ import annotations

import numpy as np
import pytest

import qdframe
from qdframe.cli import main
from qdframe.errors import InputError
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.sets import Interval, SetModel, Sgn
from qdframe.registry import lookup

SCHEMES = ("trapezoid", "implicit-euler", "radau-iia")


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("nodes", [3, 5, 21])
def test_cumulative_adjoint_is_the_transpose(scheme, nodes):
    grid = Grid(2.0, nodes, scheme)
    dense = np.column_stack([grid.cumulative(np.eye(nodes)[:, j]) for j in range(nodes)])
    y = np.random.default_rng(nodes).standard_normal((nodes, 3))
    np.testing.assert_allclose(grid.cumulative_adjoint(y), dense.T @ y, atol=1e-14)
    np.testing.assert_allclose(grid.integral_weights, dense[-1], atol=1e-15)
    assert np.all(grid.weights > 0) and grid.t[0] == 0.0 and grid.t[-1] == 2.0


@pytest.mark.parametrize("scheme, order", [("trapezoid", 2), ("implicit-euler", 1), ("radau-iia", 3)])
def test_the_integral_of_cos_converges_at_the_schemes_order(scheme, order):
    errors = []
    for nodes in (41, 81):
        grid = Grid(1.0, nodes, scheme)
        errors.append(np.max(np.abs(grid.cumulative(np.cos(grid.t)) - np.sin(grid.t))))
    assert np.log2(errors[0] / errors[1]) == pytest.approx(order, abs=0.1)


def test_radau_needs_an_odd_number_of_points():
    with pytest.raises(InputError, match="odd"):
        Grid(1.0, 10, "radau-iia")
    with pytest.raises(InputError, match="scheme"):
        Grid(1.0, 10, "nope")


class Block(SetModel):
    """v' ∈ 1 − 3·Sgn(v): a free p(0), p(3) = 1."""

    state_names = "p v"
    default_T = 3.0
    default_x0 = (float("nan"), 2.0)
    default_xT = {"p": 1.0}

    def sets(self, p, v):
        return {p: v, v: 1 - 3 * Sgn(v)}


class Relaxing(SetModel):
    """x' ∈ −x + [−1, 1] with x(0) free and x(T) = x(0): every constant in [−1, 1] is a solution."""

    state_names = "a b"
    default_T = 2.0
    default_x0 = (float("nan"), 0.5)
    periodic = (0,)

    def sets(self, a, b):
        return {a: -a + Interval(-1, 1), b: -b + Interval(-1, 1)}


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("model", [Block(), Relaxing(), Block(end_values=[1.0, float("nan")], periodic=["v"])])
def test_directional_derivative_with_free_starts_and_periodic_ends(scheme, model):
    functional = Functional(model, Grid(model.T, 21, scheme))
    rng = np.random.default_rng(3)
    xi = functional.initial_point() + 0.3 * rng.standard_normal((21, functional.dim)) * functional.free
    assert functional.free[0, 0] and not functional.free[0, 1]  # p(0) / a(0) free, v(0) / b(0) given
    g = rng.standard_normal(xi.shape) * functional.free
    alpha = 1e-7
    fd = (functional.objective(xi + alpha * g) - functional.objective(xi)) / alpha
    qd = functional.quasidifferential(xi, 1e-3)
    assert qd.directional_derivative(g, functional.weights) == pytest.approx(fd, rel=1e-5, abs=1e-6)


def test_a_free_start_is_found():
    result = qdframe.solve(Block(), nodes=1001)
    assert result.converged and abs(result.x[-1, 0] - 1.0) <= 1e-8
    assert abs(result.x[0, 0]) <= 4e-3 and result.x[0, 1] == 2.0  # p(0) = 0 to O(h)


def test_periodic_components_close():
    result = qdframe.solve(Relaxing(), nodes=101)
    assert result.status == "solved"
    assert abs(result.x[-1, 0] - result.x[0, 0]) <= 1e-8 and result.x[0, 1] == 0.5
    assert result.boundary_error <= 1e-8


def test_boundary_options_on_the_command_line(capsys):
    # a fixed grid of 1001 points: the discrete problem solved, its error above 1e-6 (exit 3: uncertified)
    assert main(["solve", "coulomb-block", "--x0=free,3", "--xT=3,free", "--nodes", "1001", "--quiet",
                 "--json", "/dev/null"]) == 3
    assert main(["solve", "coulomb-block", "--x0=free,3", "--xT=3,free", "--quiet", "--json", "/dev/null"]) == 0
    assert main(["solve", "coulomb-block", "--x0=free,inf"]) == 2
    assert "free" in capsys.readouterr().err
    assert main(["solve", "coulomb-block", "--periodic", "nope"]) == 2
    assert "periodic" in capsys.readouterr().err


def test_band_and_exact_agree_off_the_switch():
    """Where |s| ≥ band the band's set is the point a·sign(s), and so is the exact one with
    λ = sign(s) (which its natural map holds: σ = 0): the same sets, distances and I."""
    model = qdframe.load_model("slide-on-line", x0=[1.0, 0.5])  # s = x1 + x2 > 0 from the start
    grid = Grid(model.T, 11, model.default_scheme)
    exact, band = Functional(model, grid), Functional(model, grid, signs="band")
    rng = np.random.default_rng(4)
    t = grid.t[:, None]
    x = np.hstack([1.0 + t, 0.5 + 0.1 * t]) * np.where(rng.random((11, 1)) < 0.5, 1.0, -1.0)  # |x1 + x2| ≥ 1.5
    z = rng.normal(size=(11, 2))
    on_exact, on_band = exact.pack(x, z), band.pack(x, z)  # λ = clip(s/band) = sign(s) here
    s = -(on_exact[:, 0] + on_exact[:, 1])  # the term's switch −x1 − x2
    assert np.min(np.abs(s)) >= 1.0 and np.array_equal(exact.selections(on_exact)[:, 0], np.sign(s))
    for (lo_e, hi_e), (lo_b, hi_b) in zip(exact.set_bounds(on_exact), band.set_bounds(on_band)):
        assert np.array_equal(lo_e, hi_e) and np.array_equal(lo_b, hi_b)  # a point each
        assert np.array_equal(lo_e, lo_b)
    terms_exact, terms_band = exact.terms(on_exact), band.terms(on_band)
    assert terms_exact.sigma == 0.0 and terms_exact.phi > 0.1
    assert terms_exact.phi == pytest.approx(terms_band.phi, rel=1e-14)
    assert terms_exact.I == pytest.approx(terms_band.I, rel=1e-14)


@pytest.mark.parametrize("name", ["trapezoid", "implicit-euler", "radau-iia"])
def test_the_schemes_velocity_is_the_derivative_its_rule_integrates(name):
    """Scheme.velocity is x' of the rule: integrating it over a mesh interval gives the rule's
    own increment x_{k+1} − x_k, for every scheme, on a nonuniform mesh."""
    from qdframe.schemes.grid import Grid

    scheme = lookup("schemes", name).obj()
    grid = Grid.from_mesh(np.array([0.0, 0.1, 0.35, 0.5, 1.0]), scheme)
    z = np.sin(3 * grid.t)[:, None] + np.cos(7 * grid.t)[:, None] ** 2
    increments = grid.cumulative(z)  # Z_p, the rule's ∫_0^{t_p} z
    mesh = np.arange(0, grid.t.size, scheme.stages)
    for k in range(mesh.size - 1):
        a, b = grid.t[mesh[k]], grid.t[mesh[k + 1]]
        s, w = np.polynomial.legendre.leggauss(4)
        times = 0.5 * (b - a) * s + 0.5 * (a + b)
        integral = 0.5 * (b - a) * w @ scheme.velocity(grid.t, mesh, z, times)[:, 0]
        assert integral == pytest.approx(increments[mesh[k + 1], 0] - increments[mesh[k], 0], abs=1e-13)
