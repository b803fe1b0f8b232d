"""The optimal-control references of qdframe/models/optimal_references.py, each checked on its own:
the dynamics integrated (DOP853, rtol = atol = 1e-12) from the reference control give its states and
end conditions, the cost by quadrature is its cost, Pontryagin's conditions hold, and no small
admissible perturbation of the control lowers the cost."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson, quad, solve_ivp

from qdframe.models.optimal_references import least_effort, least_effort_bounded, least_effort_speed_bounded, lq_terminal

TOL = 1e-9
CASES = {
    "least-effort": lambda: least_effort(),
    "least-effort-other": lambda: least_effort(D=0.7, T=1.3, mu=0.2),
    "bounded-start": lambda: least_effort_bounded(),  # U = 1.5 binds on [0, 1/2] only
    "bounded-both-ends": lambda: least_effort_bounded(U=1.3),
    "bounded-frictionless": lambda: least_effort_bounded(mu=0.0, U=1.2),
    "bounded-nearly-bang-bang": lambda: least_effort_bounded(U=1.21),
    "lq-terminal": lambda: lq_terminal(),
}
REST_TO_REST = [name for name in CASES if name != "lq-terminal"]
D_OF = {"least-effort-other": 0.7}
LQ_WEIGHT, LQ_TARGET = 50.0, np.array([2.0, 0.0])


def _coulomb(v: float, u: float, mu: float) -> float:
    """v' of the block with Coulomb friction; at rest it sticks unless |u| > mu."""
    if v != 0:
        return u - mu * math.copysign(1.0, v)
    return u - mu * math.copysign(1.0, u) if abs(u) > mu else 0.0


@pytest.fixture(scope="module")
def runs():
    """Each case's reference and its motion integrated from the reference control alone."""
    out = {}
    for name, make in CASES.items():
        ref = make()
        grid = np.linspace(0, ref.T, 81)
        sol = solve_ivp(lambda t, x: [x[1], _coulomb(x[1], ref.control(t)[0], ref.mu)], (0, ref.T), [0.0, 0.0],
                        method="DOP853", rtol=1e-12, atol=1e-12, t_eval=grid)
        assert sol.success
        out[name] = (ref, grid, sol.y.T)
    return out


def _hamiltonian(ref, x, u, lam):
    return u**2 + lam[..., 0] * x[..., 1] + lam[..., 1] * (u - ref.mu)


@pytest.mark.parametrize("name", CASES)
def test_the_integrated_motion_is_the_reference(runs, name):
    ref, grid, x = runs[name]
    assert np.max(np.abs(x - ref.states(grid))) < TOL
    if name in REST_TO_REST:
        assert abs(x[-1, 0] - D_OF.get(name, 1.0)) < TOL and abs(x[-1, 1]) < TOL
        assert np.all(x[1:-1, 1] > 0)  # moving forward: the friction is -mu throughout


@pytest.mark.parametrize("name", CASES)
def test_the_cost_by_quadrature(runs, name):
    ref, _, x = runs[name]
    cost, _ = quad(lambda t: ref.control(t)[0] ** 2, 0, ref.T, points=ref.switch_times or None,
                   epsabs=1e-13, epsrel=1e-13, limit=200)
    if name == "lq-terminal":
        cost += LQ_WEIGHT * np.sum((x[-1] - LQ_TARGET) ** 2)
    assert abs(cost - ref.cost) < TOL


