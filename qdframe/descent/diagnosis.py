"""Which conditions of a problem an unsolved iterate leaves unmet, and by how much.

When a solve stops with I = φ + χ + ω + υ + σ bounded away from 0 (Fominyh,
arXiv:2406.15384, (3.16)), its iterate is a least-squares compromise between conditions
that cannot all hold: :func:`unmet_conditions` says where I sits, in the model's names.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import QdframeError
from ..functional import DistanceSides, Functional
from ..model import SetBlock

SHARE = 0.1  # a condition is named when its part of I is at least this fraction of I
MAX_CLAUSES = 3
GAP_TOL = 1e-8  # an end or periodic condition missed by more than this is named even with a small part of I
EMPTY_TOL = 1e-8  # F_b is called empty where c(F, ψ) + c(F, −ψ) < −EMPTY_TOL (relative to 1 + |ℓ|)


@dataclass(frozen=True)
class Clause:
    """One condition's part of I at an iterate, and the clause that names it."""

    part: float  # its contribution to I
    text: str
    kind: str  # "inclusion" (φ), "end", "periodic" (χ), "surface" (ω), "consistency" (υ), "selection" (σ)
    gap: float = 0.0  # end and periodic conditions: |x_j(T) − target|, read from x
    index: int = -1  # end conditions: the coordinate j


def unmet_conditions(functional: Functional, xi: np.ndarray, gap_tol: float = GAP_TOL) -> str:
    """The conditions the iterate `xi` leaves unmet, as "; "-separated clauses ("" when I = 0).

    I is split per condition (:func:`condition_parts`): χ (paper (3.14)) per end condition
    x_j(T) = xT_j and per periodic condition x_i(T) = x_i(0), φ (3.13) per block of F,
    ω (3.14') per surface equation, υ (3.17) per state, σ per sign term. Those carrying at
    least SHARE of I are named, largest first, at most MAX_CLAUSES. When none of them is an
    end or periodic condition, the largest one missed by more than `gap_tol` takes the last
    place: a target outside the reachable set puts most of I on the dynamics the iterate
    breaks to approach it (φ, υ, σ), little on χ itself.

    An end condition gives its target, the value x_j at the last node (with the digits the
    gap needs) and the gap between them; this is the compromise's value, so where the
    dynamics carry a share of I it says that the value is reached "only by violating the
    dynamics" (the nearest value the inclusion itself reaches may be farther). It adds that
    the target "may lie outside the reachable set" only where a test of reachability
    supports it (:func:`reach_bound`): x_j(0) plus the quadrature of the largest (or
    least) x_j' that F allows at the states the iterate visits falls short of the target.
    A pointwise condition gives its largest violation and the t of it; an inclusion adds
    "the set may be empty" where F_b(x) certainly is.
    """
    clauses = condition_parts(functional, xi)
    total = sum(clause.part for clause in clauses)
    if not (np.isfinite(total) and total > 0):
        return ""
    ranked = sorted(clauses, key=lambda clause: -clause.part)
    named = [clause for clause in ranked if clause.part >= SHARE * total][:MAX_CLAUSES] or ranked[:1]
    missed = [clause for clause in ranked if clause.kind in ("end", "periodic") and clause.gap > gap_tol]
    if missed and not any(clause.kind in ("end", "periodic") for clause in named):
        named = named[: MAX_CLAUSES - 1] + missed[:1]
    texts = [clause.text for clause in named]
    dynamics = sum(clause.part for clause in clauses if clause.kind in ("inclusion", "consistency", "selection"))
    for number, clause in enumerate(named):
        if clause.kind != "end":
            continue
        if dynamics >= SHARE * total:
            texts[number] += ", only by violating the dynamics"
        try:
            bound = reach_bound(functional, xi, clause.index)
        except (QdframeError, ArithmeticError, ValueError):  # the test failed (the model NaN in a simulation, …): no claim
            bound = None
        if bound is not None:
            texts[number] += f"; it may lie outside the reachable set ({bound})"
    return "; ".join(texts)


