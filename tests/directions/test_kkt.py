"""directions/kkt.py: the KKT solve against a dense solve, a fresh SuperLU factorization,
and its own reuse of the symbolic analysis."""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import qdframe
from qdframe.directions.kkt import REUSE_ENTRIES, KKTSolver, solve_kkt
from qdframe.directions.linearized_system import LinearizedSystem
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid


def dense_kkt(hessian, constraints, gradient, rhs):
    size = hessian.shape[0]
    H, C = hessian.toarray(), constraints.toarray()
    K = np.block([[H, C.T], [C, np.zeros((C.shape[0], C.shape[0]))]])
    solution = np.linalg.solve(K, np.concatenate([-gradient, rhs]))
    return solution[:size], solution[size:]


def chain_system(rng, nodes, singular):
    """A chain-structured KKT like gauss-newton's: per node [x, z, Z], Z_p = Z_{p−1} + (z_{p−1} + z_p)/2·h,
    x_0 and Z_0 fixed. singular: H is zero on every Z and on x_0 (only PD on the constraints' null space)."""
    width, h = 3, 0.1
    size = nodes * width
    blocks = []
    for k in range(nodes):
        a = rng.normal(size=(width, width))
        block = a @ a.T + 1e-3 * np.eye(width)
        if singular:
            block[2, :] = block[:, 2] = 0.0  # no curvature on Z_k
            if k == 0:
                block[0, :] = block[:, 0] = 0.0
        blocks.append(block)
    hessian = sp.block_diag(blocks, format="csc")
    rows, cols, vals = [0, 1], [0, 2], [1.0, 1.0]  # x_0 = 0, Z_0 = 0
    for p in range(1, nodes):
        r = 1 + p
        for col, val in ((p * width + 2, 1.0), ((p - 1) * width + 2, -1.0),
                         ((p - 1) * width + 1, -h / 2), (p * width + 1, -h / 2)):
            rows.append(r)
            cols.append(col)
            vals.append(val)
    constraints = sp.csr_matrix((vals, (rows, cols)), shape=(nodes + 1, size))
    return hessian, constraints, rng.normal(size=size), rng.normal(size=nodes + 1)


@pytest.mark.parametrize("singular", [False, True])
@pytest.mark.parametrize("seed", [0, 1])
def test_solution_equals_a_dense_solve(seed, singular):
    """On small chains (H positive definite, or singular but PD on the null space of C),
    d and ν equal numpy's dense solve of the same KKT system, and satisfy its rows."""
    rng = np.random.default_rng(seed)
    hessian, constraints, gradient, rhs = chain_system(rng, 12, singular)
    d, nu = solve_kkt(hessian, constraints, gradient, rhs)
    d_ref, nu_ref = dense_kkt(hessian, constraints, gradient, rhs)
    assert np.allclose(d, d_ref, rtol=1e-9, atol=1e-11)
    assert np.allclose(nu, nu_ref, rtol=1e-9, atol=1e-11)
    assert np.allclose(hessian @ d + constraints.T @ nu, -gradient, atol=1e-11)
    assert np.allclose(constraints @ d, rhs, atol=1e-12)
    if singular:
        assert np.linalg.matrix_rank(hessian.toarray()) < hessian.shape[0]


def test_reused_analysis_solves_later_systems():
    """One KKTSolver over systems with the same constraints and new H values: one analysis,
    every solution equal to a fresh factorization's. An H with many more entries (another
    pattern: a band start's order on the exact selections' rows filled in 9e7 entries on
    paper-7.3) is analysed afresh before it is factored, and its order then serves the
    sparser systems that follow; another shape is analysed afresh."""
    rng = np.random.default_rng(3)
    solver = KKTSolver()
    hessian, constraints, gradient, rhs = chain_system(rng, 40, singular=True)
    for _ in range(3):
        hessian, _, gradient, rhs = chain_system(rng, 40, singular=True)
        d, nu = solver.solve(hessian, constraints, gradient, rhs)
        d_ref, nu_ref = dense_kkt(hessian, constraints, gradient, rhs)
        assert np.allclose(d, d_ref, rtol=1e-9, atol=1e-11) and np.allclose(nu, nu_ref, rtol=1e-9, atol=1e-11)
    assert solver.analyses == 1 and solver.factorizations == 3
    extra = sp.random(hessian.shape[0], hessian.shape[0], density=0.02, random_state=4)
    denser = (hessian + extra @ extra.T).tocsc()
    assert denser.nnz > REUSE_ENTRIES * hessian.nnz
    for system in (denser, hessian):
        d, nu = solver.solve(system, constraints, gradient, rhs)
        d_ref, nu_ref = dense_kkt(system, constraints, gradient, rhs)
        assert np.allclose(d, d_ref, rtol=1e-9, atol=1e-11)
    assert solver.analyses == 2 and solver.factorizations == 5  # the denser analysed, the sparser reusing its order
    other = chain_system(rng, 41, singular=True)  # another shape: analysed afresh
    solver.solve(*other)
    assert solver.analyses == 3