@pytest.mark.parametrize("name", CASES)
def test_pontryagin(runs, name):
    """Adjoint equations, the control minimizing H over the admissible set at each time, H constant
    along the (integrated) optimal motion, and for the free end the transversality condition."""
    ref, grid, x = runs[name]
    lam, u = ref.costates(grid), ref.control(grid)
    assert np.ptp(lam[:, 0]) == 0 and np.allclose(lam[:, 1] - lam[0, 1], -lam[:, 0] * grid, rtol=0, atol=1e-13)
    bound = ref.U if math.isfinite(ref.U) else 10 * np.max(np.abs(u))
    trials = np.linspace(-bound, bound, 4001)
    h_trials = trials[None, :] ** 2 + lam[:, 1:2] * trials[None, :]  # H's u-dependent part
    assert np.all(u**2 + lam[:, 1] * u <= h_trials.min(axis=1) + 1e-12)
    gradient = 2 * u + lam[:, 1]  # KKT: zero inside the bounds, pushing outwards on them
    inside = np.abs(u) < ref.U
    assert np.max(np.abs(gradient[inside])) < 1e-12
    assert np.all(gradient[u == ref.U] <= 0) and np.all(gradient[u == -ref.U] >= 0)
    h = _hamiltonian(ref, x, u, lam)
    assert np.ptp(h[1:-1]) < 1e-8  # autonomous: H constant on the motion (v > 0 inside)
    if name == "lq-terminal":
        assert np.allclose(lam[-1], 2 * LQ_WEIGHT * (x[-1] - LQ_TARGET), rtol=0, atol=1e-7)


def _pieces(ref):
    edges = [0.0, *ref.switch_times, ref.T]
    nodes, weights = np.polynomial.legendre.leggauss(40)
    t = np.concatenate([(b - a) / 2 * nodes + (a + b) / 2 for a, b in zip(edges, edges[1:])])
    w = np.concatenate([(b - a) / 2 * weights for a, b in zip(edges, edges[1:])])
    return t, w


def _free_arc(ref):
    u = ref.control(np.array([0.0, ref.T]))
    t1 = ref.switch_times[0] if u[0] == ref.U else 0.0
    t2 = ref.switch_times[-1] if u[1] == -ref.U else ref.T
    return t1, t2


def _constraint_keeping_perturbation(ref, rng):
    """ψ with ∫ψ = ∫tψ = 0 (so v(T) and p(T) unchanged), vanishing at the free arc's ends and
    pointing inwards (a sine bump) where the bound binds."""
    t1, t2 = _free_arc(ref)
    length = t2 - t1
    coef, push_start, push_end = rng.normal(size=5), rng.uniform(0.2, 1), rng.uniform(0.2, 1)

    def sines(t, ks):
        s = np.clip((t - t1) / length, 0, 1)
        return np.stack([np.sin(k * np.pi * s) for k in ks], axis=-1)

    def rough(t):
        out = sines(t, range(3, 8)) @ coef
        out = np.where(t < t1, -push_start * np.sin(np.pi * t / t1) if t1 > 0 else 0, out)
        return np.where(t > t2, push_end * np.sin(np.pi * (t - t2) / (ref.T - t2)) if t2 < ref.T else 0, out)

    t, w = _pieces(ref)
    basis = sines(t, (1, 2))
    moments = np.array([[w @ basis[:, j], w @ (t * basis[:, j])] for j in range(2)]).T
    fix = np.linalg.solve(moments, -np.array([w @ rough(t), w @ (t * rough(t))]))
    return lambda s: rough(s) + sines(s, (1, 2)) @ fix


@pytest.mark.parametrize("name", REST_TO_REST)
def test_no_admissible_end_keeping_perturbation_lowers_the_cost(runs, name):
    ref = runs[name][0]
    t, w = _pieces(ref)
    u = ref.control(t)
    fine = np.linspace(0, ref.T, 2001)
    v_fine, tested = ref.states(fine)[:, 1], 0
    rng = np.random.default_rng(7)
    for _ in range(20):
        psi = _constraint_keeping_perturbation(ref, rng)
        scale = np.max(np.abs(psi(fine)))
        p, v_shift = psi(t) / scale, cumulative_simpson(psi(fine) / scale, x=fine, initial=0)
        assert abs(w @ p) < 1e-12 and abs(w @ (t * p)) < 1e-12  # v(T) = 0 and p(T) = D kept
        for eps in (1e-1, 1e-2, 1e-3, -1e-3, -1e-2, -1e-1):
            moved = u + eps * p
            if math.isfinite(ref.U) and not np.all(np.abs(moved) <= ref.U):
                continue  # not admissible at this size and sign
            assert np.all(v_fine[1:-1] + eps * v_shift[1:-1] > 0)  # still moving forward: friction -mu
            assert w @ moved**2 > ref.cost
            tested += 1
        if not ref.switch_times:  # unbounded: the first variation vanishes, J(u + εψ) = J* + ε²∫ψ²
            assert abs(w @ (u * p)) < 1e-12
    assert tested >= 20  # the admissible sizes and signs are many


