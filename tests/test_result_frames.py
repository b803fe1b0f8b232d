"""Results for notebooks (issue 17, item 14): SolveResult's repr, to_dataframe() and to_xarray()."""

import dataclasses
import sys

import numpy as np
import pytest

import qdframe

# paper-7.3's x(0) given (its default is simulated at first use): states, a control u and
# three sign terms with selections; a short run is enough, the frames need not be solved
X0_73 = [-1.0524, 1.0994, -0.7873, 0.0, 0.0265, 1.1196]


@pytest.fixture(scope="module")
def masses():
    return qdframe.solve(qdframe.load_model("paper-7.3", x0=X0_73), nodes=11, max_iter=3)


@pytest.fixture(scope="module")
def paper71():
    return qdframe.solve("paper-7.1", nodes=11, max_iter=10)


# ---------------------------------------------------------------- repr
def test_repr_says_how_it_ended_in_a_few_lines(paper71):
    text = repr(paper71)
    lines = text.splitlines()
    assert 3 <= len(lines) <= 6 and all(len(line) < 130 for line in lines)
    assert lines[0].startswith(f"SolveResult paper-7.1: {paper71.status}, {paper71.iterations} iterations, 11 nodes")
    assert f"I {paper71.I:.3e}" in text and f"cost {paper71.cost:.3e}" in text
    assert f"boundary {paper71.boundary_error:.2e}" in text
    assert f"inclusion {paper71.inclusion_residual:.2e}" in text
    assert f"consistency {paper71.consistency_error:.2e}" in text
    assert "selection" not in text and "surface" not in text  # paper-7.1 has neither
    assert f"error vs the known solution {paper71.solution_error:.2e}" in text  # it has a known solution
    assert str(paper71) == text


def test_repr_shows_the_residuals_the_model_has_and_the_message(masses):
    text = repr(masses)
    assert f"selection {masses.selection_residual:.2e}" in text and f"surface {masses.surface_error:.2e}" in text
    assert "known solution" not in text  # none known for 7.3: no error estimate is invented
    assert masses.status == "max_iter" and text.splitlines()[-1] == f"  message: {masses.message}"
    assert masses.residuals() == {"boundary": masses.boundary_error, "inclusion": masses.inclusion_residual,
                                  "consistency": masses.consistency_error, "selection": masses.selection_residual,
                                  "surface": masses.surface_error}


# ---------------------------------------------------------------- pandas
def test_dataframe_is_indexed_by_t_with_a_column_per_state(masses):
    pytest.importorskip("pandas")
    df = masses.to_dataframe()
    assert df.index.name == "t" and np.array_equal(df.index.to_numpy(), masses.t)
    states = list(masses.state_names)
    assert list(df.columns) == (states + [f"{name}'" for name in states] + ["u"]
                                + ["1.05|x|Sgn(x4)", "0.3 Sgn(x5)", "0.3 Sgn(x6)"])
    assert np.array_equal(df[states].to_numpy(), masses.x)
    assert np.array_equal(df["x4'"].to_numpy(), masses.z[:, 3])
    assert np.array_equal(df["u"].to_numpy(), masses.u[:, 0])
    assert np.array_equal(df["0.3 Sgn(x6)"].to_numpy(), masses.selections[:, 2])
    assert df.loc[masses.t[4], "x2"] == masses.x[4, 1]


def test_dataframe_without_controls_or_selections_has_only_x_and_z_and_a_costs_multipliers(paper71):
    pytest.importorskip("pandas")
    df = paper71.to_dataframe()  # 7.1 has a cost (∫|x1|): its multipliers μ of x' = f follow
    assert list(df.columns) == ["x1", "x2", "x1'", "x2'", "μ_x1", "μ_x2"] and df.shape == (11, 6)
    assert np.array_equal(df[["μ_x1", "μ_x2"]].to_numpy(), paper71.multipliers)


def test_repeated_names_get_their_number(masses):
    pytest.importorskip("pandas")
    renamed = dataclasses.replace(masses, selection_names=["sgn", "sgn", "x1"], control_names=())
    df = renamed.to_dataframe()
    assert list(df.columns[-4:]) == ["u", "sgn [1]", "sgn [2]", "x1 [3]"]  # "x1" is a state's column
    assert df.columns.is_unique


