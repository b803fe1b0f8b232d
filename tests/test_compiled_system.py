"""A model's Filippov system compiled into one call (`formulas` hooks, qdframe.certificates.model_system)
gives the numbers of the pieces called one by one, on every registered model it covers, at
random states, velocities to take the nearest point to and controls."""

from __future__ import annotations

import numpy as np
import pytest

import qdframe
from qdframe.certificates import model_system as ms
from qdframe.functional import Functional
from qdframe.schemes.grid import Grid
from qdframe.model import MaxGroup, SetBlock, SignTerm
from qdframe.models.exact_friction import BlockStopStick
from qdframe.registry import names

# the models whose pieces all carry the hook (checked, so that a model losing it is seen)
COMPILED = {"block-breakaway", "block-stop-stick", "block-stop-stick-bvp", "block-stopping-time",
            "block-time-optimal", "coulomb-block", "coulomb-rest-to-rest", "disturbed-control",
            "double-pendulum", "isotropic-puck", "least-effort-block", "least-effort-bounded", "lq-terminal", "isotropic-slide-3d", "orthotropic-puck", "paper-7.3",
            "paper-7.3-reduced", "pivot-friction-pendulum", "relay-oscillator", "relay-period",
            "slide-after-reaching", "slide-on-line", "sliding-mode", "sliding-mode-terminal",
            "stick-slip-oscillator", "two-block-chain", "two-surface-sliding", "velocity-range"}


def _functional(model) -> Functional:
    return Functional(model, Grid(model.T, 2, "implicit-euler"), signs="exact")


@pytest.mark.parametrize("name", sorted(COMPILED))
def test_the_compiled_system_is_the_pieces_one_by_one(name):
    functional = _functional(qdframe.load_model(name))
    compiled = ms._Compiled.build(functional)
    assert compiled is not None
    rng = np.random.default_rng(7)
    u = rng.normal(size=functional.m)
    controls = (lambda t: u) if functional.m else None
    wanted = rng.normal(size=functional.n) * 3.0
    slow = ms._fields_by_pieces(functional, controls, lambda t: wanted)
    fast = ms._fields_compiled(functional, compiled, controls, lambda t: wanted)
    for _ in range(10):
        x = rng.normal(size=functional.n) * 2.0
        a, b = slow(0.5, x), fast(0.5, x)
        for field in ("g", "B", "s", "ds"):
            expected, got = getattr(a, field), getattr(b, field)
            assert got.shape == expected.shape
            np.testing.assert_allclose(got, expected, rtol=1e-14, atol=1e-14, err_msg=f"{name}: {field}")


def test_the_covered_models_are_the_registered_ones_whose_pieces_have_formulas():
    covered = set()
    for name in names("models"):
        model = qdframe.load_model(name)
        if ms._Compiled.build(_functional(model)) is not None:
            covered.add(name)
    assert covered == COMPILED


def test_a_hand_written_piece_without_formulas_is_called_one_by_one():
    class Plain(BlockStopStick):
        def blocks(self):
            p, v = super().blocks()
            pieces = v.max_groups[0].pieces
            return p, SetBlock(v.coords, (MaxGroup(lambda y: pieces(y)),), v.min_groups, v.name, v.signs)

    functional = _functional(Plain())
    assert ms._Compiled.build(functional) is None
    motion = ms.model_system(functional)
    x = np.array([0.2, 0.7])
    assert np.array_equal(motion.fields(0.1, x).g, ms.model_system(_functional(BlockStopStick())).fields(0.1, x).g)


def test_a_non_finite_value_is_named():
    class Blowing(BlockStopStick):
        def blocks(self):
            p, v = super().blocks()
            term = v.signs[0]
            switch = term.switch

            def s(y):  # infinite at v = 0.7
                value, gradient = switch(y)
                return value / (y[:, 1] - 0.7), gradient

            s.formulas = lambda symbols: [switch.formulas(symbols)[0] / (symbols[1] - 0.7)]
            return p, SetBlock(v.coords, v.max_groups, v.min_groups, v.name,
                               (SignTerm(term.amplitude, s, term.band, term.name, term.sense),))

    functional = _functional(Blowing())
    assert ms._Compiled.build(functional) is not None
    system = ms.model_system(functional)
    with pytest.raises(qdframe.certificates.filippov.FilippovError, match="non-finite at t = 0.1"):
        system.fields(0.1, np.array([0.2, 0.7]))
