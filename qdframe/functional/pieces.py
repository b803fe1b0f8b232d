"""The model's pieces at ψ: each block's ℓ(ψ) = <z_b, ψ> − c(F_b(y), ψ) and its parts.

The support function of a block (paper (support), (supf), (subf)) is

    c(F_b(y), ψ) = Σ_j max_q <f_jq(y), ψ> + Σ_j min_p g_jp(y, ψ) + Σ_i a_i(y)·c(Sgn(s_i), ψ),

evaluated here for all nodes at once and checked (shape, finiteness: a NaN names its
piece and node). ψ* = argmax_ψ ℓ(ψ): in closed form (ψ = ±1) for a one-coordinate block,
searched on S_k (:mod:`.psi`, Remark 5.1) for a block of k coordinates, once per
iterate. h_b = max(0, ℓ(ψ*)) is the distance of z_b from F_b (paper (3.13)).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ..errors import ModelOutputError
from ..schemes.grid import Grid
from ..model import InclusionModel, SetBlock
from .psi import maximize_on_sphere, sphere_samples

FACE_TOL = 1e-7  # a max-group's vertex is on the face ψ* exposes: <f_q, ψ*> within this (relative) of the maximum
FACE_STEP = 1e-6  # the central difference of a min-group's support along S_k at ψ*
VALUES_TOL = 1e-9  # a min-group's `values` agrees with its pieces' values to this, relative to max(1, |g|)
VALUES_CHECK_NODES = 64  # nodes (spread over the grid) where a functional compares `values` with the pieces
VALUES_CHECK_DIRECTIONS = 32  # directions of S_k per node there


def values_error(given: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """|values − pieces' values| / max(1, |pieces' values|) per entry: 0 where the two are
    equal (infinities included) or both NaN, inf where only one is NaN."""
    with np.errstate(invalid="ignore"):
        error = np.abs(given - expected) / np.maximum(1.0, np.abs(expected))
        error = np.where((given == expected) | (np.isnan(given) & np.isnan(expected)), 0.0, error)
    return np.where(np.isnan(error), np.inf, error)


@dataclass
class _Piece:
    """One group of pieces at ψ: values (N, m) and gradients (N, m, n + m)."""

    values: np.ndarray
    grads: np.ndarray


@dataclass
class _SignPart:
    """A sign term at ψ: κ = c(Sgn, ψ) (ψλ with a selection), its gradient, the amplitude a."""

    kappa: np.ndarray  # (N,)
    kappa_grad: np.ndarray  # (N, n + m + p): dκ/dy (the band's slope·∇s, or ψ on λ's column)
    amplitude: np.ndarray  # (N,) a(y)
    groups: list[_Piece]  # a = Σ_i max_q a_iq


@dataclass
class _Side:
    """A block evaluated at ψ (N, k): ℓ(ψ) = <z, ψ> − c(F_b, ψ) and its groups.

    `faces`: for a block of k ≥ 2 coordinates at ψ*, (nodes, [λ (nodes, m) per max-group])
    where a max-group's face exposed by ψ* has several vertices and the nearest point's
    decomposition over the faces is unique (:func:`_faces`): there h is smooth in y
    and its gradient takes each group's vertices weighted by λ, not one active vertex."""

    psi: np.ndarray
    ell: np.ndarray
    max_parts: list[_Piece]  # values <f_q, ψ>, gradients ψᵀ ∂f_q/∂y
    min_parts: list[_Piece]  # values g_p(y, ψ), gradients ∂g_p/∂y
    sign_parts: list[_SignPart]
    faces: tuple[np.ndarray, list[np.ndarray]] | None = None

    @property
    def h(self) -> np.ndarray:
        return np.maximum(0.0, self.ell)

    def gradient(self, width: int) -> np.ndarray:
        """∂ℓ/∂y (N, width) from the active piece of every group (a generalized-Jacobian
        element); y = (x, u, λ), the pieces' gradients fill the first n + m columns."""
        rows = np.arange(self.ell.size)
        grad = np.zeros((self.ell.size, width))
        for index, part in enumerate(self.max_parts):
            active = part.grads[rows, np.argmax(part.values, axis=1)]
            if self.faces is not None:  # a face of several vertices: λ-weighted, ∂ψ*ᵀΣλf/∂y
                at, weights = self.faces
                active[at] = np.einsum("nq,nqd->nd", weights[index], part.grads[at])
            grad[:, : part.grads.shape[-1]] -= active
        for part in self.min_parts:
            grad[:, : part.grads.shape[-1]] -= part.grads[rows, np.argmin(part.values, axis=1)]
        for sign in self.sign_parts:
            grad -= sign.amplitude[:, None] * sign.kappa_grad
            for piece in sign.groups:
                grad[:, : piece.grads.shape[-1]] -= sign.kappa[:, None] * piece.grads[rows, np.argmax(piece.values, axis=1)]
        return grad

    @staticmethod
    def choose(upper: np.ndarray, a: "_Side", b: "_Side") -> "_Side":
        """Per node, side `a` where `upper` else side `b` (same block, same groups)."""

        def pick(u, v):
            mask = upper.reshape(upper.shape + (1,) * (u.ndim - 1))
            return np.where(mask, u, v)

        return _Side(
            pick(a.psi, b.psi),
            pick(a.ell, b.ell),
            [_Piece(pick(p.values, q.values), pick(p.grads, q.grads)) for p, q in zip(a.max_parts, b.max_parts)],
            [_Piece(pick(p.values, q.values), pick(p.grads, q.grads)) for p, q in zip(a.min_parts, b.min_parts)],
            [
                _SignPart(pick(p.kappa, q.kappa), pick(p.kappa_grad, q.kappa_grad), p.amplitude, p.groups)
                for p, q in zip(a.sign_parts, b.sign_parts)
            ],
        )


