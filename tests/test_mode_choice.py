"""The Filippov mode at an event without 3^k enumeration (issue 57, item 1).

`choose_mode` decides the switches at their surface group by group (no coupling ∇s_i·B_j
between groups) and a large coupled group of scalar sign terms by a box LCP. Held here:
- against the full enumeration of every labelling (the rule the integrator had: the first
  mode, in the order (0, +1, −1) of the switches, of largest smallest margin), on random
  systems of independent and coupled switches, a crossed and a released one among them;
- the box LCP (Lemke) against enumeration on random dissipative couplings −A = G·D;
- k independent Coulomb blocks: 3k margin checks at an event, and the event integrator's
  model evaluations growing linearly in k (a budget, not a timer), the motion exact.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from qdframe.certificates import filippov
from qdframe.certificates.complementarity import box_lcp, labels
from qdframe.certificates.filippov import MARGIN_TOL, Fields, FilippovSystem, choose_mode, integrate


def _enumerated(fields: Fields, x: np.ndarray, current=None, crossed=None, released=None) -> tuple[int, ...]:
    """The mode by enumerating all 3^k labellings of the switches at their surface."""
    near = filippov.SURFACE_TOL * max(1.0, float(np.max(np.abs(x))))
    at = {i for i, c in enumerate(fields.s) if abs(c) <= near}
    if current is not None:
        at |= {i for i, m in enumerate(current) if m == 0}
    at |= {i for i in (crossed, None if released is None else released[0]) if i is not None}
    at = sorted(at)
    best, best_value = None, -np.inf
    for choice in itertools.product((0, 1, -1), repeat=len(at)):
        mode = [1 if c > 0 else -1 for c in fields.s]
        for i, m in zip(at, choice):
            mode[i] = m
        if crossed is not None and mode[crossed] == current[crossed]:
            continue
        if released is not None and mode[released[0]] != released[1]:
            continue
        margins = filippov._margins(fields, tuple(mode), at)
        value = float(margins.min()) if margins.size else np.inf
        if value >= -MARGIN_TOL and value > best_value:
            best, best_value = tuple(mode), value
    return best


def _random_fields(rng: np.random.Generator, k: int, groups: int, on_surface: float = 0.8) -> tuple[Fields, np.ndarray]:
    """x' = g + B·λ on n = k states with s = x (∇s = I): B block diagonal over `groups`
    groups of switches (dissipative, −B = G·D within a group, or not), most switches at s = 0."""
    B = np.zeros((k, k))
    for members in np.array_split(rng.permutation(k), groups):
        G = rng.normal(size=(members.size, members.size))
        G = G @ G.T + 0.2 * np.eye(members.size)
        block = -G @ np.diag(rng.uniform(0.3, 2.0, members.size))
        if rng.random() < 0.2:  # a repelling coupling: several modes can be consistent
            block = -block
        B[np.ix_(members, members)] = block
    x = np.where(rng.random(k) < on_surface, 0.0, rng.normal(size=k))
    g = rng.normal(size=k) * rng.choice([0.3, 1.0, 4.0])
    return Fields(g, B, x.copy(), np.eye(k)), x


@pytest.mark.parametrize("seed", range(40))
def test_groups_choose_the_mode_the_full_enumeration_chooses(seed):
    rng = np.random.default_rng(seed)
    k = int(rng.integers(2, 8))
    fields, x = _random_fields(rng, k, groups=int(rng.integers(1, k + 1)))
    expected = _enumerated(fields, x)
    if expected is None:
        with pytest.raises(filippov.FilippovError, match="no consistent Filippov mode"):
            choose_mode(fields, x)
    else:
        assert choose_mode(fields, x) == expected


@pytest.mark.parametrize("seed", range(20))
def test_a_crossed_and_a_released_switch_are_kept_to_their_rule(seed):
    rng = np.random.default_rng(100 + seed)
    k = int(rng.integers(2, 7))
    fields, x = _random_fields(rng, k, groups=int(rng.integers(1, k + 1)), on_surface=1.0)
    current = tuple(int(v) for v in rng.choice([0, 1, -1], size=k))
    crossed = int(rng.integers(k)) if current[0] != 0 else None
    if crossed is not None and current[crossed] == 0:
        crossed = None
    sliding = [i for i, m in enumerate(current) if m == 0]
    released = (sliding[0], int(rng.choice([1, -1]))) if sliding and crossed is None else None
    expected = _enumerated(fields, x, current, crossed, released)
    if expected is None:
        with pytest.raises(filippov.FilippovError):
            choose_mode(fields, x, current, crossed, released)
    else:
        assert choose_mode(fields, x, current, crossed, released) == expected


@pytest.mark.parametrize("seed", range(6))
def test_a_coupled_group_beyond_enumeration_is_solved_as_a_box_lcp(seed, monkeypatch):
    """Seven coupled dissipative switches (3^7 modes, over the enumeration cap): the LCP's mode
    is the one consistent mode the full enumeration finds, and far fewer margins are checked."""
    rng = np.random.default_rng(200 + seed)
    k = 7
    G = rng.normal(size=(k, k))
    B = -(G @ G.T + 0.2 * np.eye(k)) @ np.diag(rng.uniform(0.3, 2.0, k))
    fields = Fields(rng.normal(size=k) * 2.0, B, np.zeros(k), np.eye(k))
    x = np.zeros(k)
    expected = _enumerated(fields, x)
    calls = []
    original = filippov._margins
    monkeypatch.setattr(filippov, "_margins", lambda *a, **kw: calls.append(1) or original(*a, **kw))
    assert choose_mode(fields, x) == expected
    assert len(calls) < 3**6


def test_independent_switches_cost_three_margin_checks_each(monkeypatch):
    k = 30
    fields = Fields(np.linspace(-0.9, 0.9, k), -np.eye(k), np.zeros(k), np.eye(k))
    calls = []
    original = filippov._margins
    monkeypatch.setattr(filippov, "_margins", lambda *a, **kw: calls.append(1) or original(*a, **kw))
    mode = choose_mode(fields, np.zeros(k))
    assert mode == (0,) * k  # every |g_i| < 1: each sticks
    assert len(calls) == 3 * k


@pytest.mark.parametrize("seed", range(30))
def test_box_lcp_finds_the_unique_mode_of_a_dissipative_coupling(seed):
    rng = np.random.default_rng(300 + seed)
    k = int(rng.integers(1, 7))
    G = rng.normal(size=(k, k))
    A = -(G @ G.T + 0.1 * np.eye(k)) @ np.diag(rng.uniform(0.2, 3.0, k))
    b = rng.normal(size=k) * rng.choice([0.3, 1.0, 5.0])
    lam = box_lcp(A, b)
    assert lam is not None and np.all(np.abs(lam) <= 1.0)
    w = A @ lam + b
    inside = np.abs(lam) < 1 - 1e-9
    assert np.all(np.abs(w[inside]) <= 1e-9 * max(1.0, np.abs(b).max()))
    assert np.all(np.sign(lam[~inside]) * w[~inside] >= -1e-9 * max(1.0, np.abs(b).max()))
    fields = Fields(b, A, np.zeros(k), np.eye(k))
    assert labels(A, b, lam) == _enumerated(fields, np.zeros(k))


# --------------------------------------------------------------- k independent blocks
def _blocks(k: int, counted: list[int]) -> FilippovSystem:
    """p_i' = v_i, v_i' ∈ f_i − 2·Sgn(v_i), v_i(0) = 1 + 0.1·i: each stops at v_i(0)/(2 − f_i)
    and sticks (|f_i| < 2). States (p_0, v_0, p_1, …); switches s_i = −v_i (λ of Sgn(−v))."""
    f = 0.5 * np.sin(np.arange(1, k + 1))
    B = np.zeros((2 * k, k))
    B[2 * np.arange(k) + 1, np.arange(k)] = 2.0
    ds = np.zeros((k, 2 * k))
    ds[np.arange(k), 2 * np.arange(k) + 1] = -1.0

    def fields(t: float, x: np.ndarray) -> Fields:
        counted.append(1)
        g = np.empty(2 * k)
        g[0::2], g[1::2] = x[1::2], f
        return Fields(g, B, -x[1::2], ds)

    return FilippovSystem(fields, tuple(f"Sgn(-v{i})" for i in range(k)), f"blocks-{k}")


def _exact(k: int, T: float) -> np.ndarray:
    f = 0.5 * np.sin(np.arange(1, k + 1))
    v0 = 1.0 + 0.1 * np.arange(k)
    a = 2.0 - f
    stop = np.minimum(v0 / a, T)
    out = np.empty(2 * k)
    out[0::2], out[1::2] = v0 * stop - 0.5 * a * stop**2, v0 - a * stop
    return out


def test_k_blocks_are_integrated_exactly_with_model_evaluations_linear_in_k():
    counts = {}
    for k in (4, 16):
        counted: list[int] = []
        x0 = np.zeros(2 * k)
        x0[1::2] = 1.0 + 0.1 * np.arange(k)
        motion = integrate(_blocks(k, counted), x0, 5.0)
        assert np.max(np.abs(motion(np.array([5.0]))[0] - _exact(k, 5.0))) <= 1e-9
        assert len(motion.switch_times) == k
        counts[k] = len(counted)
    # 4× the blocks, 4× the stops: at most 4× the evaluations and a margin (3^k grew ×43 million)
    assert counts[16] <= 4 * 1.5 * counts[4], counts
