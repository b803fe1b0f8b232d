"""`qdframe check-model NAME`: every piece and gradient of a model against finite differences.

A model hands the solver its pieces with gradients (:mod:`qdframe.model`): max-groups
f_q(y) with ∂f/∂y, min-groups g_p(y, ψ) with ∂g/∂y, sign terms' amplitudes and switches,
the surface e(x) and the cost's groups. A wrong gradient does not stop a solve: it
misleads the direction and the run stalls or ends `stationary` far from I = 0. This
check evaluates every piece at random states and controls (and random ψ) around the
model's boundary data and initial guess, compares each gradient with central finite
differences, and reports the worst error per piece; a piece that returns NaN/inf, an
array of the wrong shape, or a negative sign amplitude fails too. A min-group's optional
values-only function must give the values of its pieces (to 1e-9, relative to max(1, |g|)).

Two checks of the model as a whole: `initial_guess()` (and `initial_controls()`) is called
on 11 points of [0, T] and must return finite arrays of the right shapes; and every set
F_b(y) must be non-empty along that start and somewhere among the sample points. F_b(y)
is certainly empty where c(F_b, ψ) + c(F_b, −ψ) < 0 for some ψ (ψ = ±1 for one
coordinate, 16 directions of S_k for a block of k; sign terms with their band, which
contains Filippov's set): a set empty at every sample point (`Interval(0, 1) &
Interval(2, 3)`) or along the start fails; one empty at some sample points only is noted
(a state constraint, as `disturbed-control`'s U(x) for |x1| > 0.75).

The error of an entry is |∂_fd − ∂| / max(1, |∂|). Where it exceeds the tolerance the
difference is taken again with a step 100 times smaller (a kink of |·| inside the first
step is not an error); the smaller of the two errors counts.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..argtypes import integer, positive_float
from ..errors import InputError, QdframeError
from ..functional.pieces import VALUES_TOL, values_error
from ..model import InclusionModel
from ..registry import plugin_code


class ModelCheckError(QdframeError):
    """A model's piece has a wrong gradient, returns NaN/inf or the wrong shape (exit status 1)."""


@dataclass
class PieceCheck:
    """The verdict on one group of pieces."""

    label: str
    # "ok" | "wrong gradient" | "values differ" | "non-finite" | "bad shape" | "negative amplitude" | "empty set" | "error"
    status: str
    worst_error: float  # worst gradient error (0 if not compared)
    detail: str = ""  # where the worst error is, or what went wrong
    note: str = ""  # shown with an ok status too (a set empty at some sample points)

    @property
    def ok(self) -> bool:
        return self.status == "ok"


@dataclass
class CheckReport:
    """All pieces of a model checked at `samples` random points."""

    model: str
    samples: int
    seed: int
    tol: float
    pieces: list[PieceCheck] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return all(p.ok for p in self.pieces)

    @property
    def failures(self) -> list[PieceCheck]:
        return [p for p in self.pieces if not p.ok]

    def table(self) -> str:
        width = max([len(p.label) for p in self.pieces] + [5])
        lines = [
            f"model {self.model}: {len(self.pieces)} piece groups at {self.samples} random points (seed {self.seed}), "
            f"gradient tolerance {self.tol:g}",
            f"  {'piece':<{width}}  {'worst error':>11}  status",
        ]
        for p in self.pieces:
            status = p.status + (f" — {p.detail}" if p.detail and not p.ok else "") + (f" — {p.note}" if p.note else "")
            lines.append(f"  {p.label:<{width}}  {p.worst_error:>11.1e}  {status}")
        lines.append(self._agreement() if self.ok else f"{len(self.failures)} piece group(s) failed")
        return "\n".join(lines)

    def _agreement(self) -> str:
        values = any(p.label.endswith(" values") for p in self.pieces)
        return "all pieces agree with finite differences" + (" and every values() with its pieces" if values else "")

    def message(self) -> str:
        """One line naming the first failure."""
        if self.ok:
            return f"model {self.model!r}: {self._agreement()}"
        first = self.failures[0]
        more = f" (and {len(self.failures) - 1} more)" if len(self.failures) > 1 else ""
        return f"model {self.model!r}: {first.label}: {first.status}: {first.detail}{more}"

    def to_dict(self) -> dict:
        return {"model": self.model, "samples": self.samples, "seed": self.seed, "tol": self.tol, "ok": self.ok,
                "pieces": [asdict(p) for p in self.pieces]}


