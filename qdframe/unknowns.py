"""Free end time and unknown parameters: the problem restated with constant states.

A model whose end time T is free (``free_T``) or which declares unknown parameters p
(``parameter_names``) is solved as an ordinary model, :class:`Unknowns`, on the scaled
time s = t/T ∈ [0, 1] (when T is free) with the unknowns as states that do not move:

    X(s) = x(s·T),   X' ∈ T·F(X, p, u),   σ_p' = 0,   σ_T' = 0,

T = b_T(σ_T) and p_i = b_i(σ_i), each b a smooth increasing map from R onto the open
interval (lo, hi) of its bounds: the identity without bounds, lo + e^σ or hi − e^−σ with
one, lo + (hi − lo)/(1 + e^−σ) with both; T's bounds are (0, ∞) unless the model says
otherwise (``T_bounds``). T = 0 with x constant meets every periodic condition: from a poor
guess a periodic orbit can shrink towards it, which the first guess's sweep along the
motion (:func:`qdframe.solve.start.swept_T`) avoids, ``T_bounds = (lo, hi)``, lo > 0, forbids and the
verdict never calls solved (:func:`qdframe.descent.checks.closed_by_tolerance`). For T > 0 the support function
of T·F is T·c(F, ψ): every max-group, min-group and sign amplitude of the model is scaled
by T, a switch s(y) is not (Sgn(s) does not change), the cost integrand is scaled by T
(∫ c dt = ∫ T·c ds) and the surface is not. The σ's start and end free; the boundary,
periodic and surface conditions of the model are those of X. So T and p enter the
functional (paper (3.13)–(3.17)) through F alone, and every scheme, direction, start,
error estimate and certificate applies unchanged.

:func:`qdframe.solve.unwrap.unwrap` maps the result back: t = s·T, x = X, z = X'/T, ``result.T`` and
``result.parameters``. The bisection estimate compares the two solves in what the user is
given (:meth:`Unknowns.observed`: x at the user's times t = s·T, each solve with its own
T, then T and p), so it covers T, p and x at those times. A replay keeps the T found, so
its estimate, of X and the σ's, is multiplied by 1 + max_s |X'(s)|: to first order an
error ΔT moves every point by |ΔT|/T·s·|X'|.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping

import numpy as np

from .errors import InputError
from .model import BallSwitch, Cost, InclusionModel, MaxGroup, MinGroup, SetBlock, SignTerm, Surface


T_NAME = "T"


@dataclasses.dataclass(frozen=True)
class Bound:
    """b: R → (lo, hi), smooth and increasing, with its derivative and inverse."""

    lo: float = -np.inf
    hi: float = np.inf

    def value(self, sigma: np.ndarray) -> np.ndarray:
        lo, hi = self.lo, self.hi
        if np.isfinite(lo) and np.isfinite(hi):
            return lo + (hi - lo) / (1.0 + np.exp(-sigma))
        if np.isfinite(lo):
            return lo + np.exp(sigma)
        if np.isfinite(hi):
            return hi - np.exp(-sigma)
        return np.asarray(sigma, dtype=float)

    def slope(self, sigma: np.ndarray) -> np.ndarray:
        lo, hi = self.lo, self.hi
        if np.isfinite(lo) and np.isfinite(hi):
            e = np.exp(-np.abs(sigma))
            return (hi - lo) * e / (1.0 + e) ** 2
        if np.isfinite(lo):
            return np.exp(sigma)
        if np.isfinite(hi):
            return np.exp(-sigma)
        return np.ones_like(sigma, dtype=float)

    def inverse(self, value: float) -> float:
        lo, hi = self.lo, self.hi
        if np.isfinite(lo) and np.isfinite(hi):
            return float(np.log((value - lo) / (hi - value)))
        if np.isfinite(lo):
            return float(np.log(value - lo))
        if np.isfinite(hi):
            return float(-np.log(hi - value))
        return float(value)


def _per_node(function: Callable[[np.ndarray], np.ndarray], sigma: np.ndarray) -> np.ndarray:
    """function(σ) at every node, evaluated once where σ is the same at every node (a constant
    state on gauss-newton's iterates: its steps move it alike everywhere), else node by node."""
    if sigma.size > 1 and np.all(sigma == sigma[0]):
        return np.full(sigma.shape, function(sigma[:1])[0])
    return function(sigma)


def restated(model: InclusionModel, free_T: bool | None, parameters: Mapping[str, float] | None) -> InclusionModel:
    """A copy of `model` with T free (True) or fixed (False) and the guesses of some parameters."""
    out = copy.copy(model)
    if free_T is not None:
        if not isinstance(free_T, (bool, np.bool_)):
            raise InputError("free_T", "True or False", free_T)
        out.free_T = bool(free_T)
    if parameters:
        if not isinstance(parameters, Mapping):
            raise InputError("parameters", "a mapping {name: starting guess}", parameters)
        out.parameters = out._parameter_guesses({**dict(zip(model.parameter_names, model.parameters)), **parameters})
    return out


class Unknowns(InclusionModel):
    """The model with its free T and parameters as constant states (module docstring):
    states (x, σ_p, σ_T), y = (x, σ_p, σ_T, u). With `fixed` the parameters are not
    unknowns but the model's values (its guesses), inserted into every piece's argument:
    states (x, σ_T), the form :func:`qdframe.simulate.simulate`, the plots and the cost
    comparison of ``qdframe bench unknowns`` use."""

    def __init__(self, model: InclusionModel, fixed: bool = False) -> None:
        if model.free_T and not (len(model.end_indices) or len(model.periodic)):
            raise InputError("free_T", "a model with an end value or a periodic condition that determines T "
                                       "(without one every T is a solution)", True)
        self.inner = model
        self.fixed = bool(fixed)
        self.values = np.asarray(model.parameters, dtype=float)
        self.name = model.name
        self.description = model.description
        self.default_tol = model.default_tol
        self.default_scheme = model.default_scheme
        self.control_names = tuple(model.control_names)
        n = model.n_states
        self.scaled = bool(model.free_T)
        self.bounds = [] if self.fixed else [Bound(*model.parameter_bounds.get(name, (-np.inf, np.inf)))
                                             for name in model.parameter_names]
        q = len(self.bounds)  # the parameters' columns (none when fixed)
        self.time_bound = Bound(*model.T_bounds)
        extra = (*model.parameter_names[:q], *((T_NAME,) if self.scaled else ()))
        self.state_names = (*model.state_names, *extra)
        self.resolved = {} if self.scaled else dict(model.resolved)
        self.end_indices = tuple(model.end_indices)
        self.periodic = tuple(model.periodic)
        self.n, self.q = n, q
        self.T0 = float(model.T)
        self._wrapped: dict[int, Callable] = {}  # id of the model's callable → its wrapper
        self._blocks: tuple[SetBlock, ...] | None = None
        super().__init__(T=1.0 if self.scaled else model.T, x0=[*model.x0, *([np.nan] * len(extra))],
                         end_values=model.end_values, free_T=False, parameters=())
        self.constant_states = tuple(range(n, self.n_states))
        self.bounds_table = dict(model.bounds_table)  # by name: the model's states keep their columns
        self.T_guess = self.T0  # the user's; a solve may start from a better one (qdframe.solve.start.swept_T)

    # -- the columns of y = (x, σ_p, σ_T, u) and the model's y = (x, p, u)
    @property
    def width(self) -> int:
        return self.n_states + self.n_controls

    def _user(self, y: np.ndarray) -> np.ndarray:
        """The model's own argument (x, p, u) (or (x, p) for the surface) from (x, σ_p, σ_T, u)."""
        n, q = self.n, self.q
        parts = [y[:, :n]] + [_per_node(bound.value, y[:, n + i])[:, None] for i, bound in enumerate(self.bounds)]
        if self.fixed and self.values.size:
            parts.append(np.broadcast_to(self.values, (y.shape[0], self.values.size)))
        parts.append(y[:, n + q + self.scaled:])
        return np.concatenate(parts, axis=1)

    def _gradient(self, y: np.ndarray, grad: np.ndarray) -> np.ndarray:
        """∂/∂(x, σ_p, σ_T, u) from ∂/∂(x, p, u): the chain rule through b_i (fixed p: its columns
        dropped), a zero σ_T column (T·v's σ_T column is added by :meth:`_times_T`)."""
        n, q = self.n, self.q
        grad = np.asarray(grad, dtype=float)
        shape = (grad.shape[0],) + (1,) * (grad.ndim - 2)
        parts = [grad[..., :n]]
        for i, bound in enumerate(self.bounds):
            parts.append(grad[..., n + i: n + i + 1] * _per_node(bound.slope, y[:, n + i]).reshape(shape + (1,)))
        if self.scaled:
            parts.append(np.zeros(grad.shape[:-1] + (1,)))
        parts.append(grad[..., n + q + (self.values.size if self.fixed else 0):])
        return np.concatenate(parts, axis=-1)

    def _T(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """T and dT/dσ_T per node."""
        sigma = y[:, self.n + self.q]
        return _per_node(self.time_bound.value, sigma), _per_node(self.time_bound.slope, sigma)

    def _times_T(self, y: np.ndarray, value: np.ndarray, grad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """T·v and its gradient (the σ_T column dT/dσ_T·v) where T is free; v unchanged if not."""
        if not self.scaled:
            return value, grad
        T, dT = self._T(y)
        shape = (value.shape[0],) + (1,) * (value.ndim - 1)
        grad = grad * T.reshape(shape + (1,))
        grad[..., self.n + self.q] = value * dT.reshape(shape)
        return value * T.reshape(shape), grad

    # -- the wrapped pieces
    def _max_group(self, group: MaxGroup) -> MaxGroup:
        return MaxGroup(self._scaled(group.pieces), group.name)

    def _min_group(self, group: MinGroup) -> MinGroup:
        def pieces(y: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            value, grad = group.pieces(self._user(y), psi)
            return self._times_T(y, np.asarray(value, float), self._gradient(y, grad))

        values = None
        if group.values is not None:
            def values(y: np.ndarray, psi: np.ndarray) -> np.ndarray:
                out = np.asarray(group.values(self._user(y), psi), float)  # type: ignore[misc]
                return out * self._T(y)[0][:, None] if self.scaled else out

        return MinGroup(pieces, group.name, values)

    def _scalar(self, function: Callable) -> Callable:
        """A function of y returning (value, gradient) with the model's argument: the same
        function of (x, σ_p, σ_T, u), not scaled (a switch, a surface)."""
        if id(function) not in self._wrapped:  # one wrapper per callable: terms sharing a switch share λ
            def wrapped(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                value, grad = function(self._user(y))
                return value, self._gradient(y, grad)

            self._wrapped[id(function)] = wrapped
        return self._wrapped[id(function)]

    def _switch(self, switch: Callable | BallSwitch) -> Callable | BallSwitch:
        if isinstance(switch, BallSwitch):
            key = id(switch)
            if key not in self._wrapped:
                self._wrapped[key] = BallSwitch(self._scalar(switch.function), switch.dim, switch.name)  # type: ignore[assignment]
            return self._wrapped[key]
        return self._scalar(switch)

    def _scaled(self, piece: Callable) -> Callable:
        """A piece group of y (a max-group, a sign amplitude, a cost group) as a function of
        (x, σ_p, σ_T, u), scaled by T."""
        def pieces(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            value, grad = piece(self._user(y))
            return self._times_T(y, np.asarray(value, float), self._gradient(y, grad))

        return pieces

    def _sign(self, term: SignTerm) -> SignTerm:
        amplitude = term.amplitude
        if isinstance(amplitude, tuple):
            amplitude = tuple(self._scaled(group) for group in amplitude)
        elif self.scaled:  # a constant a: T·a, a function of σ_T
            a = float(amplitude)

            def constant(y: np.ndarray, a: float = a) -> tuple[np.ndarray, np.ndarray]:
                T, dT = self._T(y)
                grad = np.zeros((y.shape[0], 1, self.width))
                grad[:, 0, self.n + self.q] = a * dT
                return (a * T)[:, None], grad

            amplitude = (constant,)
        return dataclasses.replace(term, amplitude=amplitude, switch=self._switch(term.switch))

    def _still(self, coord: int) -> SetBlock:
        """σ' = 0: a block without pieces, F_b = {0}."""
        return SetBlock((coord,), name=f"{self.state_names[coord]}' = 0")

    def _resolved(self, i: int, j: int) -> SetBlock:
        """x_i' = x_j becomes X_i' = T·X_j on the scaled time."""
        def rhs(y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            grad = np.zeros((y.shape[0], self.width))
            grad[:, j] = 1.0
            return self._times_T(y, y[:, j].copy(), grad)

        return SetBlock.equation(i, rhs, name=f"{self.state_names[i]}' = T·{self.state_names[j]}")

    def blocks(self) -> tuple[SetBlock, ...]:
        if self._blocks is None:
            own = tuple(
                SetBlock(block.coords, tuple(self._max_group(g) for g in block.max_groups),
                         tuple(self._min_group(g) for g in block.min_groups), block.name,
                         tuple(self._sign(term) for term in block.signs))
                for block in self.inner.blocks())
            resolved = tuple(self._resolved(i, j) for i, j in self.inner.resolved.items()) if self.scaled else ()
            still = tuple(self._still(coord) for coord in range(self.n, self.n_states))
            self._blocks = own + resolved + still
        return self._blocks

    def surface(self) -> Surface | None:
        surface = self.inner.surface()
        if surface is None:
            return None
        return Surface(self._scalar(surface.function))  # it takes (x, σ_p, σ_T), the model's (x, p)

    def cost(self) -> Cost | None:
        cost = self.inner.cost()
        if cost is None:
            return None
        hessian = None
        if cost.hessian is not None:  # (T·)∇²c on the columns of x and u (the unknowns' curvature left out)
            def hessian(y: np.ndarray, inner=cost.hessian) -> np.ndarray:
                n, m = self.n, self.n_controls
                user = self._user(y)
                own = np.r_[0:n, user.shape[1] - m:user.shape[1]]
                mine = np.r_[0:n, self.width - m:self.width]
                out = np.zeros((y.shape[0], self.width, self.width))
                scale = self._T(y)[0][:, None, None] if self.scaled else 1.0
                out[:, mine[:, None], mine[None, :]] = scale * np.asarray(inner(user))[:, own[:, None], own[None, :]]
                return out
        terminal = None
        if cost.terminal is not None:  # M(x(T)) of the model's states (the unknowns' columns 0)
            def terminal(x: np.ndarray, inner=cost.terminal) -> tuple[float, np.ndarray, np.ndarray]:
                value, grad, hess = inner(x[: self.n])
                g, H = np.zeros(x.size), np.zeros((x.size, x.size))
                g[: self.n], H[: self.n, : self.n] = grad, hess
                return value, g, H
        return Cost(tuple(self._scaled(g) for g in cost.max_groups), tuple(self._scaled(g) for g in cost.min_groups),
                    cost.weight, hessian=hessian, terminal=terminal)

    # -- starting guesses and the way back
    def initial_guess(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        times = t * self.T0 if self.scaled else t
        x, z = self.inner.initial_guess(times)
        z = np.asarray(z, float) * (self.T0 if self.scaled else 1.0)
        sigma = [bound.inverse(p) for bound, p in zip(self.bounds, self.inner.parameters)]
        if self.scaled:
            sigma.append(self.time_bound.inverse(self.T0))
        still = np.tile(sigma, (t.size, 1))
        return np.concatenate([np.asarray(x, float), still], axis=1), np.concatenate([z, np.zeros_like(still)], axis=1)

    def initial_controls(self, t: np.ndarray) -> np.ndarray:
        return self.inner.initial_controls(t * self.T0 if self.scaled else t)

    def accuracy_scale(self, x: np.ndarray) -> float:
        return max(1.0, float(np.max(np.abs(x[:, : self.n]))))  # the model's states, not the σ's

    def time_scale(self, x: np.ndarray) -> float:
        return self.found(x)[0] if self.scaled else 1.0

    def observed(self, x: np.ndarray) -> np.ndarray:
        """x, then T (when found) and the parameters, each column the same at every point."""
        T, parameters = self.found(x)
        found = ([T] if self.scaled else []) + ([] if self.fixed else list(parameters.values()))
        return np.concatenate([x[:, : self.n], np.tile(found, (x.shape[0], 1))], axis=1)

    def found(self, x: np.ndarray) -> tuple[float, dict[str, float]]:
        """T and the parameters of a scaled trajectory (the σ columns' means: constant on a solution)."""
        sigma = np.mean(x[:, self.n:], axis=0)
        parameters = dict(zip(self.inner.parameter_names, map(float, self.values))) if self.fixed else {
            name: float(bound.value(sigma[i])) for i, (name, bound) in enumerate(zip(self.inner.parameter_names, self.bounds))}
        T = float(self.time_bound.value(sigma[self.q])) if self.scaled else float(self.inner.T)
        return T, parameters
