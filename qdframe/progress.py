"""Progress on stderr for long commands: a tqdm bar for benchmark sweeps, shown only on
a terminal, so that stdout keeps just the results (tables, or JSON with ``--json -``)."""

from __future__ import annotations

import sys
from typing import Any


def bar(total: int, description: str, enabled: bool = True) -> Any:
    """A tqdm progress bar over `total` items on stderr; disabled when `enabled` is False
    or stderr is not a terminal. Use ``bar.write(text)`` for lines that keep the bar intact."""
    from tqdm import tqdm

    return tqdm(total=total, desc=description, file=sys.stderr, unit="run", dynamic_ncols=True,
                disable=not enabled or not sys.stderr.isatty())
