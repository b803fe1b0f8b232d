"""Deprecated: `check-model` moved to :mod:`qdframe.authoring.check` (the model author's corner).

Importing a name from here still works, with a DeprecationWarning, until the next release.
"""

from .deprecation import moved

__all__ = ["CheckReport", "ModelCheckError", "PieceCheck", "add_check_parser", "check_model", "main_check"]
__getattr__ = moved(__name__, "qdframe.authoring.check", __all__)
