"""Deprecated: `bench hard` moved to :mod:`qdframe.bench.hard` (one package for every benchmark).

Importing a name from here still works, with a DeprecationWarning, until the next release.
"""

from .deprecation import moved

__all__ = ["CASES", "HardCase", "run", "table"]
__getattr__ = moved(__name__, "qdframe.bench.hard", __all__)
