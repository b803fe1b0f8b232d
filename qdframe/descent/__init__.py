"""One descent on one functional (paper Section 6): the loop and its options (:mod:`.loop`),
a step as the descent takes it (:mod:`.steps`), the result of its last iterate
(:mod:`.outcome`), the pointwise checks behind `solved` (:mod:`.checks`), and which
conditions an unsolved iterate leaves unmet (:mod:`.diagnosis`)."""

from .loop import DescentOptions, descend

__all__ = ["DescentOptions", "descend"]
