"""The problem catalogue: every benchmark problem in one place, with all the benchmarks know
about it.

A :class:`Problem` names a registered model and carries

- its **tags**: the suites and subcommands that run it (``quick``, ``standard``, ``scale``,
  ``directions``, ``friction-suite``, ``unknowns``, and the groups ``paper``, ``friction``,
  ``plugin``, ``control``, ``long-horizon``, ``user-friction``);
- its **sign form** for the peers (:mod:`.sign_forms`: x' ∈ f + Σ a_j·Sgn(c_j), which nosnoc
  and solve_bvp state it from), or None;
- its **replay statement** (:mod:`.replay_statements`: the separable Filippov system the
  event-driven integrator runs for the reference), or None;
- its **input recovery**, for a problem with an input judged by the motion that input
  drives (:mod:`.references`), or None.

Its reference follows from these and the model: the model's closed form where it has one,
else the replayed motion of its input where it has an input recovery, else the projection
replay (:func:`.references.kind`). A peer (:mod:`.peer`) states a problem from its sign form
or its own statement, or declines it.

Adding a problem is one entry in :data:`CATALOGUE` (docs/benchmarks.md, "Adding a problem").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from ..certificates.filippov import FilippovSystem, FilippovTrajectory, integrate
from . import replay_statements as replay
from . import sign_forms as forms

Input = Callable[[float], np.ndarray]


@dataclass(frozen=True)
class Problem:
    """One benchmark problem: a registered model's name and what the benchmarks know of it."""

    name: str
    tags: frozenset[str] = field(default_factory=frozenset)
    sign_form: Callable[[object], forms.SignForm] | None = None  # model -> its peers' statement
    replay: Callable[[object, Input | None], FilippovSystem | None] | None = None  # (model, input) -> system
    inputs: Callable | None = None  # (x, z, u, model, selections) -> the input(s) at the trajectory's points


def _problem(name: str, tags: str = "", sign_form=None, replay=None, inputs=None) -> Problem:
    return Problem(name, frozenset(tags.split()), sign_form, replay, inputs)


CATALOGUE: dict[str, Problem] = {problem.name: problem for problem in (
    # the paper's examples (Section 7)
    _problem("paper-7.1", "paper standard quick scale directions"),
    _problem("paper-7.2", "paper standard scale directions"),
    _problem("paper-7.3", "paper standard scale", replay=replay.paper_73, inputs=replay.paper_control),
    _problem("paper-7.3-reduced", "", replay=replay.paper_73, inputs=replay.paper_control),
    # the qdframe-mechanics plugin's models
    _problem("coulomb-block", "plugin standard friction-suite", forms.coulomb_block, replay.coulomb_block),
    _problem("sliding-mode", "plugin standard", forms.sliding_mode, replay.sliding_mode),
    _problem("double-pendulum", "plugin standard"),
    _problem("velocity-range", "plugin standard"),
    _problem("disturbed-control", "plugin standard"),
    _problem("intersecting-balls", "plugin standard"),
    # stick, slide and switch, with exact solutions (qdframe.models.exact_friction)
    _problem("block-stop-stick", "friction standard quick friction-suite", forms.block_stop_stick,
             replay.block_stop_stick),
    _problem("block-stop-stick-bvp", "friction standard friction-suite", forms.block_stop_stick,
             replay.block_stop_stick),
    _problem("block-breakaway", "friction standard friction-suite", forms.block_breakaway, replay.block_breakaway),
    _problem("slide-on-line", "friction standard friction-suite", forms.slide_on_line, replay.slide_on_line),
    _problem("slide-after-reaching", "friction standard quick friction-suite", forms.slide_on_line,
             replay.slide_on_line),
    _problem("two-surface-sliding", "friction standard friction-suite", forms.two_surface, replay.two_surface),
    # bounded-input control problems (qdframe.models.bounded_input): judged by the motion their input drives
    _problem("coulomb-rest-to-rest", "control standard quick", replay=replay.coulomb_rest_to_rest,
             inputs=replay.coulomb_force),
    _problem("sliding-mode-terminal", "control standard quick friction-suite", replay=replay.sliding_mode_terminal,
             inputs=replay.sliding_inputs),
    # a long horizon, and the friction models users brought (qdframe.models.user_friction)
    _problem("stick-slip-oscillator", "long-horizon standard", forms.stick_slip, replay.stick_slip_oscillator),
    _problem("pivot-friction-pendulum", "user-friction standard", forms.pendulum),
    _problem("two-block-chain", "user-friction standard", forms.two_block_chain),
    _problem("relay-oscillator", "user-friction standard", forms.relay),
    # T or a coefficient found with x (qdframe.models.identification)
    _problem("block-friction-coefficient", "friction-suite unknowns"),
    _problem("block-stopping-time", "friction-suite unknowns"),
)}


def problem(name: str) -> Problem | None:
    """The catalogue's entry for model `name`, None for a model it does not hold."""
    return CATALOGUE.get(name)


def tagged(tag: str) -> tuple[str, ...]:
    """The names of the problems with `tag`, in catalogue order."""
    return tuple(name for name, entry in CATALOGUE.items() if tag in entry.tags)


def with_sign_form() -> tuple[str, ...]:
    """The problems the peers can state from a sign form."""
    return tuple(name for name, entry in CATALOGUE.items() if entry.sign_form is not None)


def sign_form(model) -> forms.SignForm | None:
    """The sign form of `model` (its constants read from the instance), None if it has none."""
    entry = problem(getattr(model, "name", ""))
    return None if entry is None or entry.sign_form is None else entry.sign_form(model)


def recovers_inputs(model) -> bool:
    """Whether `model` is judged by the motion of an input recovered from its trajectory."""
    entry = problem(getattr(model, "name", ""))
    return entry is not None and entry.inputs is not None


def recovered_inputs(model, x, z, u, selections=None):
    """The input(s) of `model` recovered at a trajectory's points (see :data:`Problem.inputs`)."""
    return problem(model.name).inputs(x, z, u, model, selections)


def statement(model, inputs: Input | None = None) -> FilippovSystem | None:
    """The separable Filippov system x' ∈ g − Σ a_i·Sgn(c_i)·b_i of a catalogue problem, its
    parameters read from the model (class attributes, module constants); None for a model
    the catalogue cannot state, or one that needs `inputs` when none is given. An `inputs`
    with a `breaks` attribute (times of its jumps) passes them to the system
    (:mod:`.replay_statements` says how each model is stated)."""
    entry = problem(getattr(model, "name", ""))
    system = None if entry is None or entry.replay is None else entry.replay(model, inputs)
    if system is None or not getattr(inputs, "breaks", ()):
        return system
    return replace(system, breaks=tuple(inputs.breaks))


def start(model) -> np.ndarray | None:
    """model.x0, its NaN entries (free starts) taken from the model's exact solution at 0; None if unknown."""
    x0 = np.array(model.x0, dtype=float)
    if np.all(np.isfinite(x0)):
        return x0
    exact = model.exact_solution(np.array([0.0]))
    if exact is None:
        return None
    return np.where(np.isfinite(x0), x0, exact[0])


def reference(model, inputs: Input | None = None, rtol: float = 1e-12, atol: float = 1e-12) -> FilippovTrajectory | None:
    """The Filippov motion of `model` over [0, model.T] from :func:`start`, by the event-driven
    integrator; None when :func:`statement` cannot state the model or its start is unknown."""
    system, x0 = statement(model, inputs), start(model)
    if system is None or x0 is None:
        return None
    return integrate(system, x0, model.T, rtol, atol)
