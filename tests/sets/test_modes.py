"""`Modes`: a switched field as nosnoc states it (modes and switching functions) compiled to exact sign
terms; nosnoc's periodic stick-slip example solved and held to an independent integration."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import qdframe
from qdframe.bench.two_modes import TwoModes, integrate
from qdframe.sets import Interval, Modes, SetModel, SetStructureError, Sgn

x0, x1, x2 = sp.symbols("x0 x1 x2")


def _parts(field) -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """(mean, amplitude, switch) of a compiled field {mean} + max(a, 0)·Sgn(c) − max(−a, 0)·Sgn(c)."""
    point, *terms = field.sets
    factors, switches = [], set()
    for term in terms:
        factor = sp.Integer(1)
        while not hasattr(term, "switch"):  # −(max(−a, 0)·Sgn(c)) nests one scaling in another
            factor, term = factor * term.factor, term.inner
        factors.append(factor)
        switches.add(term.switch)
    assert len(terms) == 2 and len(switches) == 1
    return point.f[0], sum(factors), switches.pop()


def test_one_switching_function_is_the_mean_plus_half_the_jump_times_its_sign():
    """f₊ − f₋ of this friction law is negative: max(a, 0)·Sgn(c) − max(−a, 0)·Sgn(c) keeps each
    term's amplitude ≥ 0 (check_model holds it) and sums to a·λ on one selection."""
    plus, minus = -x0 - 1 / (0.8 + x1), -x0 + 1 / (1.2 - x1)
    sets = Modes(x1 - 0.2, positive={x0: x1, x1: plus}, negative={x0: x1, x1: minus})
    assert sets[x0] == x1  # the same in both modes: no sign term
    mean, amplitude, switch = _parts(sets[x1])
    assert switch == x1 - 0.2
    assert sp.simplify(mean - (plus + minus) / 2) == 0
    for value in (-0.5, 0.0, 0.2, 1.0):
        assert float(amplitude.subs(x1, value)) == pytest.approx(float(((plus - minus) / 2).subs(x1, value)))


def test_the_table_form_and_the_keywords_give_the_same_sets():
    plus, minus = {x0: x1, x1: -x0 - 1}, {x0: x1, x1: -x0 + 1}
    first = Modes(x1, positive=plus, negative=minus)
    second = Modes((x1,), {(1,): plus, (-1,): minus})
    assert str(first[x1]) == str(second[x1]) == str(-x0 - Sgn(x1))


def test_separable_modes_of_two_switches_are_two_sign_terms():
    """Two contacts: each state's modes differ along its own switch, the field is g + a1·Sgn(c1) + a2·Sgn(c2)."""
    def mode(s1, s2):
        return {x0: -0.5 * s1 + x2, x1: -0.3 * s2 - x0, x2: x0 * x1}

    sets = Modes((x0, x1), {(s1, s2): mode(s1, s2) for s1 in (1, -1) for s2 in (1, -1)})
    assert str(sets[x0]) == str(x2 - 0.5 * Sgn(x0))
    assert str(sets[x1]) == str(-x0 - 0.3 * Sgn(x1))
    assert sets[x2] == x0 * x1


def test_a_product_of_switches_is_refused_naming_the_state():
    """nosnoc's codim-2 stick-slip example: its fourth mode alone adds x0·(x1 + 0.8)·(x2 + 0.6) to x0'."""
    base = {x0: (x1 + x2) / 2, x1: -x0, x2: -x0}
    fourth = {**base, x0: (x1 + x2) / 2 + x0 * (x1 + 0.8) * (x2 + 0.6)}
    with pytest.raises(SetStructureError, match=r"Modes: x0'.*Sgn\(x1 - 0\.2\)·Sgn\(x2 - 0\.4\)"):
        Modes((x1 - 0.2, x2 - 0.4), {(-1, -1): base, (-1, 1): base, (1, -1): base, (1, 1): fourth})


@pytest.mark.parametrize("call, field", [
    (lambda: Modes(x1, positive={x0: 1}), "positive= and negative= together"),
    (lambda: Modes((x0, x1), {(1, 1): {x0: 1}, (1, -1): {x0: 1}, (-1, 1): {x0: 1}}), r"none for \(-1, -1\)"),
    (lambda: Modes(x1, {(2,): {x0: 1}, (-1,): {x0: 1}}), "sign pattern"),
    (lambda: Modes(x1, {(1,): {x0: 1}, (-1,): {x1: 1}}), r"Modes mode \(-1,\)"),
    (lambda: Modes(x1, {(1,): {x0: Interval(0, 1)}, (-1,): {x0: 1}}), r"Modes mode \(1,\), x0'"),
    (lambda: Modes((), {}), "at least one switching function"),
])
def test_bad_modes_are_refused_with_one_line_naming_the_part(call, field):
    with pytest.raises(SetStructureError, match=field) as caught:
        call()
    assert "\n" not in str(caught.value)


class NosnocStickSlip(SetModel):
    """nosnoc's examples/periodic_stick_slip (codim 1), as it states it: modes f_11 where
    c = x1 − 0.2 < 0 and f_12 where c > 0, from (0.04, −0.01), over its simulated 40 s."""

    name = "nosnoc-stick-slip"
    state_names = "x0 x1"
    default_x0 = (0.04, -0.01)
    default_T = 40.0

    def sets(self, x0, x1):
        return Modes(x1 - 0.2, positive={x0: x1, x1: -x0 - 1 / (0.8 + x1)},
                     negative={x0: x1, x1: -x0 + 1 / (1.2 - x1)})


def test_nosnocs_stick_slip_is_solved_against_an_independent_integration():
    """The default call is solved, and its error against the two-mode event integration (no code
    shared with qdframe's certificate) is within its estimate and the target."""
    result = qdframe.solve(NosnocStickSlip())
    assert result.solved, result.message
    system = TwoModes(lambda x, u: np.array([x[1], -x[0] - 1 / (0.8 + x[1])]),
                      lambda x, u: np.array([x[1], -x[0] + 1 / (1.2 - x[1])]),
                      lambda x: float(x[1] - 0.2), lambda x: np.array([0.0, 1.0]))
    t = np.asarray(result.t)
    reference = integrate(system, NosnocStickSlip.default_x0, NosnocStickSlip.default_T, dense=t)
    error = float(np.max(np.abs(np.asarray(result.x) - reference.at(t))))
    assert reference.events >= 8  # it sticks on v = 0.2 and slips again, period after period
    assert error <= result.error_estimate <= 1e-6 * max(1.0, float(np.max(np.abs(result.x))))
