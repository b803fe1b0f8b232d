"""The set language (moved from qdframe/sets.py; split into modules in the next commit)."""

from .compiler import *  # noqa: F401,F403
from .compiler import Hull, Intersection, Scaled, Sum, as_set, Compiled  # noqa: F401