@pytest.mark.parametrize("name", ["paper-7.2", "paper-7.3"])
def test_gauss_newton_system_matches_superlu(name):
    """On gauss-newton's own first KKT system of the paper's examples (H's diagonal down to
    μ·w ≈ 1e-13 on 7.3), the residual relative to the right-hand side is at the level of a
    fresh SuperLU spsolve of the unpermuted matrix."""
    model = qdframe.load_model(name)
    functional = Functional(model, Grid(model.T, 201, model.default_scheme))
    system = LinearizedSystem(functional, functional.initial_point(), 1e-3)
    J, E = system.jacobian, system.constraints
    hessian = (system.penalty * (J.T @ J) + 1e-12 * sp.diags(system.damping())).tocsc()
    gradient = system.penalty * (J.T @ system.residual)
    kkt = sp.bmat([[hessian, E.T], [E, None]], format="csc")
    right = np.concatenate([-gradient, np.zeros(E.shape[0])])
    reference = spla.spsolve(kkt, right)
    d, nu = solve_kkt(hessian, E, gradient)
    ours = np.linalg.norm(kkt @ np.concatenate([d, nu]) - right) / np.linalg.norm(right)
    theirs = np.linalg.norm(kkt @ reference - right) / np.linalg.norm(right)
    assert ours <= max(10 * theirs, 1e-14)
    assert np.allclose(E @ d, 0.0, atol=1e-12 * np.abs(d).max())


def test_an_order_that_filled_in_is_not_reused_again():
    """Issue 31's cliff: a reused order whose factors outgrew the analysed ones (SuperLU's
    pivots left its diagonal) was recomputed once and then reused again, filling in 10×
    every other iteration. After one growth, every later system of the solve is analysed afresh."""
    rng = np.random.default_rng(3)
    hessian, constraints, gradient, rhs = chain_system(rng, 40, singular=True)
    solver = KKTSolver()
    solver.solve(hessian, constraints, gradient, rhs)
    assert solver.analyses == 1
    solver.solve(hessian, constraints, gradient, rhs)
    assert solver.analyses == 1  # reused
    solver._factor_nnz = 1  # as if the analysed factors were tiny: the next reuse 'grows'
    d, nu = solver.solve(hessian, constraints, gradient, rhs)
    expected = dense_kkt(hessian, constraints, gradient, rhs)
    assert np.allclose(d, expected[0], atol=1e-8) and np.allclose(nu, expected[1], atol=1e-8)
    for _ in range(3):
        solver.solve(hessian, constraints, gradient, rhs)
    assert solver.analyses == 4  # each of the three analysed afresh


def test_dense_columns_are_bordered_and_solve_the_same_system():
    """A chain with one column coupled to every node (a free start value, an unknown parameter):
    it is detected as dense, bordered, and d and ν equal a fresh sparse LU of the whole system."""
    from qdframe.directions.kkt import _dense_columns

    rng = np.random.default_rng(3)
    nodes = 3000
    hessian, constraints, gradient, rhs = chain_system(rng, nodes, singular=False)
    size = hessian.shape[0]
    column = np.zeros(size)
    column[1::3] = rng.normal(size=nodes) * 0.01  # every node's z couples to x_0
    column[0] = 0.0
    coupling = sp.csr_matrix(column[:, None])
    hessian = (hessian + sp.hstack([coupling, sp.csr_matrix((size, size - 1))])
               + sp.vstack([coupling.T, sp.csr_matrix((size - 1, size))])).tocsc()
    tie = sp.csr_matrix(([1.0, -2.0], ([0, 0], [0, 4])), shape=(1, size))  # a row on x_0 too (a tie of C in D)
    constraints = sp.vstack([constraints[1:], tie], format="csr")  # x_0 free: Z_0 = 0, the recursion, the tie
    rhs = np.append(rhs[1:], 0.5)
    hessian = (hessian + 10 * sp.eye(size)).tocsc()  # positive definite
    assert list(_dense_columns(hessian)) == [0]
    last = np.r_[1:size, 0]  # the same system with that column last (where gauss-newton puts a constant state)
    moved = (hessian[last][:, last].tocsc(), sp.csr_matrix(constraints[:, last]), gradient[last])
    assert list(_dense_columns(moved[0])) == [size - 1]
    K = sp.bmat([[hessian, constraints.T], [constraints, None]], format="csc")
    reference = spla.spsolve(K, np.concatenate([-gradient, rhs]))
    for (H, C, g), back in (((hessian, constraints, gradient), np.arange(size)), (moved, np.argsort(last))):
        d, nu = solve_kkt(H, C, g, rhs)
        assert np.allclose(np.concatenate([d[back], nu]), reference, rtol=1e-9, atol=1e-10)
        assert np.allclose(H @ d + C.T @ nu, -g, atol=1e-9)
