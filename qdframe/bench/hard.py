"""Hard cases: degenerate, extreme and long problems, each with what it must satisfy.

`qdframe bench hard` prints what every case measured; the test suite runs the same
cases and asserts `passed`. Each case is a function returning a :class:`HardCase`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..status import Status
from ..solve.solving import solve
from ..registry import load_model
from ..directions.minnorm import min_norm_point
from ..directions.native import NativeDirection
from ..functional import Functional
from ..schemes.grid import Grid
from ..model import InclusionModel, MaxGroup, MinGroup, SetBlock
from ..progress import bar
from ..functional.quasidifferential import Quasidifferential, SimplexSum


@dataclass(frozen=True)
class HardCase:
    """One case: what it measured (a short text), whether it passed, and its time."""

    name: str
    measured: str
    passed: bool
    seconds: float = 0.0


def _constant(value: float, width: int):
    return lambda y: (np.full(y.shape[0], value), np.zeros_like(y))


def _interval(lo: float, hi: float, width: int) -> MaxGroup:
    """co{lo, hi}: the max-group of two constant pieces."""

    def pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        values = np.tile([lo, hi], (y.shape[0], 1))[:, :, None]
        return values, np.zeros((y.shape[0], 2, 1, width))

    return MaxGroup(pieces, f"[{lo}, {hi}]")


def degenerate_polytopes() -> HardCase:
    """Duplicate and collinear generators, the zero vector, a tie within δ."""
    center = np.array([[0.0, 0.0], [0.0, 0.0], [0.5, 0.0], [0.0, 0.0]])
    generators = np.array([
        [[[1.0, 0.0], [1.0, 0.0], [-1.0, 0.0]]],  # duplicates around 0: answer 0
        [[[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]],  # collinear: answer (1, 1)
        [[[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]]],  # the zero vector: answer (0.5, 0)
        [[[1.0, 0.0], [1.0, 1e-4], [1.0, -1e-4]]],  # a tie within δ: answer (1, 0)
    ])
    mask = np.ones(generators.shape[:3], dtype=bool)
    points, weights = min_norm_point(center, generators, mask)
    expected = np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.0], [1.0, 0.0]])
    error = float(np.max(np.abs(points - expected)))
    sums = np.abs(weights.sum(axis=2) - 1).max()
    return HardCase("degenerate polytopes", f"max error {error:.1e}, simplex sums off by {sums:.1e}",
                    error <= 1e-12 and sums <= 1e-12 and weights.min() >= -1e-14)


def extreme_scales() -> HardCase:
    """The same min-norm problem at scales 1e-8 … 1e8 gives the scaled answer."""
    rng = np.random.default_rng(7)
    center, generators = rng.normal(size=(200, 4)), rng.normal(size=(200, 2, 3, 4))
    mask = np.ones((200, 2, 3), dtype=bool)
    reference, _ = min_norm_point(center, generators, mask)
    worst = 0.0
    for scale in (1e-8, 1e-4, 1e4, 1e8):
        points, _ = min_norm_point(scale * center, scale * generators, mask)
        worst = max(worst, float(np.max(np.abs(points / scale - reference))))
    return HardCase("extreme scales 1e-8…1e8", f"max relative deviation {worst:.1e}", worst <= 1e-9)


class _TwoBalls(InclusionModel):
    """z ∈ B_1((−1, 0)) ∩~ B_1((1, 0)) with c̃ = min of the two (Remark 5.1)."""

    name = "hard-two-balls"
    state_names = ("x1", "x2")
    default_x0 = (0.0, 0.0)

    def blocks(self) -> tuple[SetBlock, ...]:
        def values(y: np.ndarray, psi: np.ndarray) -> np.ndarray:
            norm = np.linalg.norm(psi, axis=1)
            return np.stack([-psi[:, 0] + norm, psi[:, 0] + norm], axis=1)

        def pieces(y: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return values(y, psi), np.zeros((y.shape[0], 2, 2))

        return (SetBlock((0, 1), min_groups=(MinGroup(pieces, "two unit balls", values=values),)),)


def non_unique_psi() -> HardCase:
    """z = (0, 1) is equidistant (√2 − 1) from both balls: ψ* is not unique."""
    model = _TwoBalls()
    functional = Functional(model, Grid(1.0, 3))
    xi = functional.pack(np.zeros((3, 2)), np.tile([0.0, 1.0], (3, 1)))
    h = functional.distance_sides(xi)[0].h
    direction = NativeDirection().compute(functional, xi, 1e-3)
    ok = np.allclose(h, np.sqrt(2) - 1, atol=1e-9) and np.all(np.isfinite(direction.step))
    return HardCase("non-unique ψ* (equidistant point)", f"h = {h[1]:.12f} (√2 − 1 = {np.sqrt(2) - 1:.12f})", bool(ok))


class _Band(InclusionModel):
    """z ∈ [−1, 1] with x(1) = 1: z ≡ 1 lies exactly on the boundary of F."""

    name = "hard-boundary"
    state_names = ("x",)
    default_x0 = (0.0,)
    end_indices = (0,)
    default_end_values = (1.0,)

    def blocks(self) -> tuple[SetBlock, ...]:
        return (SetBlock((0,), max_groups=(_interval(-1.0, 1.0, 1),)),)

    def initial_guess(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return t[:, None].copy(), np.ones((t.size, 1))


def on_the_boundary() -> HardCase:
    """A start on the boundary of F that solves the problem: 0 iterations, solved."""
    outcome = [solve(_Band(), nodes=51, direction=d) for d in ("native", "gauss-newton")]
    ok = all(r.converged and r.iterations == 0 and r.I <= 1e-25 for r in outcome)
    return HardCase("z on the boundary of F, a solving start", ", ".join(
        f"{r.direction}: {r.status} after {r.iterations}, I = {r.I:.1e}" for r in outcome), ok)


def unreachable_end() -> HardCase:
    """paper-7.2 with x(1) = (5, 5), unreachable since |x'| ≤ 1: never `solved`."""
    result = solve(load_model("paper-7.2", end_values=[5.0, 5.0]), nodes=21, max_iter=60)
    return HardCase("unreachable end point (7.2, xT = 5,5)", f"{result.status}, I = {result.I:.2f}",
                    not result.converged and result.I > 1.0)