def reach_bound(functional: Functional, xi: np.ndarray, j: int) -> str | None:
    """A test of whether x_j(T) can reach its target: the clause that supports "it may lie
    outside the reachable set", or None. Two tests, where they apply (x_j(0) given, no
    unknown controls, x_j not a resolved state):

    - deterministic dynamics (x(0) given, every block one coordinate whose set is a point
      plus sign terms): the reachable set is the Filippov solution from x(0), simulated
      (:func:`qdframe.simulate.simulate`, implicit Euler with exact selections) with
      SIMULATION_STEPS and twice as many steps; a target farther from the finer end value
      than 10 times the two's difference (plus 1e-6·max(1, |target|)) is not reached;
    - otherwise a speed bound: F_b(y) bounds x_j' by c(F_b(y), ±e_j), its support along
      ±e_j (a sign term by its whole a·[−1, 1]); its largest value S± over the states the
      iterate visits and REACH_SAMPLES states drawn in a box around them, x(0) and the
      targets (each side widened by max(1, its width)) bounds every trajectory that stays
      in the box: x_j(0) − T·S− ≤ x_j(T) ≤ x_j(0) + T·S+, and a target beyond that (by
      more than 1e-6·max(1, |target|)) supports the remark.
    """
    model = functional.model
    if functional.m or not functional.start_given[j] or j in functional.resolved:
        return None
    target = float(model.end_values[list(functional.end).index(j)])
    margin, name = 1e-6 * max(1.0, abs(target)), model.state_names[j]
    if _deterministic(functional):
        from ..simulate import simulate

        ends = [simulate(model, 0.0, model.T, model.x0, dt=model.T / steps).x[-1, j]
                for steps in (SIMULATION_STEPS, 2 * SIMULATION_STEPS)]
        error = abs(ends[1] - ends[0])
        if np.isfinite(ends[1]) and abs(ends[1] - target) > 10.0 * error + margin:
            return f"the Filippov solution from x(0) ends at {name}(T) = {_number(ends[1], abs(ends[1] - target))}"
        return None
    block = next(block for block in functional.blocks if j in block.coords)
    x = functional.arguments(xi)
    known = np.vstack([x, np.where(np.isfinite(model.x0), model.x0, x[0])[None, :]])  # a free x_i(0): the iterate's
    if not np.all(np.isfinite(known)):
        return None
    lo, hi = known.min(axis=0), known.max(axis=0)
    for i, value in zip(functional.end, model.end_values):
        lo[i], hi[i] = min(lo[i], value), max(hi[i], value)
    pad = np.maximum(1.0, hi - lo)
    box = np.random.default_rng(0).uniform(lo - pad, hi + pad, size=(REACH_SAMPLES, x.shape[1]))
    y = np.vstack([x, box])
    psi = np.zeros((y.shape[0], block.size))
    psi[:, list(block.coords).index(j)] = 1.0
    zero = np.zeros((y.shape[0], functional.n))
    with np.errstate(all="ignore"):
        faster = float(np.max(-functional.pieces.side(block, y, zero, psi).ell))  # S+: the largest x_j'
        slower = float(np.max(-functional.pieces.side(block, y, zero, -psi).ell))  # S−: the largest −x_j'
    start, T = float(model.x0[j]), float(model.T)
    if np.isfinite(faster) and target > start + T * faster + margin:
        return (f"{name}' ≤ {faster:.4g} at every state tried, so {name}(T) ≤ "
                f"{_number(start + T * faster, target - start - T * faster)}")
    if np.isfinite(slower) and target < start - T * slower - margin:
        return (f"{name}' ≥ {-slower:.4g} at every state tried, so {name}(T) ≥ "
                f"{_number(start - T * slower, start - T * slower - target)}")
    return None


REACH_SAMPLES = 256  # states drawn in the box around the problem by reach_bound's speed bound, with the iterate's
SIMULATION_STEPS = 10_000  # reach_bound's simulation: this many steps and twice as many (cheap next to a solve)


def _deterministic(functional: Functional) -> bool:
    """Whether x' ∈ F(x) has one Filippov solution from the given x(0) to simulate: x(0)
    given, no controls, and every block one coordinate whose set is a point (max-groups of
    one piece, no min-group) plus sign terms."""
    model = functional.model
    if functional.m or not np.all(np.isfinite(model.x0)):
        return False
    y = model.x0[None, :]
    for block in functional.blocks:
        if block.size != 1 or block.min_groups:
            return False
        for group in block.max_groups:
            try:
                values = np.asarray(group.pieces(y)[0])
            except Exception:  # the model's own error shows elsewhere; no claim here
                return False
            if values.ndim != 3 or values.shape[1] != 1:
                return False
    return True