def test_the_perturbation_tests_are_not_vacuous(runs):
    """On the bounded cases the small perturbations are admissible (so they are tested)."""
    for name in ("bounded-start", "bounded-both-ends"):
        ref = runs[name][0]
        t, _ = _pieces(ref)
        psi = _constraint_keeping_perturbation(ref, np.random.default_rng(0))
        scale = np.max(np.abs(psi(np.linspace(0, ref.T, 2001))))
        assert np.all(np.abs(ref.control(t) + 1e-3 * psi(t) / scale) <= ref.U)


def test_no_perturbation_lowers_the_terminal_cost(runs):
    ref = runs["lq-terminal"][0]
    t, w = _pieces(ref)
    u = ref.control(t)

    def cost(control):
        end = np.array([w @ ((ref.T - t) * control), w @ control])  # p(T), v(T) of v' = u from rest
        return w @ control**2 + LQ_WEIGHT * np.sum((end - LQ_TARGET) ** 2)

    rng = np.random.default_rng(3)
    for _ in range(20):
        c = rng.normal(size=6)
        p = c[0] + c[1] * t + c[2] * t**2 + c[3] * np.sin(3 * t) + c[4] * np.cos(7 * t) + c[5] * np.exp(-t)
        p_end = np.array([w @ ((ref.T - t) * p), w @ p])
        second = w @ p**2 + LQ_WEIGHT * p_end @ p_end
        for eps in (1e-1, 1e-3, -1e-3, -1e-1):
            assert cost(u + eps * p) > ref.cost
            assert abs(cost(u + eps * p) - ref.cost - eps**2 * second) < 1e-10 * max(1.0, eps**2 * second)


def test_closed_forms_at_the_default_numbers():
    ref = least_effort()
    t = np.linspace(0, 2, 9)
    assert ref.cost == 12 / 8 + 0.25 * 2 == 2.0
    assert np.allclose(ref.states(t), np.column_stack([3 * t**2 / 4 - 2 * t**3 / 8, 6 * t * (2 - t) / 8]),
                       rtol=0, atol=1e-15)
    assert np.allclose(ref.control(t), 0.5 + 1.5 - 1.5 * t, rtol=0, atol=1e-15)
    bounded = least_effort_bounded()  # U = 1.5 binds on [0, 1/2]: then u = 3/2 − (16/9)(t − 1/2) ≥ −7/6
    assert len(bounded.switch_times) == 1 and abs(bounded.switch_times[0] - 0.5) < 1e-14
    assert abs(bounded.beta - 16 / 9) < 1e-14 and abs(bounded.alpha - 43 / 18) < 1e-14
    assert abs(bounded.cost - 37 / 18) < 1e-14
    symmetric = least_effort_bounded(mu=0.0, U=1.2)  # binds on [0, 1 − 1/√2] and [1 + 1/√2, 2]
    assert np.allclose(symmetric.switch_times, (1 - 2**-0.5, 1 + 2**-0.5), rtol=0, atol=1e-14)
    loose = least_effort_bounded(U=3.0)  # above max |u*| = 2: the bound does not bind, least_effort's answer
    assert loose.switch_times == () and abs(loose.cost - 2.0) < 1e-14 and abs(loose.beta - 1.5) < 1e-14
    lq = lq_terminal()
    assert abs(lq.cost - 850 / 23) < 1e-12 and round(lq.cost, 2) == 36.96
    assert np.allclose(lq.states([1.0])[0], [2 - 2 * 1.02 / 0.1104 / 50, 0.5 / 0.1104 * 2 / 50], rtol=0, atol=1e-13)


