"""Exact references for three optimal-control problems of a block (pure NumPy/SciPy).

The block: p' = v, v' = u − μ·sign(v) on [0, T] from rest at (0, 0). Each reference moves it
forward, v > 0 on (0, T), so on the motion the friction is the constant −μ and the dynamics are
linear; the references check this and raise ValueError when the data would make the block stand
still or go backwards (there the friction term would not be −μ).

In all three the optimal control is a clipped affine function of time. Pontryagin's principle
(Bryson & Ho, Applied Optimal Control, ch. 2 and 3; Kirk, Optimal Control Theory, ch. 5)
with H = u² + a·v + b·(u − μ) gives the costates a' = −∂H/∂p = 0, b' = −∂H/∂v = −a (∂H/∂v has no
friction term where v > 0), so b is affine in t and

    u(t) = argmin_{|u| ≤ U} H = clip(−b(t)/2, −U, U) = clip(α − βt, −U, U),  a = −2β, b = −2(α − βt).

Each problem is convex (quadratic cost, dynamics linear on the motion, convex control set), so
these conditions are also sufficient: the references are the global optima.

- `least_effort`: rest to rest over D, U = ∞, α and β in closed form;
- `least_effort_bounded`: the same with |u| ≤ U, (α, β) root-found, the states exact piecewise
  polynomials;
- `lq_terminal`: no friction, free end with a quadratic terminal penalty, closed form by the
  controllability Gramian;
- `least_effort_speed_bounded`: `least_effort` with the state bound v ≤ V binding on a stretch
  (:class:`SpeedBoundedReference`; its u is not of the clipped affine form).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq


def _moments(alpha: float, beta: float, U: float, t: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """∫_0^t u ds, ∫_0^t s·u ds and ∫_0^t u² ds for u(s) = clip(α − βs, −U, U), exactly.

    With U finite (then β > 0) u = U on [0, s1], α − βs on [s1, s2], −U on [s2, t], where α − βs = ±U
    at s1, s2 (clipped to [0, t]); with U = ∞, s1 = 0 and s2 = t."""
    t = np.asarray(t, dtype=float)
    if math.isinf(U):
        s1, s2, Uc = np.zeros_like(t), t, 0.0
    else:
        s1, s2, Uc = np.clip((alpha - U) / beta, 0.0, t), np.clip((alpha + U) / beta, 0.0, t), U
    d1, d2, d3 = s2 - s1, s2**2 - s1**2, s2**3 - s1**3
    m0 = Uc * s1 + alpha * d1 - beta * d2 / 2 - Uc * (t - s2)
    m1 = Uc * s1**2 / 2 + alpha * d2 / 2 - beta * d3 / 3 - Uc * (t**2 - s2**2) / 2
    m2 = Uc**2 * (s1 + t - s2) + alpha**2 * d1 - alpha * beta * d2 + beta**2 * d3 / 3
    return m0, m1, m2


@dataclass(frozen=True)
class OptimalReference:
    """An optimal motion on [0, T]: u(t) = clip(α − βt, −U, U) (U = inf: unbounded), p' = v,
    v' = u − μ from (0, 0), and its optimal `cost`. Costate convention: H = u² + a·v + b·(u − μ)
    (plus, in `lq_terminal`, λ(T) = ∂/∂x of the terminal penalty), a' = −∂H/∂p, b' = −∂H/∂v; then
    a ≡ −2β, b(t) = −2(α − βt). `switch_times` are the interior times where the bound starts or
    stops binding."""

    T: float
    mu: float
    alpha: float
    beta: float
    U: float
    cost: float
    switch_times: tuple[float, ...] = ()

    def control(self, t: ArrayLike) -> np.ndarray:
        """u(t), shape (len(t),)."""
        return np.clip(self.alpha - self.beta * np.atleast_1d(np.asarray(t, dtype=float)), -self.U, self.U)

    def states(self, t: ArrayLike) -> np.ndarray:
        """[p(t), v(t)], shape (len(t), 2): v = ∫_0^t u − μt, p = ∫_0^t (t − s)·u(s) ds − μt²/2."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        m0, m1, _ = _moments(self.alpha, self.beta, self.U, t)
        return np.column_stack([t * m0 - m1 - self.mu * t**2 / 2, m0 - self.mu * t])

    def costates(self, t: ArrayLike) -> np.ndarray:
        """[a(t), b(t)], shape (len(t), 2), in the convention of the class docstring."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return np.column_stack([np.full_like(t, -2 * self.beta), -2 * (self.alpha - self.beta * t)])


def _check_data(D: float, T: float, mu: float) -> None:
    if not T > 0 or not mu >= 0:
        raise ValueError(f"need T > 0 and a friction coefficient mu >= 0, got T = {T}, mu = {mu}")
    if not D > 0:
        raise ValueError(f"D = {D} <= 0: the block would stand still or move backwards, where the "
                         "friction is not -mu; the reference covers forward moves only")


def _check_moves_forward(ref: OptimalReference) -> None:
    """v > 0 on (0, T): u − μ is nonincreasing (β > 0), so v is concave with v(0) = v(T) = 0 and is
    positive inside unless it vanishes; the grid only guards that argument's premises."""
    inner = np.linspace(0, ref.T, 203)[1:-1]
    if not ref.beta > 0 or np.any(ref.states(inner)[:, 1] <= 0):
        raise ValueError("the block stops or reverses before T: the data leave the forward-motion model")


