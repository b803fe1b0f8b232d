"""Deprecated: the benchmarks moved to :mod:`qdframe.bench` (one package for every
`qdframe bench` subcommand). ``import qdframe.benchmarks.<module>`` and the names of this
package keep working, with a DeprecationWarning, until the next release.
"""

import importlib
import sys
import warnings

from ..deprecation import moved

_MODULES = ("accuracy", "bvp_peer", "cli", "filippov", "friction", "peers", "references", "replay", "report", "scale",
            "sweep")
for _name in _MODULES:  # the old module paths name the new modules (the same objects)
    sys.modules[f"{__name__}.{_name}"] = globals()[_name] = importlib.import_module(f"qdframe.bench.{_name}")
warnings.warn("qdframe.benchmarks moved to qdframe.bench; import from there (qdframe.benchmarks goes in the next "
              "release)", DeprecationWarning, stacklevel=2)

__all__ = ["Case", "Plan", "ResultStore", "SUITES", "execute", "plan", "run_case", "run_sweep",
           "shifted_geometric_mean", "summarize", "write_report"]
__getattr__ = moved(__name__, "qdframe.bench", __all__)
