"""Deprecated: the benchmarks moved to :mod:`qdframe.bench` (one package for every
`qdframe bench` subcommand). ``import qdframe.benchmarks.<module>`` and the names of this
package keep working, with a DeprecationWarning, until the next release.
"""

import importlib
import sys
import warnings

from ..deprecation import moved

_MODULES = {name: f"qdframe.bench.{name}" for name in ("accuracy", "bvp_peer", "cli", "filippov", "friction", "peers",
                                                        "references", "report", "scale", "sweep")}
_MODULES["replay"] = "qdframe.projection_replay"  # the certificates' replay too: in the core since
for _name, _new in _MODULES.items():  # the old module paths name the new modules (the same objects)
    sys.modules[f"{__name__}.{_name}"] = globals()[_name] = importlib.import_module(_new)
warnings.warn("qdframe.benchmarks moved to qdframe.bench; import from there (qdframe.benchmarks goes in the next "
              "release)", DeprecationWarning, stacklevel=2)

__all__ = ["Case", "Plan", "ResultStore", "SUITES", "execute", "plan", "run_case", "run_sweep",
           "shifted_geometric_mean", "summarize", "write_report"]
__getattr__ = moved(__name__, "qdframe.bench", __all__)