def least_effort(D: float = 1.0, T: float = 2.0, mu: float = 0.5) -> OptimalReference:
    """From rest at p = 0 to rest at p = D in time T, minimize ∫_0^T u² dt, u free.

    With w = u − μ the problem is the double integrator's, and ∫u² = ∫w² + 2μ∫w + μ²T where
    ∫w = v(T) − v(0) = 0; the least-energy w (PMP, or the Gramian W of `lq_terminal` with x(T)
    fixed: w = Bᵀe^{Aᵀ(T−t)}W⁻¹(D, 0)) is w = 6D/T² − 12Dt/T³. So u* = μ + w,
    v = 6Dt(T − t)/T³, p = D(3t²/T² − 2t³/T³), J* = 12D²/T³ + μ²T (2 at the defaults)."""
    _check_data(D, T, mu)
    ref = OptimalReference(T=T, mu=mu, alpha=mu + 6 * D / T**2, beta=12 * D / T**3, U=math.inf,
                           cost=12 * D**2 / T**3 + mu**2 * T)
    _check_moves_forward(ref)
    return ref


def least_effort_bounded(D: float = 1.0, T: float = 2.0, mu: float = 0.5, U: float = 1.5) -> OptimalReference:
    """`least_effort` with |u| ≤ U: by PMP u = clip(α − βt, −U, U) (b is affine).

    (α, β) solve v(T) = 0, p(T) = D with the states integrated exactly piece by piece. For fixed
    β > 0, ∫u increases with α: α(β) is the root of ∫u = μT; then p(T) increases strictly with β
    (two such controls of equal integral cross once, the steeper ahead), from 0 (β → 0, u ≡ μ) to
    the bang-bang move's D_max = T²(U² − μ²)/(4U) (β → ∞): both roots are bracketed (brentq,
    xtol 1e-15). Feasible iff D < D_max, i.e. U > 2D/T² + √(4D²/T⁴ + μ²) (1.2071 at the defaults);
    if U is above the unbounded optimum's max |u| the bound does not bind and this is `least_effort`.

    Defaults: the unbounded u* = 2 − 1.5t ranges over [−1, 2]; U = 1.5 binds on [0, 1/2] only, then
    u = 3/2 − (16/9)(t − 1/2) down to −7/6 at T; J* = 37/18 ≈ 2.0556 (vs 2 unbounded)."""
    _check_data(D, T, mu)
    D_max = T**2 * (U**2 - mu**2) / (4 * U) if U > mu else 0.0
    if not D < D_max:
        U_min = 2 * D / T**2 + math.sqrt(4 * D**2 / T**4 + mu**2)
        raise ValueError(f"|u| <= {U} cannot move the block by D = {D} in T = {T} against mu = {mu}: "
                         f"the bang-bang move reaches {D_max:.6g}; need U > {U_min:.15g}")

    def alpha_of(beta: float) -> float:
        return brentq(lambda a: _moments(a, beta, U, T)[0] - mu * T, -U, U + beta * T, xtol=1e-15, rtol=1e-15)

    def reach_gap(beta: float) -> float:
        m0, m1, _ = _moments(alpha_of(beta), beta, U, T)
        return T * m0 - m1 - mu * T**2 / 2 - D

    low = high = 12 * D / T**3  # the unbounded optimum's slope
    for _ in range(200):
        if reach_gap(low) < 0:
            break
        low /= 2
    for _ in range(200):
        if reach_gap(high) > 0:
            break
        high *= 2
    beta = brentq(reach_gap, low, high, xtol=1e-15, rtol=1e-15)
    alpha = alpha_of(beta)
    switches = tuple(s for s in ((alpha - U) / beta, (alpha + U) / beta) if 0 < s < T)
    ref = OptimalReference(T=T, mu=mu, alpha=alpha, beta=beta, U=U,
                           cost=float(_moments(alpha, beta, U, T)[2]), switch_times=switches)
    _check_moves_forward(ref)
    return ref


