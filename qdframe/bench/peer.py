"""The peer interface: another tool the benchmark runs beside qdframe on the catalogue's
problems (:mod:`.problems`), judged by the same yardstick (:mod:`.references`).

A peer is a :class:`Peer` registered under the entry-point group ``qdframe.peers``
(qdframe's own: ``nosnoc``, :mod:`.nosnoc_peer`; ``solve_bvp``, :mod:`.solve_bvp_peer`).
It says whether it can run here (:meth:`Peer.unavailable`), states a problem or declines
it (:meth:`Peer.states`), and runs one at one setting of its accuracy knob
(:meth:`Peer.run`): `nodes` (the sweep's peer grids) or `tol` (its tolerances). Adding a
peer is one module and one entry point (docs/benchmarks.md, "Adding a peer").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from typing import ClassVar

import numpy as np

from ..model import InclusionModel
from ..status import Status

KNOBS = ("nodes", "tol")


@dataclass
class PeerRun:
    """What a peer produced, to be judged on qdframe's yardstick."""

    status: Status  # SOLVED when the peer reports success, FAILED otherwise
    message: str
    iterations: int
    wall_time_s: float
    setup_time_s: float
    x: np.ndarray | None = None
    z: np.ndarray | None = None
    history: list[dict] = field(default_factory=list)  # per homotopy step: iteration, I, objective, time_s
    t: np.ndarray | None = None  # the peer's own time grid (None: N uniform nodes)
    inputs: Callable[[float], np.ndarray] | None = None  # the peer's own input u(t), where it has one


class Peer:
    """A tool the benchmark compares qdframe with.

    `name` is the `direction` of its rows, `inner` (its inner solver) their `line_search`,
    `line` its line in a work-precision diagram; `knob` says which setting a run takes."""

    name: ClassVar[str]
    inner: ClassVar[str]
    line: ClassVar[str]
    knob: ClassVar[str]  # one of KNOBS
    description: ClassVar[str] = ""

    def unavailable(self) -> str | None:
        """None where the peer can run here, else why not (with the install command)."""
        return None

    def states(self, model: InclusionModel) -> bool:
        """Whether the peer can state `model` (a catalogue problem's model)."""
        raise NotImplementedError

    def run(self, model: InclusionModel, setting: float) -> PeerRun:
        """Solve `model` at one setting of the knob (nodes: an int; tol: a float)."""
        raise NotImplementedError


def package_version(distribution: str) -> str:
    """The installed version of `distribution`, or "?"."""
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return "?"
