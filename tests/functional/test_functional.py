"""Functional: terms, residuals and the quasidifferential, checked against independent
computations (dense trapezoid matrices, closed-form distances, scipy, finite differences)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import qdframe
from qdframe import Cost, InclusionModel, MaxGroup, MinGroup, SetBlock, Surface
from qdframe.errors import ModelOutputError
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid

TINY_DELTA = 1e-12


# ====================================================================== test models


def _wide_1d(x):
    """F = [−100, 100]: co of the two constant points ±100 (so h ≡ 0 for |z| < 100)."""
    nodes, n = x.shape
    f = np.zeros((nodes, 2, 1))
    f[:, 0, 0], f[:, 1, 0] = -100.0, 100.0
    return f, np.zeros((nodes, 2, 1, n))


def _wide_square(x):
    """F = [−100, 100]² as co of its four corners (a 2-coordinate block)."""
    nodes, n = x.shape
    corners = np.array([[-100.0, -100.0], [-100.0, 100.0], [100.0, -100.0], [100.0, 100.0]])
    return np.broadcast_to(corners, (nodes, 4, 2)).copy(), np.zeros((nodes, 4, 2, n))


def _wide_surface(x):
    a, b, c = x[:, 0], x[:, 1], x[:, 2]
    e = np.stack([a**2 + b * c - 1.0, np.sin(a) + c**3], axis=1)
    de = np.zeros((x.shape[0], 2, 3))
    de[:, 0, 0], de[:, 0, 1], de[:, 0, 2] = 2 * a, c, b
    de[:, 1, 0], de[:, 1, 2] = np.cos(a), 3 * c**2
    return e, de


class WideModel(InclusionModel):
    """Sets so wide that φ ≡ 0: I = χ + ω + υ is smooth."""

    name = "test-wide"
    state_names = ("a", "b", "c")
    default_T = 1.7
    default_x0 = (0.3, -0.4, 0.2)
    end_indices = (0, 2)
    default_end_values = (0.5, -0.2)

    def blocks(self):
        return (
            SetBlock((0,), max_groups=(MaxGroup(_wide_1d, "wide"),), name="A"),
            SetBlock((1, 2), max_groups=(MaxGroup(_wide_square, "square"),), name="BC"),
        )

    def surface(self):
        return Surface(_wide_surface)


def _three_pieces(x):
    """co{x1 + x2, x1² − 0.5, sin x2 + 0.3} (1-D)."""
    x1, x2 = x[:, 0], x[:, 1]
    f = np.stack([x1 + x2, x1**2 - 0.5, np.sin(x2) + 0.3], axis=1)[:, :, None]
    jac = np.zeros((x.shape[0], 3, 1, 2))
    jac[:, 0, 0, 0], jac[:, 0, 0, 1] = 1.0, 1.0
    jac[:, 1, 0, 0] = 2 * x1
    jac[:, 2, 0, 1] = np.cos(x2)
    return f, jac


def _three_values(x):
    x1, x2 = x[:, 0], x[:, 1]
    return np.stack([x1 + x2, x1**2 - 0.5, np.sin(x2) + 0.3], axis=1)


def _radius_pieces(x, psi):
    """min{0.2 + 0.1 x2², 0.5} for both ψ = ±1: a symmetric interval of that radius."""
    x2 = x[:, 1]
    g = np.stack([0.2 + 0.1 * x2**2, np.full_like(x2, 0.5)], axis=1)
    grad = np.zeros((x.shape[0], 2, 2))
    grad[:, 0, 1] = 0.2 * x2
    return g, grad


def _radius_values(x):
    return np.minimum(0.2 + 0.1 * x[:, 1] ** 2, 0.5)


def _equation_rhs(x):
    x1, x2 = x[:, 0], x[:, 1]
    grad = np.stack([x2 - np.sin(x1), x1], axis=1)
    return x1 * x2 + np.cos(x1), grad


class MaxModel(InclusionModel):
    """x1' ∈ co{f_q(x)} + [−r(x), r(x)], x2' = x1 x2 + cos x1, x2(T) = 0.7."""

    name = "test-max"
    state_names = ("x1", "x2")
    default_T = 1.3
    default_x0 = (0.1, -0.2)
    end_indices = (1,)
    default_end_values = (0.7,)

    def blocks(self):
        return (
            SetBlock((0,), max_groups=(MaxGroup(_three_pieces, "three"),),
                     min_groups=(MinGroup(_radius_pieces, "radius"),), name="F1"),
            SetBlock.equation(1, _equation_rhs, name="F2"),
        )


def _cost_max(x):
    x1, x2 = x[:, 0], x[:, 1]
    grads = np.zeros((x.shape[0], 2, 2))
    grads[:, 0, 0] = 2 * x1
    grads[:, 1, 1] = 1.0
    return np.stack([x1**2, 0.5 + x2], axis=1), grads


def _cost_min(x):
    x1, x2 = x[:, 0], x[:, 1]
    grads = np.zeros((x.shape[0], 2, 2))
    grads[:, 0, 1] = 2 * x2
    grads[:, 1, 0] = 1.0
    return np.stack([x2**2, 1.0 + x1], axis=1), grads


class MaxModelWithCost(MaxModel):
    """MaxModel plus the cost ∫ max{x1², ½ + x2} + min{x2², 1 + x1}, λ = 3."""

    name = "test-max-cost"

    def cost(self):
        return Cost(max_groups=(_cost_max,), min_groups=(_cost_min,), weight=3.0)


def _cost_integrand_values(x):
    return _cost_max(x)[0].max(axis=1) + _cost_min(x)[0].min(axis=1)


def _triangle(x):
    """co{f_0, f_1, f_2} ⊂ R², a counter-clockwise triangle moving with x (|x| ≲ 1)."""
    x1, x2 = x[:, 0], x[:, 1]
    f = np.zeros((x.shape[0], 3, 2))
    jac = np.zeros((x.shape[0], 3, 2, 2))
    f[:, 0, 0], f[:, 0, 1] = 1.0 + 0.3 * x1, 0.2 * x2
    jac[:, 0, 0, 0], jac[:, 0, 1, 1] = 0.3, 0.2
    f[:, 1, 0], f[:, 1, 1] = -0.5, 1.0 + 0.5 * np.sin(x2)
    jac[:, 1, 1, 1] = 0.5 * np.cos(x2)
    f[:, 2, 0], f[:, 2, 1] = -1.0 - 0.2 * x1**2, -0.8 + 0.3 * x2
    jac[:, 2, 0, 0], jac[:, 2, 1, 1] = -0.4 * x1, 0.3
    return f, jac


def _disc_radius(x):
    return 0.3 + 0.1 * x[:, 0] ** 2


def _disc_pieces(x, psi):
    """c(disc of radius r(x), ψ) = r(x) |ψ|: one piece."""
    norm = np.linalg.norm(psi, axis=1)
    grad = np.zeros((x.shape[0], 1, 2))
    grad[:, 0, 0] = 0.2 * x[:, 0] * norm
    return (_disc_radius(x) * norm)[:, None], grad


class TriangleModel(InclusionModel):
    """x' ∈ co{f_0(x), f_1(x), f_2(x)} + disc(r(x)): a 2-coordinate block (ψ ∈ S_1) with a
    max-group of three pieces and a min-group; x(T) = (0.4, −0.1)."""

    name = "test-triangle"
    state_names = ("x1", "x2")
    default_T = 0.8
    default_x0 = (0.2, -0.1)
    end_indices = (0, 1)
    default_end_values = (0.4, -0.1)

    def blocks(self):
        return (SetBlock((0, 1), max_groups=(MaxGroup(_triangle, "triangle"),),
                         min_groups=(MinGroup(_disc_pieces, "disc"),), name="T"),)


# ============================================================ independent computations


def dense_cumulative(nodes: int, T: float) -> np.ndarray:
    h = T / (nodes - 1)
    C = np.zeros((nodes, nodes))
    for k in range(nodes):
        for m in range(k):
            C[k, m] += h / 2
            C[k, m + 1] += h / 2
    return C


def trapezoid_weights(nodes: int, T: float) -> np.ndarray:
    h = T / (nodes - 1)
    return np.array([h / 2 if k in (0, nodes - 1) else h for k in range(nodes)])


def interval_excess(z, lo, hi):
    """max(0, z − hi, lo − z): the distance from z to [lo, hi] (lo ≤ hi)."""
    return np.maximum(0.0, np.maximum(z - hi, lo - z))


def paper71_h(x, z):
    """Per-block h for Example 7.1 from the intervals themselves."""
    x1, x2 = x[:, 0], x[:, 1]
    lo = np.maximum(np.minimum(x1, x2), x2 - 1.0)  # [x1, x2] ∩ [x2 − 1, x2 + 1]
    hi = np.minimum(np.maximum(x1, x2), x2 + 1.0)
    return [interval_excess(z[:, 0], lo, hi), np.abs(z[:, 1] - x1 - 1.0)]


def maxmodel_h(x, z):
    f = _three_values(x)
    r = _radius_values(x)
    h1 = interval_excess(z[:, 0], f.min(axis=1) - r, f.max(axis=1) + r)
    h2 = np.abs(z[:, 1] - _equation_rhs(x)[0])
    return [h1, h2]


def ellipse_distance(z, x1):
    """Distance from z to {(a, b): (a − 2)²/(x1² + 3) + b² ≤ 1} by scipy on the boundary angle."""
    a_axis = np.sqrt(x1**2 + 3.0)
    if (z[0] - 2.0) ** 2 / a_axis**2 + z[1] ** 2 <= 1.0:
        return 0.0

    def d2(theta):
        return (z[0] - 2.0 - a_axis * np.cos(theta)) ** 2 + (z[1] - np.sin(theta)) ** 2

    thetas = np.linspace(0.0, 2 * np.pi, 721)
    best = thetas[np.argmin(d2(thetas))]
    step = thetas[1] - thetas[0]
    res = minimize_scalar(d2, bounds=(best - step, best + step), method="bounded",
                          options={"xatol": 1e-12})
    return float(np.sqrt(min(res.fun, d2(best))))


def paper72_h(x, z):
    out = np.zeros(x.shape[0])
    for k in range(x.shape[0]):
        disc = max(0.0, float(np.hypot(z[k, 0], z[k, 1])) - 1.0)
        out[k] = max(disc, ellipse_distance(z[k], x[k, 0]))
    return [out]


def _segment_distance(p, a, b):
    t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return float(np.linalg.norm(p - a - t * (b - a)))


def triangle_h(x, z):
    """max(0, dist(z, triangle) − r): the triangle by vertices, inside test by orientation."""
    f = _triangle(x)[0]
    r = _disc_radius(x)
    out = np.zeros(x.shape[0])
    for k in range(x.shape[0]):
        v = f[k]
        cross = [(v[(i + 1) % 3] - v[i])[0] * (z[k] - v[i])[1] - (v[(i + 1) % 3] - v[i])[1] * (z[k] - v[i])[0]
                 for i in range(3)]
        if min(cross) >= 0.0:
            continue  # inside the counter-clockwise triangle
        d = min(_segment_distance(z[k], v[i], v[(i + 1) % 3]) for i in range(3))
        out[k] = max(0.0, d - r[k])
    return [out]


def wide_h(x, z):
    return [np.zeros(x.shape[0]), np.zeros(x.shape[0])]


def independent_terms(model, nodes, xi, h_blocks, cost_integrand=None):
    """φ, χ, ω, υ, cost, I, objective computed from scratch (dense C, explicit weights)."""
    n = model.n_states
    x, z = xi[:, :n], xi[:, n:]
    w = trapezoid_weights(nodes, model.T)
    C = dense_cumulative(nodes, model.T)
    hs = h_blocks(x, z)
    phi = 0.5 * sum(float(np.sum(w * h**2)) for h in hs)
    end = list(model.end_indices)
    chi = 0.5 * float(np.sum((model.x0[end] + w @ z[:, end] - model.end_values) ** 2))
    r = x - model.x0 - C @ z
    upsilon = 0.5 * float(np.sum(w[:, None] * r**2))
    surface = model.surface()
    omega = 0.0
    if surface is not None:
        e, _ = surface.function(x)
        omega = 0.5 * float(np.sum(w[:, None] * e**2))
    I = phi + chi + omega + upsilon
    cost = float(w @ cost_integrand(x)) if cost_integrand is not None else 0.0
    lam = model.cost().weight if cost_integrand is not None else 1.0
    objective = cost + lam * I if cost_integrand is not None else I
    return dict(phi=phi, chi=chi, omega=omega, upsilon=upsilon, cost=cost, I=I, objective=objective,
                hs=hs, r=r, end=model.x0[end] + w @ z[:, end] - model.end_values)


# ================================================================== random iterates


def random_xi(functional: Functional, seed: int, x_loc=0.0, x_scale=1.0, z_loc=0.0, z_scale=1.0):
    rng = np.random.default_rng(seed)
    nodes, n = functional.grid.nodes, functional.n
    x = np.asarray(x_loc) + x_scale * rng.standard_normal((nodes, n))
    z = np.asarray(z_loc) + z_scale * rng.standard_normal((nodes, n))
    xi = functional.pack(x, z)
    np.testing.assert_array_equal(xi[0, :n], functional.model.x0)
    return xi


def make(model_name_or_obj, nodes):
    model = qdframe.load_model(model_name_or_obj) if isinstance(model_name_or_obj, str) else model_name_or_obj
    return Functional(model, Grid(model.T, nodes))


# iterate generators per model: (model factory, random-point kwargs, independent h, cost integrand)
CASES = {
    "paper-7.1": (lambda: qdframe.load_model("paper-7.1"),
                  dict(x_scale=1.0, z_scale=1.5), paper71_h, lambda x: np.abs(x[:, 0])),
    "paper-7.2": (lambda: qdframe.load_model("paper-7.2"),
                  dict(x_scale=0.8, z_loc=(0.6, 0.0), z_scale=0.7), paper72_h, None),
    "test-max": (MaxModel, dict(x_scale=1.0, z_scale=2.0), maxmodel_h, None),
    "test-max-cost": (MaxModelWithCost, dict(x_scale=1.0, z_scale=2.0), maxmodel_h, _cost_integrand_values),
    "test-wide": (WideModel, dict(x_scale=0.7, z_scale=1.0), wide_h, None),
}


def one_sided_derivative(f, xi, g, alpha=1e-5):
    """Richardson-extrapolated one-sided difference quotient of f at xi along g."""
    f0 = f(xi)
    d1 = (f(xi + alpha * g) - f0) / alpha
    d2 = (f(xi + 0.5 * alpha * g) - f0) / (0.5 * alpha)
    return 2.0 * d2 - d1


# ========================================================================== tests: terms


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("nodes,seed", [(7, 1), (12, 2)])
def test_terms_against_independent_computation(case, nodes, seed):
    factory, kwargs, h_blocks, cost_integrand = CASES[case]
    model = factory()
    functional = make(model, nodes)
    xi = random_xi(functional, seed, **kwargs)
    terms = functional.terms(xi)
    ref = independent_terms(model, nodes, xi, h_blocks, cost_integrand)
    for name in ("phi", "chi", "omega", "upsilon", "cost", "I", "objective"):
        assert getattr(terms, name) == pytest.approx(ref[name], rel=1e-9, abs=1e-12), name
    assert functional.objective(xi) == terms.objective
    # the random iterate really exercises φ (except for the wide model)
    if case != "test-wide":
        assert ref["phi"] > 1e-2
        assert any(np.any(h == 0) for h in ref["hs"]) or case == "paper-7.1"
    else:
        assert terms.phi == 0.0 and ref["omega"] > 0.0

    res = functional.residuals(xi)
    # boundary_error reads x itself (χ's x0 + ∫z differs from it by the consistency at T)
    x = xi[:, : model.n_states]
    end = x[-1, list(model.end_indices)] - np.asarray(model.end_values)
    assert res.boundary_error == pytest.approx(float(np.max(np.abs(end))) if end.size else 0.0, rel=1e-12)
    assert res.inclusion_residual == pytest.approx(max(float(np.max(h)) for h in ref["hs"]), rel=1e-9, abs=1e-14)
    assert res.consistency_error == pytest.approx(float(np.max(np.abs(ref["r"]))), rel=1e-12)
    if model.surface() is None:
        assert res.surface_error is None
    else:
        e, _ = model.surface().function(xi[:, : model.n_states])
        assert res.surface_error == pytest.approx(float(np.max(np.abs(e))), rel=1e-12)


def test_paper72_phi_outside_both_sets_uses_the_larger_distance():
    """Nodes outside the disc and the ellipse, inside only one, and inside both."""
    functional = make("paper-7.2", 6)
    x = np.array([[0.0, 0.0], [0.5, 1.0], [-1.2, 0.3], [2.0, -1.0], [0.1, 0.1], [1.0, 2.0]])
    z = np.array([[0.75, 0.5], [0.0, 0.0], [3.5, 0.0], [-0.5, 1.5], [1.2, -0.9], [0.9, 0.0]])
    xi = functional.pack(x, z)
    hs = paper72_h(xi[:, :2], xi[:, 2:])[0]
    assert hs[0] == 0.0 and hs[-1] == 0.0  # inside both sets
    assert hs[1] > 0.0  # inside the disc, outside the ellipse
    assert hs[2] > 0.0  # inside the ellipse, outside the disc
    w = functional.weights
    assert functional.terms(xi).phi == pytest.approx(0.5 * float(w @ hs**2), rel=1e-9)
    assert functional.residuals(xi).inclusion_residual == pytest.approx(float(hs.max()), rel=1e-9)


@pytest.mark.parametrize("case", ["paper-7.1", "test-max"])
def test_set_bounds_are_the_intervals(case):
    factory, kwargs, _, _ = CASES[case]
    functional = make(factory(), 9)
    xi = random_xi(functional, 5, **kwargs)
    x = xi[:, :2]
    bounds = functional.set_bounds(xi)
    if case == "paper-7.1":
        lo = np.maximum(np.minimum(x[:, 0], x[:, 1]), x[:, 1] - 1.0)
        hi = np.minimum(np.maximum(x[:, 0], x[:, 1]), x[:, 1] + 1.0)
        f2 = x[:, 0] + 1.0
    else:
        f, r = _three_values(x), _radius_values(x)
        lo, hi = f.min(axis=1) - r, f.max(axis=1) + r
        f2 = _equation_rhs(x)[0]
    np.testing.assert_allclose(bounds[0][0], lo, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(bounds[0][1], hi, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(bounds[1][0], f2, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(bounds[1][1], f2, rtol=1e-12, atol=1e-14)


def test_set_bounds_none_for_sphere_block():
    functional = make("paper-7.2", 5)
    assert functional.set_bounds(functional.initial_point()) == [None]


# ============================================================== tests: known solutions


@pytest.mark.parametrize("nodes", [2, 7, 21])
def test_paper71_exact_solution_has_zero_functional(nodes):
    functional = make("paper-7.1", nodes)
    t = functional.grid.t
    x = functional.model.exact_solution(t)
    np.testing.assert_array_equal(x, np.stack([0 * t, t], axis=1))
    z = np.tile([0.0, 1.0], (nodes, 1))
    xi = functional.pack(x, z)
    terms = functional.terms(xi)
    for name in ("phi", "chi", "omega", "upsilon", "cost", "I", "objective"):
        assert abs(getattr(terms, name)) <= 1e-14, name
    res = functional.residuals(xi)
    assert res.boundary_error <= 1e-14
    assert res.inclusion_residual <= 1e-14
    assert res.consistency_error <= 1e-14
    assert res.surface_error is None
    # moving off the solution makes I positive
    z_off = z.copy()
    z_off[:, 1] += 0.1
    assert functional.terms(functional.pack(x, z_off)).I > 1e-4


@pytest.mark.parametrize("nodes", [2, 7, 21])
def test_paper72_exact_solution_has_zero_functional(nodes):
    functional = make("paper-7.2", nodes)
    t = functional.grid.t
    zc = np.array([0.75, 0.5])
    x = functional.model.x0 + t[:, None] * zc  # one solution of many (no exact_solution needed)
    xi = functional.pack(x, np.tile(zc, (nodes, 1)))
    terms = functional.terms(xi)
    for name in ("phi", "chi", "omega", "upsilon", "cost", "I", "objective"):
        assert abs(getattr(terms, name)) <= 1e-14, name
    res = functional.residuals(xi)
    assert res.boundary_error <= 1e-14
    assert res.inclusion_residual <= 1e-14
    assert res.consistency_error <= 1e-14
    # a z outside the disc gives φ > 0
    off = functional.pack(x, np.tile([1.2, 0.5], (nodes, 1)))
    assert functional.terms(off).phi > 1e-3


# ================================================================ tests: the gradient


def as_point(polytope) -> np.ndarray:
    """The single point of a polytope that is a singleton at every node (asserted): every
    active generator of a group coincides (e.g. several active pieces whose gradients
    were all projected to 0 on the fixed entries ξ[0, :n])."""
    point = polytope.center.copy()
    for group in range(polytope.generators.shape[1]):
        gens, mask = polytope.generators[:, group], polytope.mask[:, group]
        first = gens[:, 0]
        spread = np.where(mask[:, :, None], np.abs(gens - first[:, None, :]), 0.0)
        assert spread.max() == 0.0, "not a singleton"
        point += first
    return point


def fd_gradient(functional, f, xi, step=1e-6):
    """Central differences of f w.r.t. every free entry of ξ (fixed entries left 0)."""
    grad = np.zeros_like(xi)
    for k, j in zip(*np.nonzero(functional.free)):
        e = np.zeros_like(xi)
        e[k, j] = step
        grad[k, j] = (f(xi + e) - f(xi - e)) / (2 * step)
    return grad


@pytest.mark.parametrize("nodes", [7, 11])
def test_smooth_terms_gradient_matches_finite_differences(nodes):
    """φ ≡ 0 model: the quasidifferential is the point ∇(χ + υ + ω)/w_k."""
    functional = make(WideModel(), nodes)
    xi = random_xi(functional, 10 + nodes, x_scale=0.7)
    qd = functional.quasidifferential(xi, TINY_DELTA)
    assert qd.sub.generators.shape[1] == 0 and qd.sup.generators.shape[1] == 0
    np.testing.assert_array_equal(qd.sup.center, 0.0)
    assert functional.terms(xi).phi == 0.0
    fd = fd_gradient(functional, lambda v: functional.terms(v).I, xi)
    analytic = functional.weights[:, None] * qd.sub.center
    np.testing.assert_array_equal(analytic[~functional.free], 0.0)
    scale = np.max(np.abs(fd))
    assert scale > 1e-2
    np.testing.assert_allclose(analytic, fd, rtol=0, atol=1e-6 * scale)


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("nodes,seed", [(7, 21), (13, 22)])
def test_full_gradient_at_generic_points(case, nodes, seed):
    """At a generic point every group has one δ-active piece: A_k, B_k are points and
    w_k (A_k + B_k) is the gradient of the whole objective (φ, cost included)."""
    factory, kwargs, _, _ = CASES[case]
    functional = make(factory(), nodes)
    xi = random_xi(functional, seed, **kwargs)
    qd = functional.quasidifferential(xi, TINY_DELTA)
    analytic = functional.weights[:, None] * (as_point(qd.sub) + as_point(qd.sup))
    fd = fd_gradient(functional, functional.objective, xi)
    np.testing.assert_array_equal(analytic[~functional.free], 0.0)
    scale = np.max(np.abs(fd))
    assert scale > 1e-2
    np.testing.assert_allclose(analytic, fd, rtol=0, atol=1e-6 * scale)


# ====================================================== tests: directional derivative


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("nodes,seed", [(8, 31), (15, 32)])
def test_directional_derivative_at_generic_points(case, nodes, seed):
    factory, kwargs, _, _ = CASES[case]
    functional = make(factory(), nodes)
    xi = random_xi(functional, seed, **kwargs)
    qd = functional.quasidifferential(xi, TINY_DELTA)
    rng = np.random.default_rng(seed + 1000)
    for _ in range(3):
        g = rng.standard_normal(xi.shape) * functional.free
        predicted = qd.directional_derivative(g, functional.weights)
        measured = one_sided_derivative(functional.objective, xi, g)
        assert predicted == pytest.approx(measured, rel=1e-5, abs=1e-8)


def test_directional_derivative_ignores_fixed_entries():
    """ξ[0, :n] is fixed: a direction moving only it has derivative 0."""
    functional = make(MaxModelWithCost(), 9)
    xi = random_xi(functional, 40, z_scale=2.0)
    qd = functional.quasidifferential(xi, TINY_DELTA)
    g = np.zeros_like(xi)
    g[0, :2] = [1.0, -2.0]
    assert qd.directional_derivative(g, functional.weights) == 0.0


# The ties below are off by ~1e-14 on purpose: only δ-activity (δ = 1e-12), not exact
# floating-point equality, makes both pieces active.
TIE_OFFSET = 2e-14


def _max_model_tie_point(functional):
    """Nodes 1-3: two max pieces tie at the top (z above), nodes 4-5: two tie at the
    bottom (z below), node 6: the min-group's two pieces tie; with a cost also node 7:
    the cost max-group ties, node 8: the cost min-group ties. Other nodes generic."""
    nodes = functional.grid.nodes
    rng = np.random.default_rng(77)
    x = rng.standard_normal((nodes, 2))
    z = 2.0 * rng.standard_normal((nodes, 2))
    for k in (1, 2, 3):  # x1 + x2 = x1² − 0.5 > sin x2 + 0.3, z1 above
        x[k, 0] = 2.0 + 0.1 * k
        x[k, 1] = x[k, 0] ** 2 - 0.5 - x[k, 0] + (-1) ** k * TIE_OFFSET
        z[k, 0] = x[k, 0] ** 2 - 0.5 + 1.0 + 0.3 * k
    for k in (4, 5):  # x1 + x2 = sin x2 + 0.3 < x1² − 0.5, z1 below
        x[k, 1] = -1.0 - 0.05 * k
        x[k, 0] = np.sin(x[k, 1]) + 0.3 - x[k, 1] + (-1) ** k * TIE_OFFSET
        z[k, 0] = -3.0 - 0.1 * k
    x[6] = [-0.3, np.sqrt(3.0) + TIE_OFFSET]  # 0.2 + 0.1 x2² = 0.5
    z[6, 0] = 3.0
    ties = [1, 2, 3, 4, 5, 6]
    if functional.cost is not None:
        x[7] = [1.3, 1.3**2 - 0.5 + TIE_OFFSET]  # x1² = ½ + x2
        x[8] = [1.5**2 - 1.0 - TIE_OFFSET, -1.5]  # x2² = 1 + x1
        ties += [7, 8]
    return functional.pack(x, z), ties


def _paper71_tie_point(functional):
    """Nodes 1-2: cost |x1| at x1 ≈ 0; nodes 3-4: hull and band tie (x1 = x2 + 1, z1 above)."""
    nodes = functional.grid.nodes
    rng = np.random.default_rng(78)
    x = rng.standard_normal((nodes, 2))
    z = 1.5 * rng.standard_normal((nodes, 2))
    x[1, 0], x[2, 0] = TIE_OFFSET, -TIE_OFFSET
    for k in (3, 4):
        x[k, 1] = 0.3 * k - 1.0
        x[k, 0] = x[k, 1] + 1.0 + (-1) ** k * TIE_OFFSET
        z[k, 0] = x[k, 0] + 0.5 + 0.2 * k
    return functional.pack(x, z), [1, 2, 3, 4]


@pytest.mark.parametrize("case", ["test-max", "test-max-cost", "paper-7.1"])
def test_directional_derivative_at_nonsmooth_points(case):
    factory = CASES[case][0]
    functional = make(factory(), 10)
    tie = _paper71_tie_point if case == "paper-7.1" else _max_model_tie_point
    xi, tie_nodes = tie(functional)
    qd = functional.quasidifferential(xi, TINY_DELTA)
    # both tied pieces are δ-active: some group keeps two distinct generators at every
    # tie node (and only there)
    both = np.zeros(functional.grid.nodes, dtype=bool)
    for polytope in (qd.sub, qd.sup):
        for group in range(polytope.generators.shape[1]):
            gens, mask = polytope.generators[:, group], polytope.mask[:, group]
            spread = np.where(mask[:, :, None], np.abs(gens - gens[:, :1]), 0.0)
            both |= spread.max(axis=(1, 2)) > 1e-8
    assert both[tie_nodes].all()
    assert not both[[k for k in range(functional.grid.nodes) if k not in tie_nodes]].any()

    rng = np.random.default_rng(99)
    for _ in range(4):
        for k in tie_nodes:  # one node at a time: a kink that shows up in the derivative
            g = np.zeros_like(xi)
            g[k] = rng.standard_normal(xi.shape[1])
            g *= functional.free
            plus = one_sided_derivative(functional.objective, xi, g)
            minus = one_sided_derivative(functional.objective, xi, -g)
            assert qd.directional_derivative(g, functional.weights) == pytest.approx(plus, rel=1e-5, abs=1e-8)
            assert qd.directional_derivative(-g, functional.weights) == pytest.approx(minus, rel=1e-5, abs=1e-8)
        g = rng.standard_normal(xi.shape) * functional.free  # and all nodes together
        predicted = qd.directional_derivative(g, functional.weights)
        assert predicted == pytest.approx(one_sided_derivative(functional.objective, xi, g), rel=1e-5, abs=1e-8)


@pytest.mark.parametrize("case", ["test-max", "test-max-cost", "paper-7.1"])
def test_nonsmooth_points_are_really_kinks(case):
    """Guard for the test above: along ±g the one-sided derivatives do not cancel."""
    factory = CASES[case][0]
    functional = make(factory(), 10)
    tie = _paper71_tie_point if case == "paper-7.1" else _max_model_tie_point
    xi, tie_nodes = tie(functional)
    rng = np.random.default_rng(5)
    kinks = 0
    for k in tie_nodes:
        g = np.zeros_like(xi)
        g[k, : functional.n] = rng.standard_normal(functional.n)
        gap = one_sided_derivative(functional.objective, xi, g) + one_sided_derivative(functional.objective, xi, -g)
        kinks += abs(gap) > 1e-4  # < 0 at a concave kink (max pieces), > 0 at a convex one
    assert kinks == len(tie_nodes)


# ============================================================ tests: model output checks


class NaNPieceModel(InclusionModel):
    name = "test-nan-piece"
    state_names = ("x1", "x2")
    default_x0 = (0.0, 0.0)

    bad_node = 3
    where = "value"

    def blocks(self):
        model = self

        def spiky(x):
            f, jac = _three_pieces(x)
            target = jac if model.where == "jacobian" else f
            target[model.bad_node, 1, 0, ...] = np.nan
            return f, jac

        return (SetBlock((0,), max_groups=(MaxGroup(spiky, "spiky"),), name="F1"),
                SetBlock.equation(1, _equation_rhs, name="F2"))


class NaNMinGroupSphereModel(InclusionModel):
    name = "test-nan-sphere"
    state_names = ("x1", "x2")
    default_x0 = (0.0, 0.0)

    def blocks(self):
        def broken(x, psi):
            g = np.stack([np.sqrt(np.sum(psi**2, axis=1)), np.full(x.shape[0], 2.0)], axis=1)
            g[x[:, 0] > 5.0, 1] = np.inf  # x1 is set > 5 only at node 2
            return g, np.zeros((x.shape[0], 2, 2))

        return (SetBlock((0, 1), min_groups=(MinGroup(broken, "broken-disc"),), name="S"),)


class WrongShapeModel(InclusionModel):
    name = "test-wrong-shape"
    state_names = ("x1", "x2")
    default_x0 = (0.0, 0.0)
    mode = "values"

    def blocks(self):
        model = self

        def misshapen(x):
            f, jac = _three_pieces(x)
            if model.mode == "values":
                return f[:, :, 0], jac  # (N, 3) instead of (N, 3, 1)
            if model.mode == "jacobian":
                return f, jac[:, :, :, :1]  # (N, 3, 1, 1) instead of (N, 3, 1, 2)
            return f, jac  # Jacobian (N, 3, 1, 1) instead of (N, 3, 1, 2)

        def radius(x, psi):
            g, grad = _radius_pieces(x, psi)
            return (g[:, 0], grad) if model.mode == "min" else (g, grad)

        return (SetBlock((0,), max_groups=(MaxGroup(misshapen, "misshapen"),),
                         min_groups=(MinGroup(radius, "radius"),), name="F1"),
                SetBlock.equation(1, _equation_rhs, name="F2"))


def _evaluators(functional, xi):
    return [lambda: functional.terms(xi), lambda: functional.quasidifferential(xi, 1e-3),
            lambda: functional.residuals(xi)]


@pytest.mark.parametrize("where,label", [("value", "max-group 'spiky' returned"),
                                         ("jacobian", "max-group 'spiky' Jacobian returned")])
def test_nan_piece_names_model_piece_and_node(where, label):
    model = NaNPieceModel()
    model.where = where
    functional = make(model, 9)
    xi = functional.initial_point()
    for evaluate in _evaluators(functional, xi):
        with pytest.raises(ModelOutputError) as info:
            evaluate()
        message = str(info.value)
        assert "'test-nan-piece'" in message
        assert label in message
        assert "node 3" in message
        assert "t = 0.375" in message


def test_nan_node_is_the_first_bad_node():
    model = NaNPieceModel()
    model.bad_node = 6
    functional = make(model, 9)
    with pytest.raises(ModelOutputError, match=r"non-finite value at node 6\b"):
        functional.terms(functional.initial_point())


def test_infinite_min_group_in_sphere_block_is_reported():
    functional = make(NaNMinGroupSphereModel(), 6)
    x = np.zeros((6, 2))
    x[2, 0] = 7.0
    xi = functional.pack(x, np.zeros((6, 2)))
    with pytest.raises(ModelOutputError) as info:
        functional.terms(xi)
    message = str(info.value)
    assert "'test-nan-sphere'" in message and "'broken-disc'" in message and "node 2" in message


@pytest.mark.parametrize("mode,fragment", [
    ("values", "max-group 'misshapen' returned shape (9, 3), expected (9, *, 1)"),
    ("jacobian", "max-group 'misshapen' Jacobian returned shape (9, 3, 1, 1), expected (9, 3, 1, 2)"),
    ("min", "min-group 'radius' returned shape (9,), expected (9, *)"),
])
def test_wrong_shape_names_expected_shape(mode, fragment):
    model = WrongShapeModel()
    model.mode = mode
    functional = make(model, 9)
    xi = functional.initial_point()
    for evaluate in _evaluators(functional, xi):
        with pytest.raises(ModelOutputError) as info:
            evaluate()
        assert "'test-wrong-shape'" in str(info.value)
        assert fragment in str(info.value)


def test_nan_surface_and_cost_are_reported():
    class BadSurface(MaxModel):
        name = "test-bad-surface"

        def surface(self):
            def e(x):
                out = np.zeros((x.shape[0], 1))
                out[4, 0] = np.nan
                return out, np.zeros((x.shape[0], 1, 2))
            return Surface(e)

    class BadCost(MaxModel):
        name = "test-bad-cost"

        def cost(self):
            def a(x):
                v, g = _cost_max(x)
                v[5, 1] = np.inf
                return v, g
            return Cost(max_groups=(a,), weight=2.0)

    for model, node, label in ((BadSurface(), 4, "surface"), (BadCost(), 5, "cost max-group")):
        functional = make(model, 9)
        xi = random_xi(functional, 3)
        with pytest.raises(ModelOutputError) as info:
            functional.terms(xi)
        message = str(info.value)
        assert f"'{model.name}'" in message and label in message and f"node {node}" in message


def test_initial_guess_with_wrong_shape():
    class BadGuess(MaxModel):
        name = "test-bad-guess"

        def initial_guess(self, t):
            return np.zeros((t.size, 2)), np.zeros((t.size, 3))

    functional = make(BadGuess(), 5)
    with pytest.raises(ModelOutputError, match=r"'test-bad-guess'.*z has shape \(5, 3\), expected \(5, 2\)"):
        functional.initial_point()


def test_pack_enforces_x0():
    functional = make(MaxModel(), 5)
    xi = functional.pack(np.full((5, 2), 9.0), np.ones((5, 2)))
    np.testing.assert_array_equal(xi[0, :2], functional.model.x0)
    np.testing.assert_array_equal(xi[1:, :2], 9.0)
    np.testing.assert_array_equal(xi[:, 2:], 1.0)
    assert functional.free.sum() == 5 * 4 - 2 and not functional.free[0, :2].any()


# ====================================== a 2-coordinate block with a multi-piece max-group


def _outward_normals(v):
    """Unit outward normals of the edges (v_i, v_{i+1}) of a counter-clockwise triangle."""
    normals = []
    for i in range(3):
        d = v[(i + 1) % 3] - v[i]
        normals.append(np.array([d[1], -d[0]]) / np.linalg.norm(d))
    return normals


def _triangle_point(functional, seed, region):
    """Random x (small), and z per node: 'vertex' — beyond a vertex, inside its normal cone
    (the nearest point of the triangle is that vertex, h > 0) or at the centroid (h = 0);
    'edge' — beyond the middle of an edge (the nearest point is inside the edge)."""
    nodes = functional.grid.nodes
    rng = np.random.default_rng(seed)
    x = 0.5 * rng.standard_normal((nodes, 2))
    x[0] = functional.model.x0
    f = _triangle(x)[0]
    r = _disc_radius(x)
    z = np.zeros((nodes, 2))
    for k in range(nodes):
        v = f[k]
        normals = _outward_normals(v)
        q = k % 3
        if region == "vertex":
            if k % 4 == 3:
                z[k] = v.mean(axis=0)  # inside: h = 0
                continue
            cone = normals[q - 1] + normals[q]  # the two edges meeting at vertex q
            z[k] = v[q] + (r[k] + 0.2 + 0.5 * rng.random()) * cone / np.linalg.norm(cone)
        else:
            z[k] = 0.5 * (v[q] + v[(q + 1) % 3]) + (r[k] + 0.2 + 0.5 * rng.random()) * normals[q]
    return functional.pack(x, z)


@pytest.mark.parametrize("region", ["vertex", "edge"])
def test_triangle_phi_against_independent_distance(region):
    functional = make(TriangleModel(), 9)
    xi = _triangle_point(functional, 3, region)
    h = triangle_h(xi[:, :2], xi[:, 2:])[0]
    assert (h > 0).sum() >= 5
    w = trapezoid_weights(9, functional.model.T)
    assert functional.terms(xi).phi == pytest.approx(0.5 * float(w @ h**2), rel=1e-9)
    model = functional.model
    ref = independent_terms(model, 9, xi, triangle_h)
    assert functional.terms(xi).I == pytest.approx(ref["I"], rel=1e-9)
    assert functional.residuals(xi).inclusion_residual == pytest.approx(float(h.max()), rel=1e-9)


def test_triangle_phi_at_random_points():
    functional = make(TriangleModel(), 11)
    xi = random_xi(functional, 8, x_scale=0.5, z_scale=1.5)
    h = triangle_h(xi[:, :2], xi[:, 2:])[0]
    assert (h > 0).any() and (h == 0).any()
    w = trapezoid_weights(11, functional.model.T)
    assert functional.terms(xi).phi == pytest.approx(0.5 * float(w @ h**2), rel=1e-9)


@pytest.mark.parametrize("nodes,seed", [(9, 51), (14, 52)])
def test_triangle_gradient_and_directional_derivative_beyond_vertices(nodes, seed):
    """ψ* varies smoothly and one vertex is active: (4.5) gives the gradient."""
    functional = make(TriangleModel(), nodes)
    xi = _triangle_point(functional, seed, "vertex")
    qd = functional.quasidifferential(xi, TINY_DELTA)
    analytic = functional.weights[:, None] * (as_point(qd.sub) + as_point(qd.sup))
    fd = fd_gradient(functional, functional.objective, xi)
    scale = np.max(np.abs(fd))
    np.testing.assert_allclose(analytic, fd, rtol=0, atol=1e-6 * scale)
    rng = np.random.default_rng(seed)
    for _ in range(3):
        g = rng.standard_normal(xi.shape) * functional.free
        measured = one_sided_derivative(functional.objective, xi, g)
        assert qd.directional_derivative(g, functional.weights) == pytest.approx(measured, rel=1e-5, abs=1e-8)


def test_triangle_gauss_newton_gradient_beyond_edges():
    """gauss-newton's element of ∂h/∂x beyond an edge is h's gradient (the λ-weighted ends),
    not one end's: against central differences of the independent distance."""
    functional = make(TriangleModel(), 9)
    xi = _triangle_point(functional, 61, "edge")
    [sides] = functional.distance_sides(xi)
    [(ell, grad, psi)] = sides.sides
    x, z = functional.split(xi)
    assert np.allclose(ell, triangle_h(x, z)[0], rtol=1e-9)
    step = 1e-6
    for i in range(functional.n):
        shift = np.zeros_like(x)
        shift[:, i] = step
        fd = (triangle_h(x + shift, z)[0] - triangle_h(x - shift, z)[0]) / (2 * step)
        np.testing.assert_allclose(grad[:, i], fd, rtol=1e-6, atol=1e-8)


