"""What a solve will run, decided from its arguments before any work: :func:`plan` and the
frozen :class:`Plan` that :func:`qdframe.solve`, its verdict and the command line read.

One rule decides a solve's kind: given `accuracy`, or neither `nodes` nor `mesh`, the mesh is
refined until the error estimate meets the target (``refining``); otherwise the grid is fixed
and its estimate is made once. The kind sets the other defaults:

==================  =========================================  ==================================
                    refining                                   fixed grid
==================  =========================================  ==================================
first points        `nodes`, else 21 (or the model's motion)   `nodes`, else 101
scheme              `scheme`, else radau-iia (implicit Euler   `scheme`, else the model's
                    first, to find the switches)               `default_scheme`
budget (max_iter)   the direction's `certified_max_iter`       500
residual_tol        1e-8, and at most target/100 (the checks   1e-8
                    under a target below 1e-6)
ε floor             1e-12 (ε and δ shrink)                     ε (the paper's fixed ε and δ)
==================  =========================================  ==================================
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..certificates.estimates import CERTIFICATES
from ..descent.options import EPS_FLOOR, DescentOptions
from ..directions.base import DirectionSolver
from ..errors import InputError
from ..schemes.grid import Grid
from ..line_searches.base import LineSearch
from ..model import InclusionModel
from ..registry import make_direction, make_line_search
from ..schemes import Scheme
from ..schemes.grid import check_mesh

DEFAULT_ACCURACY = 1e-6  # the target when none is given: max|x − x*| ≤ 1e-6·max(1, max|x|)
DEFAULT_MAX_ITER = 500  # max_iter=None on a fixed grid (a certified solve: the direction's certified_max_iter)
DEFAULT_NODES = 101  # the paper's tables and the benchmarks' fixed grids (`nodes` is required for one)
ACCURACY_START_NODES = 21  # `nodes` when not given under `accuracy`: the first mesh, refined from there
ACCURACY_SCHEME = "radau-iia"  # the scheme of an accuracy request that names none: order 3
BOOTSTRAP_SCHEME = "implicit-euler"  # an accuracy request's first solves: finds the switches robustly
DEFAULT_RESIDUAL_TOL = 1e-8  # the pointwise checks' tolerance (qdframe.descent.checks) …
RESIDUAL_SHARE = 1e-2  # … and, refining to a target, at most this share of it: the estimate adds the residuals'
# own defects (boundary error, T·inclusion residual: certificates.estimates.defects) and a cost's Σ|y|·tol, which
# checks at 1e-8 leave above a target of 1e-8 (least-effort-bounded to accuracy=1e-8: uncertified, cost estimate 3.4e-7)
ESTIMATE_DIRECTION, ESTIMATE_LINE_SEARCH = "gauss-newton", "armijo"  # a bisection estimate's solve, whatever the user's


@dataclass(frozen=True)
class Plan:
    """A solve's decisions (the module's table), made by :func:`plan` from its arguments.

    `nodes` and `mesh` are the first grid while refining, the grid when fixed; `from_motion`:
    the first mesh comes from the model's simulated motion where it has one (refining with
    neither given). `first_scheme` runs the first solves, `scheme` the result's. `continuation`
    is the coarser grids' rule as given (None: the direction's own, or none where the model's
    motion starts the requested grid)."""

    refining: bool
    target: float
    nodes: int
    mesh: tuple[float, ...] | None
    from_motion: bool
    scheme: str | Scheme
    first_scheme: str | Scheme
    options: DescentOptions
    direction: DirectionSolver
    line_search: LineSearch
    continuation: Sequence[int] | str | None
    estimate: bool
    certificate: str | None
    max_nodes: int
    signs: str
    selection_scale: float
    inputs: str
    simulate_start: bool
    estimate_direction: DirectionSolver  # the bisection estimate's solve on the bisected grid (gauss-newton)
    estimate_line_search: LineSearch

    @property
    def budget(self) -> int:
        """The iterations of the whole solve (every grid, every second chance)."""
        return self.options.max_iter

    def describe(self) -> str:
        """The plan in a few words: `on N nodes`, or `from N points to accuracy A`."""
        if not self.refining:
            return f"on {self.nodes} nodes"
        return f"from {self.nodes} points to accuracy {self.target:g}"


def plan(model: InclusionModel, nodes: int | None = None, direction: str | DirectionSolver = "gauss-newton",
         line_search: str | LineSearch | None = None, *, max_iter: int | None = None, tol: float | None = None,
         delta: float = 1e-3, eps: float = 1e-2, gamma_max: float = 1.0, residual_tol: float | None = None,
         eps_floor: float | None = None, continuation: Sequence[int] | str | None = None,
         scheme: str | Scheme | None = None, signs: str = "exact", selection_scale: float = 1.0,
         inputs: str = "held", mesh: Sequence[float] | np.ndarray | None = None, estimate: bool = True,
         accuracy: float | None = None, max_nodes: int = 100_001, certificate: str | None = None,
         simulate_start: bool = True) -> Plan:
    """The :class:`Plan` of ``qdframe.solve(model, …)`` with these arguments (the same names
    and defaults), checked: an argument out of its range raises InputError naming it."""
    if accuracy is not None and not (isinstance(accuracy, (int, float)) and np.isfinite(accuracy) and accuracy > 0):
        raise InputError("accuracy", "a positive finite number (the target of the error estimate)", accuracy)
    if isinstance(max_nodes, bool) or not isinstance(max_nodes, (int, np.integer)) or max_nodes < 3:
        raise InputError("max_nodes", "an integer ≥ 3", max_nodes)
    if certificate not in (None, *CERTIFICATES):
        raise InputError("certificate", " or ".join(f'"{name}"' for name in CERTIFICATES) + " (None: by the problem)",
                         certificate)
    if not isinstance(estimate, (bool, np.bool_)):
        raise InputError("estimate", "True or False", estimate)
    if continuation is not None and not isinstance(continuation, (str, Sequence, np.ndarray)):
        raise InputError("continuation", '"auto", "none" or increasing node counts', continuation)
    refining = accuracy is not None or (nodes is None and mesh is None)  # else a fixed grid
    if refining and not estimate:
        raise InputError("estimate", "True when the mesh is refined to an accuracy (estimate=False needs nodes= or "
                         "mesh= without accuracy=)", estimate)
    requested = (ACCURACY_SCHEME if refining else model.default_scheme) if scheme is None else scheme
    if refining and nodes is None and mesh is None:  # the refinement starts on a mesh it cannot go below
        first = Grid.from_mesh(np.linspace(0.0, model.T, ACCURACY_START_NODES), requested).nodes
        if isinstance(max_nodes, (int, np.integer)) and not isinstance(max_nodes, bool) and max_nodes < first:
            raise InputError("max_nodes", f"an integer ≥ {first} when the mesh is refined (its first mesh, "
                                          f"{ACCURACY_START_NODES - 1} intervals of {getattr(requested, 'name', requested)}, "
                                          f"has {first} points), or nodes= for a fixed grid", max_nodes)
    solver = make_direction(direction)
    cost = model.cost()
    needs = [what for what, present in (("state_bounds or control_bounds", getattr(model, "bounds_table", None)),
                                        ("a terminal cost", cost is not None and cost.terminal is not None)) if present]
    if needs and not solver.full_steps:
        raise InputError("direction", f"a Newton-type direction (gauss-newton) for a model with {needs[0]}: the "
                         "paper's min-norm direction does not model them", direction)
    if max_iter is None:  # a certified solve: the direction's budget (a first-order method needs more)
        max_iter = solver.certified_max_iter if refining else DEFAULT_MAX_ITER
    target = DEFAULT_ACCURACY if accuracy is None else float(accuracy)
    if residual_tol is None:  # the checks well inside the target (the module's table)
        residual_tol = min(DEFAULT_RESIDUAL_TOL, RESIDUAL_SHARE * target) if refining else DEFAULT_RESIDUAL_TOL
    if eps_floor is None:  # a fixed grid keeps the paper's ε and δ
        eps_floor = EPS_FLOOR if refining else eps
    options = DescentOptions(
        max_iter=max_iter, tol=model.default_tol if tol is None else tol, delta=delta, eps=eps, gamma_max=gamma_max,
        residual_tol=residual_tol, eps_floor=eps_floor,
    )
    search = make_line_search(solver.default_line_search if line_search is None else line_search)
    return Plan(
        refining=refining, target=target,
        nodes=(ACCURACY_START_NODES if refining else DEFAULT_NODES) if nodes is None else nodes,
        mesh=None if mesh is None else tuple(mesh_times(mesh, model.T)),
        from_motion=refining and mesh is None and nodes is None, scheme=requested,
        first_scheme=BOOTSTRAP_SCHEME if refining else requested, options=options, direction=solver,
        line_search=search, continuation=continuation, estimate=estimate, certificate=certificate,
        max_nodes=max_nodes, signs=signs, selection_scale=selection_scale, inputs=inputs,
        simulate_start=simulate_start, estimate_direction=make_direction(ESTIMATE_DIRECTION),
        estimate_line_search=make_line_search(ESTIMATE_LINE_SEARCH),
    )


def mesh_times(mesh: Sequence[float] | np.ndarray, T: float) -> np.ndarray:
    """The user's mesh as an array checked against the model's horizon: finite, increasing,
    from 0 to T (the last time within rounding of T, then made T); an InputError names the
    first time that is not (``mesh[i]``)."""
    expected = f"a list of at least two increasing mesh times from 0 to T = {T:g}"
    try:
        tau = np.asarray(mesh, dtype=float)
    except (TypeError, ValueError):
        shown = repr(mesh)  # the mesh itself where its repr is one short line
        got = mesh if len(shown) <= 60 and "\n" not in shown else " ".join(shown.split())[:57] + "..."
        raise InputError("mesh", expected, got) from None
    if tau.ndim != 1 or tau.size < 2:
        raise InputError("mesh", expected, f"shape {tau.shape}")
    tau = tau.copy()
    if np.isfinite(tau[-1]) and np.isclose(tau[-1], T, rtol=1e-14, atol=0.0):
        tau[-1] = T
    check_mesh(tau, float(T))
    return tau
