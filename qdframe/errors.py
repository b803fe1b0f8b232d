"""Exceptions of qdframe: each message names the field and the expected form."""

from __future__ import annotations


class QdframeError(Exception):
    """Base class of every error qdframe raises on purpose."""


class InputError(QdframeError, ValueError):
    """A bad argument or input (a usage error: CLI exit status 2)."""

    def __init__(self, field: str, expected: str, got: object | None = None) -> None:
        self.field = field
        self.expected = expected
        self.got = got
        message = f"{field}: expected {expected}"
        if got is not None:
            message += f", got {got!r}"
        super().__init__(message)


class UnknownNameError(InputError):
    """An unknown model, direction, line-search, scheme or option name.

    With names close to it (difflib) the message suggests them ("did you mean …?") and
    leaves the full list to `qdframe list`; otherwise it lists the available names."""

    def __init__(self, kind: str, name: str, available: list[str], where: str = "qdframe list") -> None:
        self.suggestions = close_names(name, available)
        if self.suggestions:
            self.field, self.expected = kind, f"one of the {len(available)} listed by `{where}`"
            QdframeError.__init__(self, f"{kind}: unknown name {name!r}; did you mean {_either(self.suggestions)}? "
                                        f"(`{where}` lists all {len(available)})")
        else:
            listing = ", ".join(available) if available else "(none installed)"
            InputError.__init__(self, kind, f"one of: {listing}", name)


class PluginLoadError(InputError):
    """A registered name whose plugin could not be imported (the warning before says why)."""

    def __init__(self, kind: str, name: str, distribution: str) -> None:
        self.field, self.expected = kind, "a loadable plugin"
        QdframeError.__init__(
            self, f"{kind} {name!r} is registered by distribution {distribution}, which could not be loaded "
                  f"(the warning above says why): fix it and reinstall it, or pip uninstall {distribution}")


class PluginCodeError(InputError):
    """A plugin's own code raised an exception that is not qdframe's (a model's __init__,
    sets(), blocks(), initial_guess, …): one line naming the distribution, the model, the
    method and where it raised (CLI exit status 2, like any bad input)."""

    def __init__(self, what: str, method: str, error: BaseException, distribution: str | None = None) -> None:
        import traceback

        self.field, self.expected, self.method = what, f"{method} to run", method
        frames = traceback.extract_tb(error.__traceback__)
        where = f" at {frames[-1].filename}:{frames[-1].lineno}" if frames else ""
        provider = f" (distribution {distribution})" if distribution else ""
        QdframeError.__init__(self, f"{what}{provider}: {method} raised {type(error).__name__}: "
                                    f"{_one_line(str(error))}{where}")


def close_names(name: str, available: list[str], count: int = 3) -> list[str]:
    """The names of `available` closest to `name` (difflib's ratio ≥ 0.6, a case-insensitive
    match first), best first."""
    import difflib

    folded = {candidate.lower(): candidate for candidate in available}
    exact = [folded[name.lower()]] if name.lower() in folded and folded[name.lower()] != name else []
    close = difflib.get_close_matches(name, available, n=count, cutoff=0.6)
    return list(dict.fromkeys(exact + close))[:count]


def _either(names: list[str]) -> str:
    quoted = [repr(n) for n in names]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + f" or {quoted[-1]}"


def _one_line(text: str) -> str:
    return " ".join(text.split()) or "(no message)"


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
