"""qdframe-mechanics: the model families of the paper's Section 5 as a qdframe plugin.

The models register through the `qdframe.models` entry points of this distribution's
pyproject.toml; `qdframe list` shows them under `qdframe-mechanics`.
"""

__version__ = "0.1.0"
