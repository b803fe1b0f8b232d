"""Exceptions of qdframe: each message names the field and the expected form."""

from __future__ import annotations


class QdframeError(Exception):
    """Base class of every error qdframe raises on purpose."""


class InputError(QdframeError, ValueError):
    """A bad argument or input (a usage error: CLI exit status 2)."""

    def __init__(self, field: str, expected: str, got: object | None = None) -> None:
        self.field = field
        self.expected = expected
        message = f"{field}: expected {expected}"
        if got is not None:
            message += f", got {got!r}"
        super().__init__(message)


class UnknownNameError(InputError):
    """An unknown model, direction or line-search name."""

    def __init__(self, kind: str, name: str, available: list[str]) -> None:
        listing = ", ".join(available) if available else "(none installed)"
        super().__init__(kind, f"one of: {listing}", name)


class ModelOutputError(QdframeError):
    """A model returned NaN/inf or arrays of the wrong shape (CLI exit status 1).

    `label` names the piece ("block F max-group 'f'"), `node` the first grid node with a
    bad value (None if unknown or not per node), `nonfinite` whether a value was NaN/inf
    (False: a wrong shape)."""

    def __init__(self, message: str, *, label: str | None = None, node: int | None = None,
                 nonfinite: bool = False) -> None:
        super().__init__(message)
        self.label = label
        self.node = node
        self.nonfinite = nonfinite


class BackendError(QdframeError):
    """A direction backend reported a failure (CLI exit status 1)."""
