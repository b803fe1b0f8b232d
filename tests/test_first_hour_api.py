"""Issue 17 ("a new user's first hour"), items 4, 10 and 15: a NaN mid-run is one error
naming the returned iterate's node and state, loading paper-7.3 does not simulate, and
the returned x(t_0) is x0 exactly."""

import numpy as np
import pytest

import qdframe
from qdframe.models import masses


# ---------------------------------------------------------------- item 10: loading is cheap
def test_loading_paper_73_does_not_simulate_until_x0_is_read(monkeypatch):
    calls = []
    real = masses.reaching_phase_end.__wrapped__

    def counted():
        calls.append(1)
        return real()

    cached = masses.lru_cache(maxsize=1)(counted)
    monkeypatch.setattr(masses, "reaching_phase_end", cached)
    model = qdframe.load_model("paper-7.3")
    reduced = qdframe.load_model("paper-7.3-reduced")
    assert calls == []  # loading ran no simulation
    x0 = model.x0
    assert calls == [1] and x0.shape == (6,) and np.all(np.isfinite(x0))
    assert np.array_equal(reduced.x0, x0) and calls == [1]  # simulated once, then cached
    assert reduced.x0 is not x0  # each model has its own array
    given = qdframe.load_model("paper-7.3", x0=[0.0] * 6)
    assert np.array_equal(given.x0, np.zeros(6)) and calls == [1]

