"""Argument types for the command line: each rejects bad text with a message that says
what was expected (argparse prefixes the option's name)."""

from __future__ import annotations

import argparse
from pathlib import Path
from collections.abc import Callable

import numpy as np

from .errors import InputError


def integer(minimum: int) -> Callable[[str], int]:
    """An integer ≥ minimum."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"expected an integer ≥ {minimum}, got {text!r}")
        return value

    return parse


def _number(text: str, positive: bool) -> float:
    """A finite number (> 0 if `positive`), or an error saying which was expected."""
    what = "a positive finite number" if positive else "a finite number"
    try:
        value = float(text)
    except ValueError:
        value = np.nan
    if not np.isfinite(value) or (positive and value <= 0):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A positive finite number."""
    return _number(text, positive=True)


def finite_float(text: str) -> float:
    """Any finite number."""
    return _number(text, positive=False)


def vector(text: str) -> list[float]:
    """Comma-separated finite numbers."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers like 0,1.5,-2, got {text!r}") from None
    if not all(np.isfinite(values)):
        raise argparse.ArgumentTypeError(f"expected finite numbers (no NaN or inf), got {text!r}")
    return values


def boundary_vector(text: str) -> list[float]:
    """Comma-separated finite numbers, or `free` (NaN) where the value is not given."""
    try:
        values = [float("nan") if v.strip() == "free" else float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers or free, like 0,free,-2, got {text!r}") from None
    if any(np.isinf(v) or (np.isnan(v) and part.strip() != "free") for v, part in zip(values, text.split(","))):
        raise argparse.ArgumentTypeError(f"expected finite numbers or the word free, got {text!r}")
    return values


def _counts(text: str, least: int, what: str, example: str) -> tuple[int, ...]:
    """Comma-separated integers ≥ `least`; `what` and `example` name them in the error."""
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated {what} like {example}, got {text!r}") from None
    if any(v < least for v in values):
        raise argparse.ArgumentTypeError(f"expected {what} ≥ {least}, got {text!r}")
    return values


def node_counts(text: str) -> tuple[int, ...]:
    """Comma-separated node counts ≥ 2."""
    return _counts(text, 2, "node counts", "11,101")


def counts(text: str) -> tuple[int, ...]:
    """Comma-separated counts ≥ 1."""
    return _counts(text, 1, "counts", "10,20")


def continuation(text: str) -> str | tuple[int, ...]:
    """"auto", "none" or comma-separated node counts ≥ 2."""
    if text in ("auto", "none"):
        return text
    try:
        return node_counts(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"expected auto, none or node counts like 11,101, got {text!r}") from None


def names(text: str) -> list[str]:
    """Comma-separated names."""
    found = [name.strip() for name in text.split(",") if name.strip()]
    if not found:
        raise argparse.ArgumentTypeError(f"expected comma-separated names like a,b, got {text!r}")
    return found


def key_value(text: str) -> tuple[str, str]:
    """KEY=VALUE (the value's type is the option's: checked where it is applied)."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip().isidentifier():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE like mu=1e-8, got {text!r}")
    return key.strip(), value.strip()


def parameter_guess(text: str) -> tuple[str, float]:
    """NAME=GUESS, GUESS a finite number: a starting guess of an unknown parameter."""
    key, sep, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if not sep or not key.strip().isidentifier():
        raise argparse.ArgumentTypeError(f"expected NAME=GUESS like mu=1.5, got {text!r}")
    if not np.isfinite(number):
        raise argparse.ArgumentTypeError(f"expected NAME=GUESS with a finite number as the guess, got {text!r}")
    return key.strip(), number


def tolerances(text: str) -> list[float]:
    """Comma-separated positive numbers like 1e-3,1e-6, or `none` for an empty ladder."""
    if text.strip() == "none":
        return []
    values = vector(text)
    if not all(v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive numbers like 1e-3,1e-6 (or none), got {text!r}")
    return values


def writable(field: str, path: str) -> None:
    """Fail early, with one line, if `path` cannot be written (tries to open it)."""
    target = Path(path).expanduser()
    existed = target.exists()
    try:
        if target.is_dir():
            raise IsADirectoryError(path)
        with open(target, "a"):
            pass
    except OSError:
        raise InputError(field, "a file path in an existing, writable directory", path) from None
    if not existed:
        target.unlink(missing_ok=True)


def figure_format(field: str, path: str) -> str:
    """The figure format of `path` from its suffix, one matplotlib can write (png, pdf, svg, …);
    an InputError naming the formats otherwise. Returns the format."""
    from matplotlib.backend_bases import FigureCanvasBase

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in formats:
        listing = ", ".join(f".{name}" for name in sorted(formats))
        raise InputError(field, f"a file name ending in a figure format matplotlib writes ({listing})", path)
    return suffix