class _Spread(InclusionModel):
    """x' ∈ [1 − |x|, 1 + |x|] from 0 to 1.5 (examples/custom_model.py)."""

    name = "hard-spread"
    state_names = ("x",)
    default_x0 = (0.0,)
    end_indices = (0,)
    default_end_values = (1.5,)

    def blocks(self) -> tuple[SetBlock, ...]:
        def pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            values = np.stack([1 + y[:, 0], 1 - y[:, 0]], axis=1)[:, :, None]
            jac = np.zeros((y.shape[0], 2, 1, 1))
            jac[:, 0, 0, 0], jac[:, 1, 0, 0] = 1.0, -1.0
            return values, jac

        return (SetBlock((0,), max_groups=(MaxGroup(pieces, "1 ± x"),)),)


def many_nodes() -> HardCase:
    """N = 10^5 nodes with gauss-newton."""
    result = solve(_Spread(), nodes=100_001, estimate=False)
    return HardCase("N = 10^5", f"{result.status} in {result.iterations} iterations, I = {result.I:.1e}",
                    result.converged)


class _Oscillator(InclusionModel):
    """x1' = x2, x2' ∈ −x1 + [−0.1, 0.1] on [0, 100]; the end point is that of x1 = cos t."""

    name = "hard-oscillator"
    state_names = ("x1", "x2")
    default_T = 100.0
    default_x0 = (1.0, 0.0)
    end_indices = (0, 1)
    default_end_values = (float(np.cos(100.0)), float(-np.sin(100.0)))

    def blocks(self) -> tuple[SetBlock, ...]:
        def x2(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            grad = np.zeros_like(y)
            grad[:, 1] = 1.0
            return y[:, 1], grad

        def spring(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            values = np.stack([-y[:, 0] - 0.1, -y[:, 0] + 0.1], axis=1)[:, :, None]
            jac = np.zeros((y.shape[0], 2, 1, 2))
            jac[:, :, 0, 0] = -1.0
            return values, jac

        return (SetBlock.equation(0, x2), SetBlock((1,), max_groups=(MaxGroup(spring, "−x1 ± 0.1"),)))


def long_horizon() -> HardCase:
    """T = 100 (about 16 periods) with N = 4001."""
    result = solve(_Oscillator(), nodes=4001)
    return HardCase("long horizon T = 100", f"{result.status} in {result.iterations} iterations, "
                    f"I = {result.I:.1e}, boundary error {result.boundary_error:.1e}", result.converged)


class _Stiff(InclusionModel):
    """x' ∈ −1000·x + [−1, 1] from 1 to x(1) = 0 (a stiff decay with a disturbance)."""

    name = "hard-stiff"
    state_names = ("x",)
    default_x0 = (1.0,)
    end_indices = (0,)
    default_end_values = (0.0,)

    def blocks(self) -> tuple[SetBlock, ...]:
        def pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            values = np.stack([-1000 * y[:, 0] - 1, -1000 * y[:, 0] + 1], axis=1)[:, :, None]
            return values, np.full((y.shape[0], 2, 1, 1), -1000.0)

        return (SetBlock((0,), max_groups=(MaxGroup(pieces, "−1000x ± 1"),)),)


def stiff() -> HardCase:
    """Coefficient 1000 against a disturbance of 1, N = 2001."""
    result = solve(_Stiff(), nodes=2001)
    return HardCase("stiff coefficient 1e3", f"{result.status} in {result.iterations} iterations, I = {result.I:.1e}",
                    result.converged)


def determinism() -> HardCase:
    """The same input gives the same result to the bit."""
    first, second = (solve("paper-7.1", nodes=101) for _ in range(2))
    same = (np.array_equal(first.x, second.x) and np.array_equal(first.z, second.z)
            and first.I == second.I and first.iterations == second.iterations)
    return HardCase("determinism (7.1 twice)", "bit-identical" if same else "results differ", same)


def friction_suite() -> HardCase:
    """The stick/slide/switch suite at N = 101 from the default start: the discrete problem solved
    (solved or uncertified: N = 101 is not meant to meet 1e-6), strict residual ≤ 1e-8."""
    from .friction import SUITE, run_suite

    rows = run_suite(SUITE, (101,))
    failed = [r.model for r in rows if r.status not in (Status.SOLVED, Status.UNCERTIFIED)]
    worst = max(r.residual for r in rows)
    return HardCase("stick/slide/switch suite (N = 101)",
                    f"{len(rows) - len(failed)}/{len(rows)} solved, strict residual ≤ {worst:.1e}"
                    + (f", failed: {', '.join(failed)}" if failed else ""), not failed)


CASES: tuple[Callable[[], HardCase], ...] = (
    degenerate_polytopes, extreme_scales, non_unique_psi, on_the_boundary, unreachable_end,
    many_nodes, long_horizon, stiff, determinism, friction_suite,
)


def run(cases=CASES, progress: bool = False) -> list[HardCase]:
    """Run every case, timing each; `progress`: a bar on stderr (on a terminal)."""
    results = []
    with bar(len(cases), "bench hard", enabled=progress) as runs:
        for case in cases:
            start = time.perf_counter()
            result = case()
            results.append(HardCase(result.name, result.measured, result.passed, time.perf_counter() - start))
            runs.update(1)
    return results


def table(results: list[HardCase]) -> str:
    width = max(len(r.name) for r in results)
    lines = [f"{'case':<{width}}  result  time (s)  measured"]
    lines += [f"{r.name:<{width}}  {'pass' if r.passed else 'FAIL':<6}  {r.seconds:8.2f}  {r.measured}" for r in results]
    return "\n".join(lines)
