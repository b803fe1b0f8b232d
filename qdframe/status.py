"""How a solve ended: the statuses a result carries, what each promises, and the exit code
`qdframe solve` returns for it.

``Status`` is a ``str`` enum, so a status compares equal to its name ("solved" ==
Status.SOLVED) and is written as that name in JSON.

===============  =====  ==================================================================
status           exit   meaning
===============  =====  ==================================================================
solved           0      certified: x itself meets the boundary values, the inclusion and
                        the surface pointwise (:mod:`qdframe.descent.checks`) and its error
                        estimate is within the target (``accuracy``, default 1e-6 times
                        max(1, max|x|))
uncertified      3      the discrete problem is solved pointwise, but the error is not
                        certified within the target (the estimate exceeds it, or none
                        could be made): more nodes, or ``accuracy=``
stationary       4      the descent stopped at an iterate whose residuals are not all
                        within tolerance (no step decreases the objective, or ε-stationary)
max_iter         5      the iteration budget was spent
failed           6      a backend reported an error mid-run (the message says which)
===============  =====  ==================================================================

Exit status 1 is an error that stopped the run without a result (a model that returns
NaN, an internal error), 2 bad input.
"""

from __future__ import annotations

from enum import Enum


class Status(str, Enum):
    """How a solve ended (this module's table)."""

    SOLVED = "solved"
    UNCERTIFIED = "uncertified"
    STATIONARY = "stationary"
    MAX_ITER = "max_iter"
    FAILED = "failed"

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)


STATUSES: tuple[str, ...] = tuple(status.value for status in Status)

EXIT_CODES: dict[Status, int] = {
    Status.SOLVED: 0,
    Status.UNCERTIFIED: 3,
    Status.STATIONARY: 4,
    Status.MAX_ITER: 5,
    Status.FAILED: 6,
}
# a benchmark row's status beside these (`qdframe bench run`): its run passed the time limit
TIME_LIMIT = "time_limit"

EXIT_ERROR = 1  # an error stopped the run before it had a result
EXIT_USAGE = 2  # bad input (the field and the expected form named), or a plugin's own code raised (the plugin named)
