"""Registries of models, direction solvers and line searches, fed by entry points.

qdframe's own built-ins are declared in its pyproject under the same groups as any
plugin's (`qdframe.models`, `qdframe.directions`, `qdframe.line_searches`). A plugin
that fails to load is a warning naming its distribution; two distributions claiming
one name give a warning and a deterministic winner (qdframe itself first, then by
distribution name); an unknown name is an error listing the available ones.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache
from importlib.metadata import EntryPoint, entry_points

from .errors import UnknownNameError

GROUPS = {
    "models": "qdframe.models",
    "directions": "qdframe.directions",
    "line_searches": "qdframe.line_searches",
}
KIND_LABEL = {"models": "model", "directions": "direction", "line_searches": "line search"}


class PluginWarning(UserWarning):
    """A plugin could not be loaded or shadows another."""


@dataclass(frozen=True)
class Entry:
    """One registered name: the class it loads and the distribution providing it."""

    kind: str
    name: str
    distribution: str
    target: str
    obj: type

    @property
    def description(self) -> str:
        text = getattr(self.obj, "description", "") or (self.obj.__doc__ or "")
        return text.strip().splitlines()[0] if text.strip() else ""


def _distribution(ep: EntryPoint) -> str:
    dist = getattr(ep, "dist", None)
    return dist.metadata["Name"] if dist is not None else "unknown"


@lru_cache(maxsize=None)
def _entries(kind: str) -> dict[str, Entry]:
    found: dict[str, Entry] = {}
    candidates = sorted(
        entry_points(group=GROUPS[kind]),
        key=lambda ep: (_distribution(ep) != "qdframe", _distribution(ep), ep.name),
    )
    for ep in candidates:
        dist = _distribution(ep)
        if ep.name in found:
            if found[ep.name].target != ep.value:
                warnings.warn(
                    f"{KIND_LABEL[kind]} {ep.name!r} from {dist} is shadowed by the one from "
                    f"{found[ep.name].distribution}",
                    PluginWarning,
                    stacklevel=3,
                )
            continue
        try:
            obj = ep.load()
        except Exception as exc:  # a broken plugin must not break qdframe
            warnings.warn(
                f"could not load {KIND_LABEL[kind]} {ep.name!r} from distribution {dist} "
                f"({ep.value}): {type(exc).__name__}: {exc}",
                PluginWarning,
                stacklevel=3,
            )
            continue
        found[ep.name] = Entry(kind, ep.name, dist, ep.value, obj)
    return found


def available(kind: str) -> dict[str, Entry]:
    """Every loadable entry of a kind ('models', 'directions', 'line_searches')."""
    return dict(_entries(kind))


def refresh() -> None:
    """Forget the cached entry points (after installing a plugin at run time)."""
    _entries.cache_clear()


def lookup(kind: str, name: str) -> Entry:
    """The entry called `name`. A name 'prefix:arg' resolves to the entry 'prefix:'."""
    entries = _entries(kind)
    if name in entries:
        return entries[name]
    prefix, sep, _ = name.partition(":")
    if sep and f"{prefix}:" in entries:
        return entries[f"{prefix}:"]
    raise UnknownNameError(KIND_LABEL[kind], name, sorted(entries))
