"""Deprecated: coulomb-rest-to-rest and sliding-mode-terminal moved to
:mod:`qdframe.models.bounded_input` (every built-in model lives in :mod:`qdframe.models`).

Importing a name from here still works, with a DeprecationWarning, until the next release;
so do entry points installed before the move (reinstall qdframe to repoint them).
"""

from ..deprecation import moved

__all__ = ["BAND", "BENCH_MODELS", "SLIDING_A", "SLIDING_B", "SLIDING_TARGET", "SLIDING_X0", "CoulombRestToRest",
           "SlidingModeTerminal"]
__getattr__ = moved(__name__, "qdframe.models.bounded_input", __all__)