def condition_parts(functional: Functional, xi: np.ndarray) -> list[Clause]:
    """Every condition's part of I at `xi` with its clause; the parts sum to I.

    φ: ½ Σ_k w_k h_b² per block b (h_b = dist(z_b, F_b(x))); χ: ½ r_j² per end or periodic
    condition (r = :meth:`Functional.end_residual`); ω: ½ Σ_k w_k e_i² per surface
    equation; υ: ½ Σ_k w_k (x_i − x_i(0) − ∫x_i')² per state; σ: ½ Σ_k w_k r_i² per selection.
    """
    model, t, w = functional.model, functional.grid.t, functional.weights
    names = list(model.state_names)
    x, z = functional.split(xi)
    y = functional.arguments(xi)

    def at(values: np.ndarray) -> str:
        """The largest of `values` (N,) and its t."""
        k = int(np.argmax(values))
        return f"{values[k]:.1e} at t = {t[k]:.4g}"

    def integral(values: np.ndarray) -> float:
        return 0.5 * float(np.sum(w * values**2))

    clauses: list[Clause] = []
    for block, sides in zip(functional.blocks, functional.distance_sides(xi)):  # φ
        ells = [ell for ell, _, _ in sides.sides]
        h = np.abs(ells[0]) if sides.equation else np.maximum(0.0, np.max(ells, axis=0))
        label = ", ".join(names[c] for c in block.coords)
        label = f"{label}'" if block.size == 1 else f"({label})'"
        text = f"inclusion for {label}{f' ({block.name})' if block.name else ''} not met: distance {at(h)}"
        empty = _empty(functional, block, sides, y, z)
        if empty[int(np.argmax(h))]:
            text += "; the set may be empty there"
        elif empty.any():
            text += f"; the set may be empty at t = {t[int(np.argmax(empty))]:.4g}"
        clauses.append(Clause(integral(h), text, "inclusion"))
    end = functional.end_residual(xi)
    for j, target, residual in zip(functional.end, model.end_values, end):  # χ
        gap = abs(x[-1, j] - target)
        clauses.append(Clause(0.5 * float(residual) ** 2, f"end condition {names[j]}(T) = {target:g} not reached: "
                              f"nearest {_number(x[-1, j], gap)} (gap {gap:.2e})", "end", gap, int(j)))
    for i, residual in zip(functional.periodic, end[functional.end.size:]):  # χ, periodic
        gap = abs(x[-1, i] - x[0, i])
        clauses.append(Clause(0.5 * float(residual) ** 2, f"periodic condition {names[i]}(T) = {names[i]}(0) not met: "
                              f"{names[i]}(0) = {_number(x[0, i], gap)}, {names[i]}(T) = {_number(x[-1, i], gap)} "
                              f"(gap {gap:.2e})", "periodic", gap))
    if functional.surface is not None:  # ω
        e = np.abs(functional.surface_values(xi)[0])
        for i in range(e.shape[1]):
            clauses.append(Clause(integral(e[:, i]), f"surface e{i + 1} = 0 not met: max |e{i + 1}| {at(e[:, i])}",
                                  "surface"))
    gaps = np.abs(functional.consistency(xi))  # υ
    for i, name in enumerate(names):
        clauses.append(Clause(integral(gaps[:, i]),
                              f"consistency {name} = {name}(0) + ∫{name}' not met: max |error| {at(gaps[:, i])}",
                              "consistency"))
    if functional.p:  # σ
        r = np.abs(functional.selection_residual(xi)[0])
        ball = {k for first, width in functional.balls for k in range(first, first + width)}
        for k, name in enumerate(functional.selection_names):
            rule = "λ − P_B(λ + c·s)" if k in ball else "λ − clip(λ + c·s, −1, 1)"
            clauses.append(Clause(integral(r[:, k]), f"selection of {name} not in Sgn(s): max |{rule}| {at(r[:, k])}",
                                  "selection"))
    return clauses


def _empty(functional: Functional, block: SetBlock, sides: DistanceSides, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The nodes where F_b(y) is certainly empty, (N,) bool: ℓ(ψ) + ℓ(−ψ) = −c(F, ψ) − c(F, −ψ) > 0
    for the block's ψ (a point p of F gives c(F, ±ψ) ≥ ±<p, ψ>). One coordinate: ψ = ±1, an
    interval [lo, hi] with lo > hi; several: ψ*, where the distance is found (ℓ(−ψ*) evaluated)."""
    if sides.equation:  # a single point
        return np.zeros(y.shape[0], dtype=bool)
    ells = [ell for ell, _, _ in sides.sides]
    if len(ells) == 2:
        total = ells[0] + ells[1]
    else:
        total = ells[0] + functional.pieces.side(block, y, z, -sides.sides[0][2]).ell
    return total > EMPTY_TOL * (1.0 + np.abs(ells[0]))


def _number(value: float, gap: float = 0.0) -> str:
    """A value reached, with the significant digits that show a difference of `gap` from it
    (at least 4, at most 15): 2.5, 0.9997 for a gap of 3e-4 (not 1.000), 1.00000012."""
    if not np.isfinite(value):
        return str(value)
    scale = abs(value)
    digits = 4
    if gap > 0 and scale > 0:
        digits = int(np.clip(np.ceil(np.log10(scale / gap)) + 2, 4, 15))
    return f"{value:#.{digits}g}"