def test_triangle_directional_derivative_beyond_edges():
    """Beyond an edge's middle the nearest point of co{f_q(x)} lies inside the edge, ψ* is
    its normal and both ends are active at ψ*: h is smooth there, ∂h/∂x = −ψ*ᵀ Σ λ_q ∂f_q
    with λ the nearest point's barycentric weights (formula (4.5)'s co{−h ψ*ᵀ∂f_q} over the
    active ends was 4.5 % off). Measured on the independent distance (triangle_h): the
    functional's own objective carries ψ*'s search error, which at a kink of ℓ(ψ) is first
    order (1e-10), 1e-5 in a difference quotient."""
    model = TriangleModel()
    functional = make(model, 9)
    xi = _triangle_point(functional, 61, "edge")
    side = functional.pieces.state(functional.blocks[0], functional.arguments(xi), functional.split(xi)[1])
    assert side.faces is not None and side.faces[0].size == 9  # an edge at every node
    assert np.allclose(side.faces[1][0].sum(axis=1), 1.0) and np.allclose(np.sort(side.faces[1][0])[:, 1:], 0.5)
    qd = functional.quasidifferential(xi, TINY_DELTA)
    exact = lambda v: independent_terms(model, 9, v, triangle_h)["objective"]  # noqa: E731
    rng = np.random.default_rng(61)
    for _ in range(3):
        g = rng.standard_normal(xi.shape) * functional.free
        measured = one_sided_derivative(exact, xi, g)
        assert qd.directional_derivative(g, functional.weights) == pytest.approx(measured, rel=1e-5, abs=1e-8)
