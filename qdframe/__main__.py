"""`python -m qdframe …`: the `qdframe` command (:mod:`qdframe.cli`)."""

import sys

from .cli import main

sys.exit(main())
