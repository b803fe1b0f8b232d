"""Names that moved: the old place keeps working for one release, with a DeprecationWarning.

A module whose contents moved keeps only its docstring and

    __getattr__ = moved(__name__, "qdframe.new.place", ("Name", "other_name"))

(PEP 562): each name read from the old module warns, naming the new place, and returns
the object of the new module (the same object, so isinstance checks and registries agree).
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Iterable
from typing import Any


def moved(old: str, new: str, names: Iterable[str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for `old` that forwards `names` to the module `new`, with a warning."""
    forwarded = frozenset(names)

    def __getattr__(name: str) -> Any:
        if name not in forwarded:
            raise AttributeError(f"module {old!r} has no attribute {name!r}")
        warnings.warn(
            f"{old}.{name} moved to {new}.{name}; import it from there ({old} goes in the next release)",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module(new), name)

    return __getattr__
