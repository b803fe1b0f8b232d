"""Sets outside the paper's form Σ max + Σ min (+ sign terms) are one clear error naming the set
(qdframe/sets/expressions.py's SetStructureError, raised by the primitives, combinators and compiler)."""

import pytest
import sympy as sp

import qdframe
from qdframe.sets import Abs, Ball, Interval, Max, Point, SetModel, SetStructureError, Sgn, compile_sets, hull, intersection

x1, x2, x3, u = sp.symbols("x1 x2 x3 u", real=True)


@pytest.mark.parametrize(
    "build, words",
    [
        (lambda: hull(intersection(Interval(x1, x2), Interval(0, 1)), Point(x1)), ["co{", "intersection", "hull"]),
        (lambda: hull(Ball((0, 0), 1), Point((x1, x2))), ["ball"]),
        (lambda: hull(Sgn(x1), 0), ["sign term"]),
        (lambda: intersection(Interval(0, 1), Sgn(x1)), ["sign term", "intersection"]),
        (lambda: intersection(Interval(0, 1), hull(x1, x2, x3)), ["hull of 3 points"]),
        (lambda: Point(Abs(x1)), ["continuously differentiable"]),
        (lambda: Interval(Max(x1, x2), 3), ["continuously differentiable"]),
        (lambda: x1 * Ball((0, 0), 1), ["state-dependent factor"]),
        (lambda: Abs(x1) * Interval(0, 1), ["symmetric"]),
        (lambda: (Abs(x1) - Abs(x2)) * Interval(-1, 1), ["c_i > 0"]),
        (lambda: Interval(2, 1), ["lo ≤ hi"]),
        (lambda: Interval(0, 1) + Ball((0, 0), 1), ["one dimension"]),
        (lambda: Interval(0, 1) * Interval(0, 1), ["not a set"]),
    ],
)
def test_combinations_outside_the_papers_form_are_clear_errors(build, words):
    with pytest.raises(SetStructureError) as caught:
        build()
    message = str(caught.value)
    for word in words:
        assert word in message, message


def test_model_level_errors_name_the_model_and_the_block():
    with pytest.raises(SetStructureError, match="one dimension"):
        (0, 0) + Sgn(x1)  # a sign term lives in one coordinate
    with pytest.raises(SetStructureError, match="R\\^2"):
        compile_sets({(x1, x2): Interval(0, 1)}, (x1, x2))
    with pytest.raises(qdframe.InputError, match="formulas in the states"):
        compile_sets({x1: x3}, (x1, x2))
    with pytest.raises(qdframe.InputError, match="keys that are states"):
        compile_sets({x3: 1}, (x1, x2))
    with pytest.raises(qdframe.InputError, match="surface"):
        compile_sets({x1: 1}, (x1,), (u,), surface=u)
    with pytest.raises(SetStructureError, match="amplitude"):
        compile_sets({x1: (Abs(x1) - Abs(u)) * Sgn(x1)}, (x1,), (u,))


def test_a_set_returned_without_its_states_is_a_one_line_input_error():
    """sets() returning the lens itself, not {(x1, x2): lens}: the error names the method, the form
    it expects and the states (it was an AttributeError from inside the compiler)."""

    class Lens(SetModel):
        state_names = "x1 x2"
        default_x0 = (0.0, 0.0)
        default_T = 1.0

        def sets(self, x1, x2):
            return Ball((0, -1), 1.5) & Ball((0, 1), 1.5)

    with pytest.raises(qdframe.InputError) as caught:
        Lens()
    message = str(caught.value)
    assert message.startswith("Lens.sets(): expected a dict") and "(x1, x2)" in message and "\n" not in message
