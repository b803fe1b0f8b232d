"""Names that moved in the package layout (issue 18) still work from their old place for one
release, with a DeprecationWarning naming the new place, and are the same objects."""

import importlib
import warnings

import pytest

import qdframe.sets

MOVED = [
    ("qdframe.check", "qdframe.authoring.check",
     ("CheckReport", "ModelCheckError", "PieceCheck", "add_check_parser", "check_model", "main_check")),
    ("qdframe.benchmarks.models", "qdframe.models.bounded_input",
     ("BAND", "BENCH_MODELS", "SLIDING_A", "SLIDING_B", "SLIDING_TARGET", "SLIDING_X0", "CoulombRestToRest",
      "SlidingModeTerminal")),
    ("qdframe.model", "qdframe.authoring.pieces", ("abs_sum",)),
    ("qdframe.hard", "qdframe.bench.hard", ("CASES", "HardCase", "run", "table")),
    ("qdframe.bench", "qdframe.bench.directions",  # the old module qdframe.bench is the package's .directions
     ("BenchRow", "Instance", "PAPER_MODELS", "degenerate_instances", "installed_directions", "paper_instances")),
    ("qdframe.benchmarks", "qdframe.bench", ("Case", "SUITES", "plan", "run_sweep", "write_report")),
    ("qdframe.psi", "qdframe.functional.psi", ("best_sample", "maximize_on_sphere", "sphere_samples")),
]


@pytest.mark.parametrize("old, new, names", MOVED)
def test_a_moved_name_warns_and_is_the_same_object(old, new, names):
    with warnings.catch_warnings():  # an old package warns once on import as well (qdframe.benchmarks)
        warnings.simplefilter("ignore", DeprecationWarning)
        before = importlib.import_module(old)
    after = importlib.import_module(new)
    for name in names:
        with pytest.warns(DeprecationWarning, match=f"{old}.{name} moved to {new}.{name}"):
            assert getattr(before, name) is getattr(after, name)


def test_an_unknown_name_of_a_moved_module_is_an_attribute_error():
    import qdframe.check

    with pytest.raises(AttributeError, match="no_such_name"):
        qdframe.check.no_such_name  # noqa: B018


def test_every_name_of_the_set_language_imports_from_qdframe_sets():
    # the names qdframe.sets had as one module, now re-exported by the package
    for name in [*qdframe.sets.__all__, "Set", "Hull", "Intersection", "Scaled", "Sum", "as_set", "Compiled"]:
        assert getattr(qdframe.sets, name) is not None, name


def test_the_old_benchmark_modules_are_the_new_ones():
    with pytest.warns(DeprecationWarning, match="qdframe.benchmarks moved to qdframe.bench"):
        import qdframe.benchmarks  # noqa: F401  (first import: warns)

        importlib.reload(qdframe.benchmarks)
    import qdframe.bench.sweep
    import qdframe.benchmarks.sweep

    assert qdframe.benchmarks.sweep is qdframe.bench.sweep
    # the names qdframe.bench had as one module (bench directions) are still there
    import qdframe.bench

    assert qdframe.bench.bench_directions is qdframe.bench.directions.bench_directions