class Pieces:
    """Evaluates and checks a model's pieces at the nodes: each takes the block it evaluates
    and y = (x, u) (N, n + m), z (N, n) and, for the sign terms with selections, their
    (column, sense·λ, sense) (:meth:`~qdframe.functional.layout.Layout.block_selections`)."""

    model: InclusionModel  # named in the messages of a piece that fails its check
    grid: Grid  # the node times in those messages
    n: int  # states (the state printed where `values` disagrees with `pieces`)
    args: int  # n + m, the width of y = (x, u)
    width: int  # n + m + p, the width of a side's gradient in (x, u, λ)
    psi_samples: int  # the samples of S_k of ψ*'s search

    def __init__(self, model: InclusionModel, grid: Grid, n: int, args: int, width: int, psi_samples: int) -> None:
        self.model, self.grid, self.n, self.args, self.width = model, grid, n, args, width
        self.psi_samples = psi_samples
        self._psi_memo: dict[int, list[tuple[bytes, np.ndarray]]] = {}  # per S_k block: recent (inputs, ψ*)
        self._values_checked: set[int] = set()  # min-groups whose `values` agreed with their pieces once

    def state(self, block: SetBlock, y: np.ndarray, z: np.ndarray, selections: list | None = None) -> _Side:
        """`block` at its ψ*: :meth:`state_1d` or :meth:`state_sphere`."""
        return self.state_1d(block, y, z, selections) if block.size == 1 else self.state_sphere(block, y, z)

    def check(self, label: str, array: np.ndarray, shape: tuple[int | None, ...]) -> None:
        array = np.asarray(array)
        if array.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, array.shape)):
            expected = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
            raise ModelOutputError(
                f"model {self.model.name!r}: {label} returned shape {array.shape}, expected {expected}", label=label
            )
        finite = np.isfinite(array)
        if not finite.all():
            bad = np.argwhere(~finite)[0]
            node = int(bad[0])
            per_node = array.shape[0] == self.grid.nodes
            when = f" (t = {self.grid.t[node]:.6g})" if per_node else ""
            raise ModelOutputError(
                f"model {self.model.name!r}: {label} returned a non-finite value at node {node}{when}",
                label=label, node=node if per_node else None, nonfinite=True,
            )

    def scalar_pieces(self, fn, x: np.ndarray, label: str) -> tuple[np.ndarray, np.ndarray]:
        values, grads = fn(x)
        self.check(label, values, (x.shape[0], None))
        self.check(f"{label} gradient", grads, (x.shape[0], values.shape[1], self.args))
        return values, grads

    def max_group(self, block: SetBlock, group, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        f, jac = group.pieces(x)
        label = f"block {block.name or block.coords} max-group {group.name!r}"
        self.check(label, f, (x.shape[0], None, block.size))
        self.check(f"{label} Jacobian", jac, (x.shape[0], f.shape[1], block.size, self.args))
        return f, jac

    def min_group(self, block: SetBlock, group, x: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g, grad = group.pieces(x, psi)
        label = f"block {block.name or block.coords} min-group {group.name!r}"
        self.check(label, g, (x.shape[0], None))
        self.check(f"{label} gradient", grad, (x.shape[0], g.shape[1], self.args))
        return g, grad

    def _check_values(self, block: SetBlock, y: np.ndarray) -> None:
        """Each min-group's `values` against its pieces' values, once per functional, at
        VALUES_CHECK_NODES nodes spread over the grid and VALUES_CHECK_DIRECTIONS directions
        of S_k each: the search of ψ* trusts `values`, and one that disagreed would find a
        wrong ψ* and make h, the inclusion check included, too small."""
        groups = [group for group in block.min_groups if group.values is not None and id(group) not in self._values_checked]
        if not groups:
            return
        nodes = np.unique(np.linspace(0, y.shape[0] - 1, min(y.shape[0], VALUES_CHECK_NODES)).astype(int))
        directions = sphere_samples(block.size, VALUES_CHECK_DIRECTIONS)
        x = np.repeat(y[nodes], len(directions), axis=0)
        psi = np.tile(directions, (nodes.size, 1))
        for group in groups:
            label = f"block {block.name or block.coords} min-group {group.name!r}"
            expected = np.asarray(group.pieces(x, psi)[0])
            g = np.asarray(group.values(x, psi))
            if g.shape != expected.shape:
                raise ModelOutputError(f"model {self.model.name!r}: {label}: values(x, ψ) returned shape {g.shape}, "
                                       f"pieces(x, ψ) values of shape {expected.shape}", label=f"{label} values")
            wrong = values_error(g, expected) > VALUES_TOL
            if wrong.any():
                row, piece = (int(i) for i in np.argwhere(wrong)[0])
                node = int(nodes[row // len(directions)])
                state = ", ".join(f"{v:.6g}" for v in x[row, : self.n])
                direction = ", ".join(f"{v:.6g}" for v in psi[row])
                raise ModelOutputError(
                    f"model {self.model.name!r}: {label}: values(x, ψ) gives {g[row, piece]:.9g} for piece "
                    f"{piece + 1}, pieces(x, ψ) {expected[row, piece]:.9g}, at node {node} "
                    f"(t = {self.grid.t[node]:.6g}, x = ({state}), ψ = ({direction})); `values` must return "
                    f"the values of `pieces` (qdframe check-model finds such errors)", label=f"{label} values", node=node)
            self._values_checked.add(id(group))

    def switch(self, block: SetBlock, term, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """s (N,) and ∇s (N, n + m) of a sign term of `block`, checked; a vector sign's
        (:class:`~qdframe.model.BallSwitch`, k components) s (N, k) and ∇s (N, k, n + m)."""
        label = f"block {block.name or block.coords} sign term {term.name!r}"
        s, ds = term.switch(y)
        ball = term.ball
        self.check(f"{label} switch", s, (y.shape[0],) if ball is None else (y.shape[0], ball.dim))
        self.check(f"{label} switch gradient", ds,
                   (y.shape[0], self.args) if ball is None else (y.shape[0], ball.dim, self.args))
        return s, ds

    def _amplitude(self, block: SetBlock, term, y: np.ndarray) -> tuple[np.ndarray, list[_Piece]]:
        """A sign term's a(y) = Σ_i max_q a_iq(y) (N,) and its groups."""
        if isinstance(term.amplitude, (int, float)):
            return np.full(y.shape[0], float(term.amplitude)), []
        label = f"block {block.name or block.coords} sign term {term.name!r}"
        groups = [_Piece(*self.scalar_pieces(fn, y, f"{label} amplitude")) for fn in term.amplitude]
        return sum(_reduce_last(np.maximum, piece.values) for piece in groups), groups

    def amplitude_values(self, block: SetBlock, term, y: np.ndarray) -> np.ndarray:
        """:meth:`_amplitude`'s a(y) alone: each group's gradients let go as soon as it is
        evaluated (an l1 norm of six states is six groups of (N, 2, n + m) gradients)."""
        if isinstance(term.amplitude, (int, float)):
            return np.full(y.shape[0], float(term.amplitude))
        label = f"block {block.name or block.coords} sign term {term.name!r}"
        return sum(_reduce_last(np.maximum, self.scalar_pieces(fn, y, f"{label} amplitude")[0]) for fn in term.amplitude)

    def _sign_part(self, block: SetBlock, term, y: np.ndarray, psi: np.ndarray,
                   selection: tuple[int, np.ndarray] | None = None) -> _SignPart:
        """c(a(y)·Sgn(s), ψ) = a(y)·κ of a sign term, ψ = ±1 per node (model.SignTerm):
        κ = ψλ with a selection (column, λ), else the band's κ_ψ(s)."""
        amplitude, groups = self._amplitude(block, term, y)
        kappa_grad = np.zeros((y.shape[0], self.width))
        if selection is not None:  # the point sense·a·λ of Filippov's set: c = a·ψ·sense·λ
            column, signed, sense = selection
            kappa_grad[:, column] = psi * sense
            return _SignPart(psi * signed, kappa_grad, amplitude, groups)
        s, ds = self.switch(block, term, y)
        if term.ball is not None:
            kappa, slope = _ball_band_kappa(term.band, s, term.component, psi * term.sense)
            if slope is not None:
                kappa_grad[:, : self.args] = np.einsum("nk,nkd->nd", slope, ds)
            return _SignPart(kappa, kappa_grad, amplitude, groups)
        kappa, slope = _band_kappa(term.band, s, psi * term.sense)  # c(−a·Sgn(s), ψ) = c(a·Sgn(s), −ψ)
        if slope is not None:
            kappa_grad[:, : self.args] = slope[:, None] * ds
        return _SignPart(kappa, kappa_grad, amplitude, groups)

    def side(self, block: SetBlock, y: np.ndarray, z: np.ndarray, psi: np.ndarray,
             maxes: list[tuple[np.ndarray, np.ndarray]] | None = None,
             selections: list | None = None) -> _Side:
        """All groups of `block` at ψ (N, k); `maxes` reuses evaluated max-groups."""
        if maxes is None:
            maxes = [self.max_group(block, group, y) for group in block.max_groups]
        ell = np.einsum("nk,nk->n", z[:, list(block.coords)], psi)
        max_parts = [_Piece(np.einsum("nqk,nk->nq", f, psi), np.einsum("nqkd,nk->nqd", jac, psi)) for f, jac in maxes]
        min_parts = [_Piece(*self.min_group(block, group, y, psi)) for group in block.min_groups]
        selections = selections or [None] * len(block.signs)
        sign_parts = [self._sign_part(block, term, y, psi[:, 0], sel) for term, sel in zip(block.signs, selections)]
        for part in max_parts:
            ell -= part.values.max(axis=1)
        for part in min_parts:
            ell -= part.values.min(axis=1)
        for part in sign_parts:
            ell -= part.kappa * part.amplitude
        return _Side(psi, ell, max_parts, min_parts, sign_parts)

    def sides_1d(self, block: SetBlock, y: np.ndarray, z: np.ndarray, selections: list | None = None) -> list[_Side]:
        """A one-coordinate block at ψ = +1 and ψ = −1."""
        maxes = [self.max_group(block, group, y) for group in block.max_groups]
        ones = np.ones((y.shape[0], 1))
        return [self.side(block, y, z, ones, maxes, selections), self.side(block, y, z, -ones, maxes, selections)]

    def state_1d(self, block: SetBlock, y: np.ndarray, z: np.ndarray, selections: list | None = None) -> _Side:
        """ψ ∈ {−1, +1}: ψ* in closed form (the nearer violated end of the interval)."""
        plus, minus = self.sides_1d(block, y, z, selections)
        return _Side.choose(plus.ell >= minus.ell, plus, minus)

    def state_sphere(self, block: SetBlock, y: np.ndarray, z: np.ndarray) -> _Side:
        """ψ ∈ S_k: ψ* searched numerically, vectorized over nodes (Remark 5.1), once per
        iterate: the last few ψ* are kept per block under a 256-bit BLAKE2b digest of their
        inputs' bytes (y, z_b and the sample count), so a repeated iterate reuses its ψ* and
        different inputs do not (a collision is as unlikely as one of BLAKE2b's), without
        keeping a copy of each input (at N = 1e5, 3.2 MB per entry on paper-7.2). A new
        iterate's search starts from the ψ* used last (:mod:`.psi`'s warm start)."""
        nodes, k = y.shape[0], block.size
        zb = z[:, list(block.coords)]
        maxes = [self.max_group(block, group, y) for group in block.max_groups]
        digest = hashlib.blake2b(np.int64([self.psi_samples, *y.shape, *zb.shape]).tobytes(), digest_size=32)
        digest.update(np.ascontiguousarray(y, dtype=float))
        digest.update(np.ascontiguousarray(zb, dtype=float))
        key = digest.digest()
        memo = self._psi_memo.setdefault(id(block), [])
        hit = next((i for i, (inputs, _) in enumerate(memo) if inputs == key), None)
        if hit is not None:  # the last used first: the next iterate's warm start
            memo.insert(0, memo.pop(hit))
            psi = memo[0][1]
        else:
            self._check_values(block, y)
            rows: dict = {}  # (node subset, samples per node) -> the subset, z_b, each max-group's f, y per sample

            def ell(psi: np.ndarray, at: np.ndarray | None = None) -> np.ndarray:  # psi (n, M, k) -> (n, M)
                count = psi.shape[1]
                key = (None if at is None else id(at), count)  # `at` stays alive in `rows`: its id is not reused
                if key not in rows:  # gathered once per subset and chunk size, not at every call
                    y_at, zb_at = (y, zb) if at is None else (y[at], zb[at])
                    y_rep = y_at if count == 1 else np.repeat(y_at, count, axis=0)
                    rows[key] = at, zb_at, [f if at is None else f[at] for f, _ in maxes], y_rep
                _, zb_at, fs, y_rep = rows[key]
                value = np.einsum("nk,nmk->nm", zb_at, psi)
                for f in fs:
                    value -= _reduce_last(np.maximum, np.einsum("nqk,nmk->nmq", f, psi))
                if block.min_groups:
                    flat = psi.reshape(zb_at.shape[0] * count, k)
                    for group in block.min_groups:
                        g = group.values(y_rep, flat) if group.values is not None else group.pieces(y_rep, flat)[0]
                        value -= _reduce_last(np.minimum, g.reshape(zb_at.shape[0], count, -1))
                return value

            # warm: from the ψ* found last for this block (the previous iterate, or trial point)
            psi = maximize_on_sphere(ell, nodes, k, samples=self.psi_samples, start=memo[0][1] if memo else None)
            memo.insert(0, (key, psi))
            del memo[4:]
        side = self.side(block, y, z, psi.copy(), maxes)
        side.faces = _faces(block, y, zb, side, maxes)
        return side

    def interval_distance(self, block: SetBlock, y: np.ndarray, z: np.ndarray, selections: list | None = None) -> np.ndarray:
        """h_b = max(0, ℓ(+1), ℓ(−1)) of a one-coordinate block from the pieces' values alone:
        :meth:`state_1d`'s h, bit for bit, with the pieces that do not depend on ψ evaluated
        once, in its order (a NaN names the same piece)."""
        plus, minus, _ = self.interval_sides(block, y, z, selections)
        return np.maximum(0.0, np.maximum(plus, minus))

    def interval_sides(self, block: SetBlock, y: np.ndarray, z: np.ndarray,
                       selections: list | None = None) -> tuple[np.ndarray, np.ndarray, bool]:
        """ℓ(+1) and ℓ(−1) of a one-coordinate block from the pieces' values alone, and whether
        its set is a point (one-piece max-groups, no min-groups, every sign term with its
        selection: then ℓ(−1) = −ℓ(+1), z_b − f_b(y), an equation)."""
        nodes = y.shape[0]
        selections = selections or [None] * len(block.signs)

        def minima(psi: float) -> list[np.ndarray]:
            return [_reduce_last(np.minimum, self.min_group(block, group, y, np.full((nodes, 1), psi))[0])
                    for group in block.min_groups]

        maxes = [self.max_group(block, group, y)[0][:, :, 0] for group in block.max_groups]
        upper = minima(1.0)
        signs = [(term, selection, self.amplitude_values(block, term, y),
                  None if selection is not None else self.switch(block, term, y)[0])
                 for term, selection in zip(block.signs, selections)]
        lower = minima(-1.0)

        def ell(psi: float, mins: list[np.ndarray]) -> np.ndarray:
            """ℓ(ψ) = zψ − c(F_b, ψ), as :meth:`side` sums it."""
            value = z[:, block.coords[0]] * psi
            for f in maxes:
                value -= _reduce_last(np.maximum, f * psi)
            for g in mins:
                value -= g
            for term, selection, amplitude, s in signs:
                value -= (psi * selection[1] if selection is not None
                          else _ball_band_kappa(term.band, s, term.component, psi * term.sense)[0]
                          if term.ball is not None else _band_kappa(term.band, s, psi * term.sense)[0]) * amplitude
            return value

        point = not block.min_groups and all(f.shape[1] == 1 for f in maxes) and all(
            selection is not None for selection in selections)
        return ell(1.0, upper), ell(-1.0, lower), point


def _faces(block: SetBlock, y: np.ndarray, zb: np.ndarray, side: _Side,
           maxes: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, list[np.ndarray]] | None:
    """Where a max-group's face exposed by ψ* has several vertices (values within
    FACE_TOL of the group's maximum), the weights λ of the nearest point's decomposition.

    h = max_ψ ℓ(y, ψ) is a max over ψ of a min over each group's vertices, and ψ* moves
    with y: formula (4.5), co{−ψ*ᵀ∂f_q : q active}, is then not h's superdifferential.
    By Danskin's theorem applied to h = min over λ_j ∈ simplices of ‖z − Σ_j Σ_q λ_jq f_jq
    − (the min-groups' support points)‖, h's superdifferential is co{−ψ*ᵀ Σ λ_jq ∂f_jq} over
    the minimizing λ: one point where λ is unique, which it is unless vertices of the
    faces are affinely dependent (duplicates, collinear, parallel faces of two groups).
    λ solves the tangential condition of ψ*'s optimality, P(z − Σ λ_jq f_jq − Σ ∇_ψ g) = 0
    with P = I − ψ*ψ*ᵀ, and Σ_q λ_jq = 1 per group (∇_ψ g of each min-group by central
    differences at ψ*). Nodes where λ is not unique keep (4.5)'s set (a superset of the
    true one). None where no node has such a face."""
    if not maxes or block.signs:
        return None
    psi = side.psi
    actives = []
    for part in side.max_parts:
        top = part.values.max(axis=1, keepdims=True)
        spread = top - part.values.min(axis=1, keepdims=True)
        actives.append(part.values >= top - FACE_TOL * (1.0 + np.abs(top) + spread))
    at = np.flatnonzero(np.logical_or.reduce([a.sum(axis=1) >= 2 for a in actives]) & (side.ell > 0))
    if at.size == 0:
        return None
    k = psi.shape[1]
    project = np.eye(k) - np.einsum("ni,nj->nij", psi[at], psi[at])  # P per node
    target = np.einsum("nij,nj->ni", project, zb[at])
    for group in block.min_groups:  # −P∇_ψ min_p g_p, by central differences along P e_i
        values = group.values if group.values is not None else (lambda x, q, g=group: g.pieces(x, q)[0])
        step = FACE_STEP * project  # (n, k, k): row i is the step along P e_i
        y_rep = np.repeat(y[at], k, axis=0)
        ahead = _reduce_last(np.minimum, np.asarray(values(y_rep, (psi[at, None, :] + step).reshape(-1, k))))
        behind = _reduce_last(np.minimum, np.asarray(values(y_rep, (psi[at, None, :] - step).reshape(-1, k))))
        target -= ((ahead - behind) / (2.0 * FACE_STEP)).reshape(at.size, k)
    columns = [np.where(a[at, :, None], f[at], 0.0) for a, (f, _) in zip(actives, maxes)]  # (n, m_j, k)
    tangential = np.concatenate([np.einsum("nij,nqj->niq", project, c) for c in columns], axis=2)
    sums = [np.zeros((at.size, len(columns), c.shape[1])) for c in columns]
    for j, (a, simplex) in enumerate(zip(actives, sums)):
        simplex[:, j, :] = a[at]
    system = np.concatenate([tangential, np.concatenate(sums, axis=2)], axis=1)  # (n, k + G, Σm)
    rhs = np.concatenate([target, np.ones((at.size, len(columns)))], axis=1)
    u, sigma, vt = np.linalg.svd(system, full_matrices=False)
    rank = (sigma > 1e-10 * sigma[:, :1]).sum(axis=1)
    unique = rank == sum(a[at].sum(axis=1) for a in actives)  # one λ: as many independent rows as active vertices
    inverse = np.where(sigma > 1e-10 * sigma[:, :1], 1.0 / np.where(sigma > 0, sigma, 1.0), 0.0)
    lam = np.einsum("nri,nr->ni", vt, inverse * np.einsum("njr,nj->nr", u, rhs))  # the least-squares λ
    at, lam = at[unique], lam[unique]
    if at.size == 0:
        return None
    weights, start = [], 0
    for a in actives:
        weights.append(lam[:, start : start + a.shape[1]])
        start += a.shape[1]
    return at, weights


def _reduce_last(ufunc: np.ufunc, values: np.ndarray) -> np.ndarray:
    """ufunc over the last (short) axis, one column at a time: `values.max(axis=-1)` for
    np.maximum, several times faster for a few pieces and many nodes, same values (NaN too)."""
    out = values[..., 0].copy()
    for column in range(1, values.shape[-1]):
        ufunc(out, values[..., column], out=out)
    return out


def _band_kappa(band: float, s: np.ndarray, psi: np.ndarray | float) -> tuple[np.ndarray, np.ndarray | None]:
    """κ_ψ(s) of a sign term without a selection (:class:`~qdframe.model.SignTerm`) and
    dκ/ds (None where it is 0): band β = inf, the whole interval a·[−1, 1] everywhere (a
    term on its own surface); β > 0, κ = 1 − 2·S(u), u = clip(−ψs/β, 0, 1), S(u) = 3u² − 2u³
    (C¹); β = 0, Filippov's exact sign, the whole interval only at s = 0."""
    if np.isinf(band):
        return np.ones_like(s), None
    if band > 0:
        u = np.clip(-psi * s / band, 0.0, 1.0)
        return 1.0 - 2.0 * u * u * (3.0 - 2.0 * u), 12.0 * u * (1.0 - u) * psi / band
    return np.where(psi * s >= 0, 1.0, -1.0), None


def _ball_band_kappa(band: float, s: np.ndarray, component: int,
                     psi: np.ndarray | float) -> tuple[np.ndarray, np.ndarray | None]:
    """κ_ψ of component j of a vector sign without a selection (:class:`~qdframe.model.SignTerm`)
    and dκ/ds (N, k) (None where it is 0): the support function of the interval
    [m − h, m + h], m = w·s_j/|s|, h = 1 − w, w = S(min(|s|/β, 1)), S(u) = 3u² − 2u³, at ψ:
    κ = ψ·m + h. It holds s_j/|s| (|m − s_j/|s|| ≤ h), is the whole [−1, 1] at s = 0 and the
    point s_j/|s| for |s| ≥ β, C¹ in s (w/|s| → 0 at s = 0). β = inf: [−1, 1] everywhere;
    β = 0: s_j/|s|, the whole interval at s = 0 only."""
    nodes, k = s.shape
    radius = np.linalg.norm(s, axis=1)
    psi = np.broadcast_to(np.asarray(psi, dtype=float), (nodes,))
    if np.isinf(band):
        return np.ones(nodes), None
    with np.errstate(divide="ignore", invalid="ignore"):
        unit = np.where(radius[:, None] > 0, s / radius[:, None], 0.0)
    if band == 0:
        return np.where(radius > 0, psi * unit[:, component], 1.0), None
    u = np.minimum(radius / band, 1.0)
    w = u * u * (3.0 - 2.0 * u)
    slope_w = np.where(u < 1.0, 6.0 * u * (1.0 - u) / band, 0.0)  # dw/d|s|
    kappa = psi * w * unit[:, component] + 1.0 - w
    with np.errstate(divide="ignore", invalid="ignore"):
        over = np.where(radius > 0, w / radius, 0.0)  # w/|s| (→ 3|s|/β² at 0)
    e = np.zeros(k)
    e[component] = 1.0
    # d(w·s_j/|s|)/ds = (w/|s|)(e_j − ŝ_j ŝ) + ŝ_j·w'·ŝ;  d(1 − w)/ds = −w'·ŝ
    dm = over[:, None] * (e[None, :] - unit[:, component, None] * unit) + (unit[:, component] * slope_w)[:, None] * unit
    return kappa, psi[:, None] * dm - slope_w[:, None] * unit
