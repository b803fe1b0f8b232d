"""qdframe: trajectories of nonsmooth differential inclusions by quasidifferential descent.

The three interfaces: :class:`InclusionModel` (qdframe.model), :class:`DirectionSolver`
(qdframe.directions.base) and :class:`LineSearch` (qdframe.line_searches.base).
"""

from .descent import DescentOptions, load_model, solve
from .directions.base import Direction, DirectionSolver, MinNormDirection
from .errors import BackendError, InputError, ModelOutputError, QdframeError
from .line_searches.base import LineSearch
from .model import Cost, InclusionModel, MaxGroup, MinGroup, SetBlock, Surface
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