def test_the_bound_costs_more_the_tighter_it_is():
    costs = [least_effort_bounded(U=U).cost for U in (3.0, 1.5, 1.3, 1.25, 1.21)]
    assert costs[0] == pytest.approx(2.0, abs=1e-14) and all(a < b for a, b in zip(costs, costs[1:]))


@pytest.mark.parametrize("call", [
    lambda: least_effort(D=0.0), lambda: least_effort(D=-1.0), lambda: least_effort(mu=-0.1),
    lambda: least_effort_bounded(D=-1.0),
    lambda: least_effort_bounded(U=1.2),  # below 2D/T² + √(4D²/T⁴ + μ²) = 1.2071…
    lambda: least_effort_bounded(U=0.5),  # cannot even overcome the friction
    lambda: least_effort_bounded(U=0.5 + math.sqrt(0.5)),  # exactly the bang-bang move: no interior optimum
    lambda: lq_terminal(weight=0.0),
])
def test_data_outside_the_forward_motion_are_refused(call):
    with pytest.raises(ValueError):
        call()


@pytest.mark.parametrize("data", [dict(), dict(D=0.5, T=2.0, mu=0.2, V=0.3), dict(D=2.0, T=3.0, mu=0.0, V=0.9)])
def test_the_speed_bounded_reference_is_its_integrated_motion_and_the_convex_programs_optimum(data):
    """v ≤ V binding on [t1, T − t1]: the motion integrated from the reference control is its states,
    ends at rest at D and keeps v ≤ V (= V on the stretch); its cost is the quadrature's; and it is the
    limit of the convex program discretized independently (w = u − μ piecewise constant on 1000 steps,
    v at the steps, p by the trapezoid rule; CVXPY), whose least ∫w² is within 1e-5 of μ²T's complement."""
    cp = pytest.importorskip("cvxpy")
    ref = least_effort_speed_bounded(**data)
    grid = np.linspace(0, ref.T, 161)
    kinks = [0.0, *ref.switch_times, ref.T]
    x = np.array([0.0, 0.0])
    for a, b in zip(kinks, kinks[1:]):  # the control is smooth between its kinks
        sol = solve_ivp(lambda t, y: [y[1], ref.control(t)[0] - ref.mu], (a, b), x, method="DOP853",
                        rtol=1e-12, atol=1e-12, dense_output=True)
        inside = (grid >= a) & (grid <= b)
        assert np.max(np.abs(sol.sol(grid[inside]).T - ref.states(grid[inside]))) < TOL
        x = sol.y[:, -1]
    assert np.allclose(x, [ref.D, 0.0], rtol=0, atol=TOL)
    v = ref.states(grid)[:, 1]
    held = (grid >= ref.t1) & (grid <= ref.T - ref.t1)
    assert np.all(v <= ref.V + 1e-15) and np.allclose(v[held], ref.V, rtol=0, atol=1e-15) and np.all(v[1:-1] > 0)
    cost = sum(quad(lambda t: ref.control(t)[0] ** 2, a, b, epsabs=1e-13)[0] for a, b in zip(kinks, kinks[1:]))
    assert abs(cost - ref.cost) < 1e-11
    steps = 1000
    h = ref.T / steps
    w, speed = cp.Variable(steps), cp.Variable(steps + 1)
    program = cp.Problem(cp.Minimize(h * cp.sum_squares(w)),
                         [speed[0] == 0, speed[1:] == speed[:-1] + h * w, speed[steps] == 0,
                          h * cp.sum(speed[1:] + speed[:-1]) / 2 == ref.D, speed <= ref.V])
    program.solve()
    assert abs(program.value + ref.mu**2 * ref.T - ref.cost) < 1e-5 * ref.cost


@pytest.mark.parametrize("V", [0.5, 0.75, 0.8])
def test_a_speed_bound_that_does_not_bind_on_a_stretch_is_refused(V):
    with pytest.raises(ValueError, match="does not bind"):
        least_effort_speed_bounded(V=V)  # D/T = 0.5 and 3D/(2T) = 0.75 at the defaults
