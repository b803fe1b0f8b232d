"""Discretization schemes (`scheme=` / `--scheme`), registered under ``qdframe.schemes``."""

from .base import Layout, Scheme
from .implicit_euler import ImplicitEuler
from .radau import RadauIIA
from .trapezoid import Trapezoid

__all__ = ["Layout", "Scheme", "Trapezoid", "ImplicitEuler", "RadauIIA"]
