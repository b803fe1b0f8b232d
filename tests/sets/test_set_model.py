"""SetModel and define_model (qdframe/sets/set_model.py): class attributes and solves."""

import pytest

import qdframe
from qdframe.sets import Abs, Interval, SetModel, define_model


def test_set_model_class_attributes_and_define_model():
    class Tiny(SetModel):
        """x' ∈ [1 − |x|, 1 + |x|]."""

        state_names = "x"
        default_x0 = (0.0,)
        default_xT = {"x": 1.5}

        def sets(self, x):
            return {x: 1 + Abs(x) * Interval(-1, 1)}

    model = Tiny()
    assert model.name == "Tiny" and model.description == "x' ∈ [1 − |x|, 1 + |x|]."
    assert model.state_names == ("x",) and model.end_indices == (0,) and list(model.end_values) == [1.5]
    assert qdframe.solve(model, nodes=51).converged
    Spread = define_model("spread", "x", lambda x: {x: 1 + Abs(x) * Interval(-1, 1)}, x0=(0.0,), xT={"x": 1.5})
    assert qdframe.solve(Spread(), nodes=51).converged
    with pytest.raises(qdframe.InputError, match="default_xT"):
        type("Bad", (SetModel,), {"state_names": "x", "default_xT": {"y": 1.0}})
