"""Every built-in model lives in qdframe/models/: qdframe's own entry points (pyproject.toml)
point there, under the model's own name."""

import importlib
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib")  # Python ≥ 3.11
PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"
ENTRIES = tomllib.loads(PYPROJECT.read_text())["project"]["entry-points"]["qdframe.models"]


@pytest.mark.parametrize("name, target", sorted(ENTRIES.items()))
def test_a_built_in_model_is_registered_from_qdframe_models(name, target):
    module, _, attribute = target.partition(":")
    assert module.startswith("qdframe.models."), target
    assert getattr(importlib.import_module(module), attribute).name == name