class _Failed(Exception):
    def __init__(self, status: str, detail: str) -> None:
        super().__init__(detail)
        self.status, self.detail = status, detail


def check_model(model: InclusionModel, samples: int = 64, seed: int = 0, tol: float = 1e-6) -> CheckReport:
    """Check every piece of `model` against central finite differences at `samples` random points."""
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise InputError("samples", "an integer ≥ 1", samples)
    if not (isinstance(tol, (int, float)) and np.isfinite(tol) and tol > 0):
        raise InputError("tol", "a positive number", tol)
    if model.has_unknowns:  # its pieces take (x, p, u): checked as the solver sees them, T and p as states
        from ..unknowns import Unknowns

        model = Unknowns(model)
    rng = np.random.default_rng(seed)
    n = model.n_states
    names = list(model.state_names) + list(model.control_names)
    report = CheckReport(model.name or type(model).__name__, int(samples), int(seed), float(tol))
    start, guess = _start(model)
    report.pieces.append(guess)
    y = _sample_points(model, samples, rng, start)
    checker = _Checker(y, names, tol)
    with plugin_code(model, "blocks()"):
        blocks = tuple(model.blocks())
    sides = _SupportWidth(model, blocks)

    for block in blocks:
        label = f"{block.name or 'block ' + str(block.coords)}"
        first = len(report.pieces)
        k = block.size
        psi = _sample_psi(k, samples, rng)
        for group in block.max_groups:
            report.pieces.append(checker.run(
                f"{label} max-group {group.name!r}",
                lambda yy, _ps, g=group: g.pieces(yy),
                value_shape=(None, k), grad_layout="max",
            ))
        for group in block.min_groups:
            report.pieces.append(checker.run(
                f"{label} min-group {group.name!r}",
                lambda yy, ps, g=group: g.pieces(yy, ps),
                value_shape=(None,), psi=psi,
            ))
            if group.values is not None:
                report.pieces.append(checker.values_agree(f"{label} min-group {group.name!r} values", group, psi))
        for term in block.signs:
            ball = term.ball  # a vector sign: s (N, k) and ∇s (N, k, n + m)
            report.pieces.append(checker.run(
                f"{label} sign term {term.name!r} switch",
                lambda yy, _ps, t=term: _as_group(t.switch(yy), None if t.ball is None else t.ball.dim),
                value_shape=(1,) if ball is None else (ball.dim,),
            ))
            if not isinstance(term.amplitude, (int, float)):
                report.pieces.append(checker.amplitude(f"{label} sign term {term.name!r} amplitude", term.amplitude))
            elif term.amplitude < 0:
                report.pieces.append(PieceCheck(f"{label} sign term {term.name!r} amplitude", "negative amplitude", 0.0,
                                                f"constant amplitude {term.amplitude} < 0"))
        if all(piece.ok for piece in report.pieces[first:]):  # a failing piece is its own row: the set needs it
            report.pieces.append(sides.check(f"{label} set", block, checker, start))
    with plugin_code(model, "surface()"):
        surface = model.surface()
    if surface is not None:
        states_only = _Checker(y[:, :n], names[:n], tol)
        report.pieces.append(states_only.run("surface e(x)", lambda yy, _ps: surface.function(yy), value_shape=(None,)))
    with plugin_code(model, "cost()"):
        cost = model.cost()
    if cost is not None:
        for kind, groups in (("max-group", cost.max_groups), ("min-group", cost.min_groups)):
            for index, fn in enumerate(groups):
                report.pieces.append(checker.run(f"cost {kind} {index + 1}", lambda yy, _ps, f=fn: f(yy), value_shape=(None,)))
        if cost.hessian is not None:  # the smooth integrand's gradient (its one piece's) against its Hessian
            report.pieces.append(checker.run(
                "cost Hessian", lambda yy, _ps: (np.asarray(cost.max_groups[0](yy)[1])[:, 0, :], cost.hessian(yy)),
                value_shape=(None,)))
        if cost.terminal is not None:  # M(x), then ∇M against ∇²M, at the sampled states
            states_only = _Checker(y[:, :n], names[:n], tol)
            report.pieces.append(states_only.run("terminal cost", lambda xx, _ps: _terminal(cost.terminal, xx, 0),
                                                 value_shape=(None,)))
            report.pieces.append(states_only.run("terminal cost Hessian",
                                                 lambda xx, _ps: _terminal(cost.terminal, xx, 1), value_shape=(None,)))
    return report