def lq_terminal(T: float = 1.0, weight: float = 50.0, target: tuple[float, float] = (2.0, 0.0)) -> OptimalReference:
    """p' = v, v' = u (no friction) from (0, 0), minimize ∫_0^T u² dt + w·|x(T) − r|², x = (p, v).

    PMP: u = Bᵀe^{Aᵀ(T−t)}ν = ν₁(T − t) + ν₂ with ν = −λ(T)/2 = w(r − x(T)), and x(T) = Wν with
    the controllability Gramian W = [[T³/3, T²/2], [T²/2, T]]; so (W + I/w)ν = r. The cost is
    νᵀWν + |ν|²/w = rᵀ(W + I/w)⁻¹r. Defaults: ν = (15300, −7500)/828, x(T) = (1.6304, 0.1812),
    J* = 850/23 = 36.9565… (the issue's 36.96, rounded)."""
    if not T > 0 or not weight > 0:
        raise ValueError(f"need T > 0 and weight > 0, got T = {T}, weight = {weight}")
    r = np.asarray(target, dtype=float)
    gramian = np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    nu = np.linalg.solve(gramian + np.eye(2) / weight, r)
    return OptimalReference(T=T, mu=0.0, alpha=float(nu[0] * T + nu[1]), beta=float(nu[0]), U=math.inf,
                            cost=float(r @ nu))


@dataclass(frozen=True)
class SpeedBoundedReference:
    """The least effort from rest at 0 to rest at D in time T under v ≤ V, binding on [t1, T − t1]:
    u = μ + a·(t1 − t) on [0, t1], μ on the bound, μ − a·(t − T + t1) on [T − t1, T], a = 2V/t1²."""

    D: float
    T: float
    mu: float
    V: float
    t1: float
    cost: float

    @property
    def switch_times(self) -> tuple[float, float]:
        """Where the bound starts and stops binding (u's kinks; v is C¹ there)."""
        return self.t1, self.T - self.t1

    def control(self, t: ArrayLike) -> np.ndarray:
        """u(t), shape (len(t),)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        a = 2 * self.V / self.t1**2
        return self.mu + a * (np.maximum(self.t1 - t, 0.0) - np.maximum(t - (self.T - self.t1), 0.0))

    def states(self, t: ArrayLike) -> np.ndarray:
        """[p(t), v(t)], shape (len(t), 2): by symmetry, the last arc is the first reflected,
        p(t) = D − p(T − t), v(t) = v(T − t)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        a, t1, V = 2 * self.V / self.t1**2, self.t1, self.V

        def first(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # on [0, t1]
            return a * (t1 * s**2 / 2 - s**3 / 6), a * (t1 * s - s**2 / 2)

        p_rise, v_rise = first(np.minimum(t, t1))
        p_fall, v_fall = first(np.clip(self.T - t, 0.0, t1))
        held = p_rise + V * np.clip(t - t1, 0.0, self.T - 2 * t1)  # up to the bound's end
        p = np.where(t <= self.T - t1, held, self.D - p_fall)
        v = np.where(t <= t1, v_rise, np.where(t <= self.T - t1, V, v_fall))
        return np.column_stack([p, v])


def least_effort_speed_bounded(D: float = 1.0, T: float = 2.0, mu: float = 0.5,
                               V: float = 0.6) -> SpeedBoundedReference:
    """`least_effort` with the state bound v ≤ V where it binds: D/T < V < 3D/(2T) (the unbounded
    optimum's top speed is 3D/(2T); a move of D in T needs an average D/T).

    With w = u − μ the cost is μ²T + ∫w² (as in `least_effort`), the problem convex (a quadratic cost,
    linear dynamics on the forward motion, a convex state constraint), so the conditions below are
    sufficient. The bound is of first order (v' = u − μ holds u): on the boundary arc w = 0, and w is
    affine off it (b affine, as for `least_effort`) and continuous at the junctions (the Hamiltonian is
    strictly convex in u; Bryson & Ho, §3.11; Hartl, Sethi & Vickson, SIAM Review 37 (1995)), so
    w = a·(t1 − t) on [0, t1] with v(t1) = a·t1²/2 = V, and the move's length D = VT − 2V·t1/3 gives
    t1 = 3(T − D/V)/2 and J* = μ²T + 2a²t1³/3. Defaults: t1 = 1/2, a = 4.8, J* = 2.42 (2 unbounded)."""
    _check_data(D, T, mu)
    if not D / T < V < 1.5 * D / T:
        raise ValueError(f"v <= {V} does not bind on a stretch of the move of D = {D} in T = {T}: need "
                         f"{D / T:.6g} < V < {1.5 * D / T:.6g} (below, the move is impossible; above, the "
                         "unbounded optimum never reaches V)")
    t1 = 1.5 * (T - D / V)
    a = 2 * V / t1**2
    return SpeedBoundedReference(D=D, T=T, mu=mu, V=V, t1=t1, cost=mu**2 * T + 2 * a**2 * t1**3 / 3)
