"""qdframe: trajectories of nonsmooth differential inclusions by quasidifferential descent.

The four interfaces: :class:`InclusionModel` (qdframe.model), :class:`DirectionSolver`
(qdframe.directions.base), :class:`LineSearch` (qdframe.line_searches.base) and
:class:`~qdframe.schemes.base.Scheme` (qdframe.schemes); docs/architecture.md shows how a
solve flows through them.
"""

from .descent.loop import DescentOptions
from .solve.solving import solve
from .directions.base import Direction, DirectionSolver, MinNormDirection
from .errors import BackendError, InputError, ModelOutputError, QdframeError
from .line_searches.base import LineSearch
from .model import Cost, InclusionModel, MaxGroup, MinGroup, SetBlock, Surface
from .registry import load_model
from .result import SolveResult

__version__ = "0.1.0"

__all__ = [
    "BackendError",
    "Cost",
    "DescentOptions",
    "Direction",
    "DirectionSolver",
    "InclusionModel",
    "InputError",
    "LineSearch",
    "MaxGroup",
    "MinGroup",
    "MinNormDirection",
    "ModelOutputError",
    "QdframeError",
    "SetBlock",
    "SolveResult",
    "Surface",
    "load_model",
    "solve",
]
