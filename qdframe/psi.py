"""Deprecated: the ψ* search moved to :mod:`qdframe.functional.psi` (with the pieces it serves).

Importing a name from here still works, with a DeprecationWarning, until the next release.
"""

from .deprecation import moved

__all__ = ["best_sample", "maximize_on_sphere", "sphere_samples"]
__getattr__ = moved(__name__, "qdframe.functional.psi", __all__)
