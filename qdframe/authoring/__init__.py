"""The model author's corner: what helps write a model, apart from the solver.

- :mod:`qdframe.sets` (its own package): models written as sets of formulas, no derivatives;
- :mod:`qdframe.ready_pieces`: ready-made pieces with gradients for hand-written models
  (:func:`affine`, :func:`constant`, :func:`coordinate`, :func:`abs_sum`), re-exported
  here; they sit in the modeling layer, which the built-in models import;
- :mod:`~qdframe.authoring.check`: ``qdframe check-model``, every piece and gradient of a
  model against finite differences (:func:`check_model`).

The interface a model implements stays in :mod:`qdframe.model`; the guide is
docs/authoring.md.
"""

from ..ready_pieces import abs_sum, affine, constant, coordinate
from .check import CheckReport, ModelCheckError, PieceCheck, check_model

__all__ = ["CheckReport", "ModelCheckError", "PieceCheck", "abs_sum", "affine", "check_model", "constant", "coordinate"]
