"""Every built-in model lives in qdframe/models/: qdframe's own entry points (pyproject.toml)
point there, under the model's own name."""

import importlib
import sys
from pathlib import Path

import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser, from the test extra
    import tomli as tomllib
PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"
ENTRIES = tomllib.loads(PYPROJECT.read_text())["project"]["entry-points"]["qdframe.models"]


@pytest.mark.parametrize("name, target", sorted(ENTRIES.items()))
def test_a_built_in_model_is_registered_from_qdframe_models(name, target):
    module, _, attribute = target.partition(":")
    assert module.startswith("qdframe.models."), target
    assert getattr(importlib.import_module(module), attribute).name == name