def _terminal(terminal: Callable, x: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """A terminal cost at every row of x as a group: (M (N, 1), ∇M (N, 1, n)) for order 0,
    (∇M (N, n), ∇²M (N, n, n)) for order 1."""
    values = [terminal(row) for row in np.asarray(x, dtype=float)]
    if order == 0:
        return (np.array([[float(v)] for v, _, _ in values]),
                np.array([np.asarray(g, dtype=float)[None, :] for _, g, _ in values]))
    return np.array([np.asarray(g, dtype=float) for _, g, _ in values]), np.array([np.asarray(h, dtype=float)
                                                                                   for _, _, h in values])


def _as_group(pair, dim: int | None = None):
    value, grad = pair
    value, grad = np.asarray(value), np.asarray(grad)
    if dim is not None:  # a BallSwitch
        if value.ndim != 2 or grad.ndim != 3 or value.shape[1] != dim or grad.shape[1] != dim:
            raise _Failed("bad shape", f"vector switch returned shapes {value.shape} and {grad.shape}, expected "
                                       f"(N, {dim}) and (N, {dim}, n + m)")
        return value, grad
    if value.ndim != 1 or grad.ndim != 2:
        raise _Failed("bad shape", f"switch returned shapes {value.shape} and {grad.shape}, expected (N,) and (N, n + m)")
    return value[:, None], grad[:, None, :]


START_POINTS = 11  # the start is checked (and the sample box built) on this many points of [0, T]


def _start(model: InclusionModel) -> tuple[np.ndarray | None, PieceCheck]:
    """The start y = (x, u) of `initial_guess()` and `initial_controls()` on START_POINTS
    points of [0, T] (None if it is unusable) and the verdict on it: the right shapes
    ((N, n) for x and z, (N, m) for u) and finite values."""
    label = "initial_guess()"
    t = np.linspace(0.0, model.T, START_POINTS)
    n, m = model.n_states, model.n_controls
    try:
        x, z = model.initial_guess(t)
        u = model.initial_controls(t)
    except Exception as exc:  # a model's own bug: report it, do not crash the check
        return None, PieceCheck(label, "error", float("nan"), f"{type(exc).__name__}: {exc}{_where(exc)}")
    arrays = (("x", x, n, "initial_guess()"), ("z", z, n, "initial_guess()"), ("u", u, m, "initial_controls()"))
    for what, array, width, method in arrays:
        array = np.asarray(array, dtype=float)
        if array.shape != (t.size, width):
            return None, PieceCheck(label, "bad shape", float("nan"), f"{method} returned {what} of shape {array.shape} "
                                                                      f"for {t.size} points, expected {(t.size, width)}")
        finite = np.isfinite(array)
        if not finite.all():
            node, column = (int(i) for i in np.argwhere(~finite)[0])
            names = model.control_names if what == "u" else model.state_names
            return None, PieceCheck(label, "non-finite", float("nan"),
                                    f"{method} returned {array[node, column]} for {what}[{names[column]!r}] at "
                                    f"t = {t[node]:.4g} (a start must be finite, at a free x_i(0) too)")
    start = np.asarray(x, float) if m == 0 else np.concatenate([np.asarray(x, float), np.asarray(u, float)], axis=1)
    return start, PieceCheck(label, "ok", 0.0)


def _where(exc: BaseException) -> str:
    import traceback

    frames = traceback.extract_tb(exc.__traceback__)
    return f" at {frames[-1].filename}:{frames[-1].lineno}" if frames else ""


class _SupportWidth:
    """c(F_b(y), ψ) + c(F_b(y), −ψ) per point: < 0 proves F_b(y) empty (sign terms with their band)."""

    def __init__(self, model: InclusionModel, blocks) -> None:
        from ..functional import Functional
        from ..schemes.grid import Grid

        self.model = model
        self.functional = Functional(model, Grid(float(model.T), 2), signs="band")  # evaluates sides at any points
        self.functional.blocks = blocks

    def widths(self, block, y: np.ndarray) -> np.ndarray:
        """The least width over the directions, per point of y (N,)."""
        from ..functional.psi import sphere_samples

        directions = np.array([[1.0]]) if block.size == 1 else sphere_samples(block.size, EMPTY_DIRECTIONS)
        zero = np.zeros((y.shape[0], self.model.n_states))
        least = np.full(y.shape[0], np.inf)
        for psi in directions:
            psi = np.tile(psi, (y.shape[0], 1))
            width = -self.functional.pieces.side(block, y, zero, psi).ell - self.functional.pieces.side(block, y, zero, -psi).ell
            least = np.minimum(least, width)
        return least

    def check(self, label: str, block, checker: "_Checker", start: np.ndarray | None) -> PieceCheck:
        try:
            at_samples = self.widths(block, checker.y)
            along = self.widths(block, start) if start is not None else np.zeros(0)
        except Exception as exc:  # a piece that fails is reported on its own row
            return PieceCheck(label, "error", float("nan"), f"{type(exc).__name__}: {exc}")
        empty = at_samples < -EMPTY_TOL * (1.0 + np.abs(at_samples))
        empty_start = along < -EMPTY_TOL * (1.0 + np.abs(along))
        if empty.all():
            k = int(np.argmin(at_samples))
            return PieceCheck(label, "empty set", 0.0, f"F is empty at all {empty.size} sample points"
                              + (" and along the start" if empty_start.all() else "")
                              + f", e.g. at {checker._point(k)}: c(F, ψ) + c(F, −ψ) = {at_samples[k]:.3g} < 0")
        if empty_start.any():
            k = int(np.argmax(empty_start))
            t = np.linspace(0.0, self.model.T, START_POINTS)[k]
            return PieceCheck(label, "empty set", 0.0, f"F is empty along the start (initial_guess()) at t = {t:.4g}, "
                              f"{checker._point(k, start)}: c(F, ψ) + c(F, −ψ) = {along[k]:.3g} < 0; start where "
                              "F is non-empty")
        note = f"empty at {int(empty.sum())} of {empty.size} sample points, e.g. {checker._point(int(np.argmax(empty)))}" \
            if empty.any() else ""
        return PieceCheck(label, "ok", 0.0, note=note)


EMPTY_DIRECTIONS = 16  # directions of S_k at which a k-block's width is taken
EMPTY_TOL = 1e-8  # a width below −this·(1 + |width|) is negative: the set is empty


def _sample_points(model: InclusionModel, samples: int, rng: np.random.Generator,
                   start: np.ndarray | None = None) -> np.ndarray:
    """Uniform points in a box around x0, the end values, the start and a known solution (±1)."""
    n, m = model.n_states, model.n_controls
    t = np.linspace(0.0, model.T, START_POINTS)
    known = [model.x0[None, :]]
    if start is not None:
        known.append(start[:, :n])
    try:
        exact = model.exact_solution(t)
        if exact is not None:
            known.append(np.asarray(exact, float).reshape(t.size, n))
    except Exception:
        pass
    states = np.concatenate(known)
    states = states[np.all(np.isfinite(states), axis=1)]
    lo, hi = states.min(axis=0), states.max(axis=0)
    for j, value in zip(model.end_indices, model.end_values):
        lo[j], hi[j] = min(lo[j], value), max(hi[j], value)
    x = rng.uniform(lo - 1.0, hi + 1.0, size=(samples, n))
    if m == 0:
        return x
    if start is not None:
        ulo, uhi = start[:, n:].min(axis=0), start[:, n:].max(axis=0)
    else:
        ulo, uhi = np.zeros(m), np.zeros(m)
    return np.concatenate([x, rng.uniform(ulo - 1.0, uhi + 1.0, size=(samples, m))], axis=1)


def _sample_psi(k: int, samples: int, rng: np.random.Generator) -> np.ndarray:
    if k == 1:
        return rng.choice([-1.0, 1.0], size=(samples, 1))
    psi = rng.standard_normal((samples, k))
    return psi / np.linalg.norm(psi, axis=1, keepdims=True)


class _Checker:
    """Evaluates one group at the sample points and compares its gradient with differences."""

    def __init__(self, y: np.ndarray, names: list[str], tol: float) -> None:
        self.y, self.names, self.tol = y, names, tol
        self.samples, self.width = y.shape

    def run(self, label: str, fn: Callable, value_shape: tuple, grad_layout: str = "plain",
            psi: np.ndarray | None = None) -> PieceCheck:
        try:
            value, grad = self._evaluate(fn, self.y, psi, value_shape, grad_layout)
            worst, detail = self._compare(fn, value, grad, psi, value_shape, grad_layout)
        except _Failed as failure:
            return PieceCheck(label, failure.status, float("nan"), failure.detail)
        except Exception as exc:  # a model's own bug: report it, do not crash the check
            return PieceCheck(label, "error", float("nan"), f"{type(exc).__name__}: {exc}")
        if worst > self.tol:
            return PieceCheck(label, "wrong gradient", worst, detail)
        return PieceCheck(label, "ok", worst, detail)

    def values_agree(self, label: str, group, psi: np.ndarray) -> PieceCheck:
        """A min-group's optional `values(y, ψ)` against the values of its `pieces(y, ψ)`:
        the error of an entry is |values − pieces| / max(1, |pieces|), at most VALUES_TOL
        (the tolerance a solve checks them to: two formulas of the same numbers, not a
        finite difference)."""
        try:
            expected = np.asarray(group.pieces(self.y, psi)[0], dtype=float)
            given = np.asarray(group.values(self.y, psi), dtype=float)
        except Exception as exc:  # a model's own bug: report it, do not crash the check
            return PieceCheck(label, "error", float("nan"), f"{type(exc).__name__}: {exc}")
        if given.shape != expected.shape:
            return PieceCheck(label, "bad shape", float("nan"),
                              f"values have shape {given.shape}, pieces' values {expected.shape}")
        error = values_error(given, expected)
        worst = float(np.max(error, initial=0.0))
        if worst > VALUES_TOL:
            sample, piece = np.unravel_index(int(np.argmax(error)), error.shape)
            direction = ", ".join(f"{v:.4g}" for v in psi[sample])
            return PieceCheck(label, "values differ", worst,
                              f"values() gives {given[sample, piece]:.6g} for piece {piece + 1}, pieces() "
                              f"{expected[sample, piece]:.6g}, at {self._point(int(sample))}, ψ = ({direction})")
        return PieceCheck(label, "ok", worst)

    def amplitude(self, label: str, groups) -> PieceCheck:
        """A sign term's amplitude Σ_i max_q a_iq(y): each group's gradient, and a ≥ 0."""
        worst, total = 0.0, np.zeros(self.samples)
        for index, fn in enumerate(groups):
            piece = self.run(f"{label} group {index + 1}", lambda yy, _ps, f=fn: f(yy), value_shape=(None,))
            if not piece.ok:
                return PieceCheck(label, piece.status, piece.worst_error, f"group {index + 1}: {piece.detail}")
            worst = max(worst, piece.worst_error)
            total += np.asarray(fn(self.y)[0]).max(axis=1)
        if np.any(total < -1e-12):
            at = int(np.argmin(total))
            return PieceCheck(label, "negative amplitude", worst,
                              f"a(y) = {total[at]:.3g} < 0 at {self._point(at)} (a Sgn amplitude must be ≥ 0)")
        return PieceCheck(label, "ok", worst)

    # -- evaluation with shape and finiteness checks
    def _evaluate(self, fn, y, psi, value_shape, grad_layout):
        rows = y.shape[0]
        value, grad = fn(y, None if psi is None else psi)
        value, grad = np.asarray(value, dtype=float), np.asarray(grad, dtype=float)
        expected_value = (rows,) + value_shape
        if value.ndim != len(expected_value) or any(e is not None and e != a for e, a in zip(expected_value, value.shape)):
            raise _Failed("bad shape", f"values have shape {value.shape}, expected {_shape(expected_value)}")
        expected_grad = value.shape + (self.width,)
        if grad.shape != expected_grad:
            raise _Failed("bad shape", f"gradients have shape {grad.shape}, expected {expected_grad}")
        for what, array in (("value", value), ("gradient", grad)):
            finite = np.isfinite(array)
            if not finite.all():
                at = int(np.argwhere(~finite)[0][0])
                raise _Failed("non-finite", f"a {what} is {array.reshape(rows, -1)[at][~finite.reshape(rows, -1)[at]][0]} "
                                            f"at {self._point(at, y)}")
        return value, grad

    def _values(self, fn, y, psi):
        value, _ = fn(y, psi)
        return np.asarray(value, dtype=float)

    def _compare(self, fn, value, grad, psi, value_shape, grad_layout):
        error = self._errors(fn, grad, psi, 1e-6)
        if np.max(error) > self.tol:  # maybe a kink within the step: difference again, 100× finer
            error = np.minimum(error, self._errors(fn, grad, psi, 1e-8))
        worst = float(np.max(error))
        index = np.unravel_index(int(np.argmax(error)), error.shape)
        sample, column = int(index[0]), int(index[-1])
        detail = f"∂/∂{self.names[column]} at {self._point(sample)}"
        if worst > self.tol:
            fd = self._fd(fn, psi, 1e-6)
            detail = (f"∂/∂{self.names[column]} is {grad[index]:.6g}, finite differences give {fd[index]:.6g}, "
                      f"at {self._point(sample)}")
        return worst, detail

    def _fd(self, fn, psi, relative):
        y, (s, w) = self.y, self.y.shape
        step = relative * np.maximum(1.0, np.abs(y))  # (S, W)
        shift = np.zeros((w, s, w))
        shift[np.arange(w), :, np.arange(w)] = step.T
        plus = (y[None] + shift).reshape(w * s, w)
        minus = (y[None] - shift).reshape(w * s, w)
        psi_rep = None if psi is None else np.tile(psi, (w, 1))
        with np.errstate(all="ignore"):
            up, down = self._values(fn, plus, psi_rep), self._values(fn, minus, psi_rep)
        diff = (up - down).reshape((w, s) + up.shape[1:])
        diff = diff / (2.0 * step.T.reshape((w, s) + (1,) * (up.ndim - 1)))
        return np.moveaxis(diff, 0, -1)  # (S, …, W)

    def _errors(self, fn, grad, psi, relative):
        fd = self._fd(fn, psi, relative)
        error = np.abs(fd - grad) / np.maximum(1.0, np.abs(grad))
        return np.where(np.isfinite(error), error, np.inf)

    def _point(self, sample: int, y: np.ndarray | None = None) -> str:
        row = (self.y if y is None else y)[sample]
        return "(" + ", ".join(f"{name} = {value:.4g}" for name, value in zip(self.names, row)) + ")"


def _shape(shape: tuple) -> str:
    return "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"


# ------------------------------------------------------------------ command line






def add_check_parser(subparsers) -> argparse.ArgumentParser:
    """Add `check-model` to the `qdframe` command's subparsers (cli.build_parser)."""
    parser = subparsers.add_parser("check-model", help="check a model's pieces and gradients against finite differences")
    parser.add_argument("model", help="model name (see `qdframe list`)")
    parser.add_argument("--samples", type=integer(1), default=64, help="random points (default 64)")
    parser.add_argument("--seed", type=integer(0), default=0, help="random seed (default 0)")
    parser.add_argument("--tol", type=positive_float, default=1e-6,
                        help="largest gradient error |fd − ∂|/max(1, |∂|) accepted (default 1e-6)")
    parser.add_argument("--json", metavar="FILE", help="write the report as JSON")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    return parser


def main_check(args: argparse.Namespace) -> int:
    """Run `qdframe check-model`: print the table; a failure raises ModelCheckError (exit 1)."""
    from ..registry import load_model

    if args.json:
        parent = Path(args.json).expanduser().resolve().parent
        if Path(args.json).is_dir() or not parent.is_dir():
            raise InputError("--json", "a file path in an existing, writable directory", args.json)
    model = load_model(args.model)
    report = check_model(model, samples=args.samples, seed=args.seed, tol=args.tol)
    if args.json:
        Path(args.json).write_text(json.dumps(report.to_dict(), indent=1) + "\n")
    if not args.quiet:
        print(report.table())
    if not report.ok:
        raise ModelCheckError(report.message())
    return 0