# ---------------------------------------------------------------- xarray
def test_dataset_has_t_state_names_and_attrs(masses):
    pytest.importorskip("xarray")
    ds = masses.to_xarray()
    assert ds["x"].dims == ("t", "state") and ds["z"].dims == ("t", "state")
    assert list(ds["state"].values) == list(masses.state_names)
    assert np.array_equal(ds["t"].values, masses.t)
    assert np.array_equal(ds["x"].sel(state="x3").values, masses.x[:, 2])
    assert np.array_equal(ds["z"].values, masses.z)
    assert ds["u"].dims == ("t", "control") and list(ds["control"].values) == ["u"]
    assert np.array_equal(ds["u"].values, masses.u)
    assert list(ds["selection"].values) == masses.selection_names
    assert np.array_equal(ds["selections"].sel(selection="0.3 Sgn(x5)").values, masses.selections[:, 1])
    attrs = ds.attrs
    assert (attrs["model"], attrs["status"], attrs["nodes"]) == ("paper-7.3", masses.status, 11)
    assert type(attrs["status"]) is str and type(masses.to_dataframe().attrs["status"]) is str  # not the enum
    assert attrs["I"] == masses.I and attrs["residual_surface"] == masses.surface_error
    assert attrs["residual_selection"] == masses.selection_residual
    assert all(isinstance(value, (str, int, float)) for value in attrs.values())  # netCDF-ready


def test_dataset_without_controls(paper71):
    pytest.importorskip("xarray")
    ds = paper71.to_xarray()
    assert set(ds.data_vars) == {"x", "z"} and "control" not in ds.dims
    assert ds.attrs["solution_error"] == paper71.solution_error and "residual_surface" not in ds.attrs


# ---------------------------------------------------------------- optional extras
@pytest.mark.parametrize("method, module", [("to_dataframe", "pandas"), ("to_xarray", "xarray")])
def test_a_missing_extra_says_how_to_install_it(paper71, monkeypatch, method, module):
    monkeypatch.setitem(sys.modules, module, None)  # import fails as if not installed
    with pytest.raises(ImportError, match=rf"^SolveResult\.{method}\(\) needs {module}: pip install 'qdframe\[frames\]'$"):
        getattr(paper71, method)()


def test_a_results_records_are_typed_frozen_and_its_options_their_fields():
    """Issue 54: SolveResult.options was a free dict written by five modules (and a side
    channel); it is now the fields of frozen records, in one dict, in the JSON too."""
    import dataclasses
    import json

    import qdframe
    from qdframe.result import DescentRecord, GridsRecord, UnknownsRecord, VerdictRecord

    result = qdframe.solve("block-friction-coefficient")
    assert isinstance(result.descent, DescentRecord) and isinstance(result.grids, GridsRecord)
    assert isinstance(result.verdict, VerdictRecord) and isinstance(result.unknowns, UnknownsRecord)
    assert result.penalty is None  # no cost
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.grids.start = "line"  # type: ignore[misc]
    fields = {}
    for record in (result.descent, result.verdict, result.grids, result.unknowns):
        fields.update(dataclasses.asdict(record))
    assert result.options.keys() == fields.keys() and result.options["grids"] == list(result.grids.grids)
    assert result.options["start"] == result.grids.start and not result.T_found
    assert json.loads(result.to_json())["options"] == json.loads(json.dumps(result.options))
    result.options["start"] = "changed"  # a copy: the records are the result's own
    assert result.grids.start != "changed"


def test_a_selection_column_reads_the_sign_its_name_writes():
    """u − 0.3·Sgn(v) is stored as 0.3·Sgn(−v), whose selection is −1 where v > 0: the column named
    "-0.3·Sgn(v)" shows the λ of Sgn(v) as written (+1 there), in the DataFrame and the Dataset alike,
    and a term written 0.3·Sgn(−v) shows its own (−1); `selections` keeps the stored λ."""
    pytest.importorskip("pandas")
    pytest.importorskip("xarray")
    from qdframe.sets import SetModel, Sgn

    def thrown(field):
        class Thrown(SetModel):
            state_names = "p v"
            default_x0 = (0.0, 1.0)
            default_T = 1.0

            def sets(self, p, v):
                return {p: v, v: field(v)}

        return qdframe.solve(Thrown(), nodes=11)

    for field, name, shown in ((lambda v: -0.3 * Sgn(v), "-0.3·Sgn(v)", 1.0),
                               (lambda v: 0.3 * Sgn(-v), "0.3·Sgn(-v)", -1.0)):
        result = thrown(field)
        moving = np.asarray(result.x)[:, 1] > 0.1
        frame = result.to_dataframe()
        assert list(frame.columns)[-1] == name
        assert np.all(frame[name].to_numpy()[moving] == shown)
        assert np.all(result.to_xarray()["selections"].values[moving, 0] == shown)
        assert np.all(np.asarray(result.selections)[moving, 0] == -1.0)  # the stored Sgn(−v)'s
