"""k independent Coulomb blocks in one model, a family with a closed form for any k.

    p_i' = v_i,   v_i' ∈ f_i − 2·Sgn(v_i),   p_i(0) = 0, v_i(0) = 1 + 0.1·i,   f_i = 0.5·sin(i + 1),

i = 0 … k − 1, over T = 5: each block slides, stops at t_i = v_i(0)/(2 − f_i) (0.63 … 2.9 s for
k ≤ 40) and sticks (|f_i| < 2). Its motion has k stops, and at the i-th every block stopped
before is at its surface too: the event-driven integrator's mode choice there sees i + 1
switches (3^(i+1) modes by enumeration). `qdframe bench certificates --blocks` times the
default call on it; it is not registered (its states depend on k).
"""

from __future__ import annotations

import numpy as np

from ..sets import SetModel, Sgn

FRICTION = 2.0
HORIZON = 5.0


def pulls(k: int) -> np.ndarray:
    return 0.5 * np.sin(np.arange(1, k + 1))


def throws(k: int) -> np.ndarray:
    return 1.0 + 0.1 * np.arange(k)


def coulomb_blocks(k: int) -> SetModel:
    """The model of k blocks (states p0 v0 p1 v1 …) with its exact solution."""
    if not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"coulomb_blocks: k must be a positive integer, got {k!r}")
    f, v0 = pulls(k), throws(k)

    class CoulombBlocks(SetModel):
        name = f"coulomb-blocks-{k}"
        description = f"{k} independent Coulomb blocks thrown at once, each stopping and sticking"
        state_names = " ".join(f"p{i} v{i}" for i in range(k))
        default_x0 = tuple(value for i in range(k) for value in (0.0, float(v0[i])))
        default_T = HORIZON
        switch_times = tuple(sorted(v0 / (FRICTION - f)))

        def sets(self, *x):
            return {state: formula for i in range(k)
                    for state, formula in ((x[2 * i], x[2 * i + 1]), (x[2 * i + 1], f[i] - FRICTION * Sgn(x[2 * i + 1])))}

        def exact_solution(self, t: np.ndarray) -> np.ndarray | None:
            if self.T != HORIZON or not np.array_equal(self.x0, self.default_x0):
                return None
            t = np.atleast_1d(np.asarray(t, dtype=float))[:, None]
            slowing = FRICTION - f
            moving = np.minimum(t, v0 / slowing)
            out = np.empty((t.shape[0], 2 * k))
            out[:, 0::2] = v0 * moving - 0.5 * slowing * moving**2
            out[:, 1::2] = v0 - slowing * moving
            return out

    return CoulombBlocks()
