"""Registries of models, direction solvers, line searches, schemes, step QPs and benchmark
peers, fed by entry points, and the factories that build one by name (`load_model`,
`make_direction`, `make_line_search`, `make_peer`).

qdframe's own built-ins are declared in its pyproject under the same groups as any
plugin's (`qdframe.models`, `qdframe.directions`, `qdframe.line_searches`,
`qdframe.schemes`, `qdframe.step_qps`: gauss-newton's step-QP backends,
`qdframe.peers`: the tools `qdframe bench run --peers` compares with). A plugin
that fails to load is a warning naming its distribution; two distributions claiming
one name give a warning and a deterministic winner (qdframe itself first, then by
distribution name); an unknown name is an error suggesting the close ones ("did you
mean …?"), and a name whose plugin failed to load an error saying so (not a typo).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from .errors import PluginCodeError, PluginLoadError, QdframeError, UnknownNameError

GROUPS = {
    "models": "qdframe.models",
    "directions": "qdframe.directions",
    "line_searches": "qdframe.line_searches",
    "schemes": "qdframe.schemes",
    "step_qps": "qdframe.step_qps",
    "peers": "qdframe.peers",
}
KIND_LABEL = {"models": "model", "directions": "direction", "line_searches": "line search", "schemes": "scheme",
              "step_qps": "step QP", "peers": "peer"}


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
def _points(kind: str) -> dict[str, EntryPoint]:
    """The entry points of a kind by name, without importing them (winners of clashes)."""
    found: dict[str, EntryPoint] = {}
    candidates = sorted(
        entry_points(group=GROUPS[kind]),
        key=lambda ep: (_distribution(ep) != "qdframe", _distribution(ep), ep.name),
    )
    for ep in candidates:
        if ep.name in found:
            if found[ep.name].value != ep.value:
                warnings.warn(
                    f"{KIND_LABEL[kind]} {ep.name!r} from {_distribution(ep)} is shadowed by the one from "
                    f"{_distribution(found[ep.name])}; rename it in {_distribution(ep)}'s entry points "
                    f"(then reinstall it) or pip uninstall {_distribution(ep)}",
                    PluginWarning,
                    stacklevel=4,
                )
            continue
        found[ep.name] = ep
    return found


@lru_cache(maxsize=None)
def _load(kind: str, name: str) -> Entry | None:
    """Import one entry; a failure is a warning naming its distribution, and None."""
    ep = _points(kind)[name]
    dist = _distribution(ep)
    try:
        obj = ep.load()
    except Exception as exc:  # a broken plugin must not break qdframe
        warnings.warn(
            f"could not load {KIND_LABEL[kind]} {ep.name!r} from distribution {dist} "
            f"({ep.value}): {type(exc).__name__}: {exc}; fix that module (then reinstall {dist}) or pip uninstall {dist}",
            PluginWarning,
            stacklevel=4,
        )
        return None
    entry = Entry(kind, ep.name, dist, ep.value, obj)
    if isinstance(obj, type):
        _PROVIDERS.setdefault(obj, entry)
    return entry


_PROVIDERS: dict[type, Entry] = {}
"""The entry of each class loaded so far, to name a plugin's distribution in its errors."""


def provider(cls: type) -> Entry | None:
    """The registered entry that provides `cls` (or the nearest registered base class it
    extends: a subclass made at run time), among those loaded; None if none."""
    for base in getattr(cls, "__mro__", ()):
        if base in _PROVIDERS:
            return _PROVIDERS[base]
    return None


def available(kind: str) -> dict[str, Entry]:
    """Every loadable entry of a kind ('models', 'directions', 'line_searches'); imports them all."""
    loaded = {name: _load(kind, name) for name in _points(kind)}
    return {name: entry for name, entry in loaded.items() if entry is not None}


@contextmanager
def plugin_code(owner: object, method: str, kind: str = "model") -> Iterator[None]:
    """Run a plugin's own code (a model's `__init__`, `sets()`, `initial_guess()`, …): an
    exception that is not qdframe's becomes a :class:`PluginCodeError`, one line naming the
    distribution, the model, the method and the file and line that raised (the original
    chained as its cause). qdframe's own errors pass unchanged."""
    try:
        yield
    except QdframeError:
        raise
    except Exception as exc:
        cls = owner if isinstance(owner, type) else type(owner)
        entry = provider(cls)
        name = (entry.name if entry is not None and isinstance(owner, type) else getattr(owner, "name", "")) or cls.__name__
        raise PluginCodeError(f"{kind} {name!r}", method, exc, entry.distribution if entry else None) from exc


def names(kind: str) -> list[str]:
    """The registered names of a kind, without importing anything."""
    return sorted(_points(kind))


def refresh() -> None:
    """Forget the cached entry points (after installing a plugin at run time)."""
    _points.cache_clear()
    _load.cache_clear()
    _PROVIDERS.clear()


def lookup(kind: str, name: str) -> Entry:
    """The entry called `name`, importing only it. A name 'prefix:arg' resolves to the
    entry 'prefix:'. An unknown name is an UnknownNameError suggesting close names; a name
    whose plugin cannot be imported a PluginLoadError naming its distribution."""
    points = _points(kind)
    prefix, sep, _ = name.partition(":")
    key = name if name in points else f"{prefix}:" if sep and f"{prefix}:" in points else None
    if key is None:  # 'qpsolver:daqp' is compared with 'qpsolvers:daqp', the entry 'qpsolvers:' with its argument
        _, _, argument = name.partition(":")
        known = sorted(f"{n}{argument}" if n.endswith(":") and sep else n for n in points)
        raise UnknownNameError(KIND_LABEL[kind], name, known)
    entry = _load(kind, key)
    if entry is None:
        raise PluginLoadError(KIND_LABEL[kind], name, _distribution(points[key]))
    return entry


# ------------------------------------------------------------------ the factories
def load_model(name: str, **overrides) -> Any:
    """A registered model (an InclusionModel) by name; `overrides` are T, x0, end_values. An exception of the
    model's own code (its `__init__`, `sets()`, …) is a PluginCodeError naming it."""
    entry = lookup("models", name)
    with plugin_code(entry.obj, "__init__"):
        return entry.obj(**overrides)


def make_direction(direction: Any) -> Any:
    """A direction solver (a DirectionSolver) by registered name ('prefix:arg' names too), or
    the instance given. The registry sits below the classes it builds: it imports none."""
    if not isinstance(direction, str):
        return direction
    entry = lookup("directions", str(direction))
    return entry.obj.from_name(direction) if hasattr(entry.obj, "from_name") else entry.obj()


def make_line_search(line_search: Any) -> Any:
    """A line search (a LineSearch) by registered name, or the instance given."""
    if not isinstance(line_search, str):
        return line_search
    return lookup("line_searches", str(line_search)).obj()


def make_peer(peer: Any) -> Any:
    """A benchmark peer (a :class:`qdframe.bench.peer.Peer`) by registered name, or the instance given."""
    if not isinstance(peer, str):
        return peer
    return lookup("peers", str(peer)).obj()
