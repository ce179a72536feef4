"""The ``workbench`` command's entry point: Ctrl-C while the command line starts is the
same one line as Ctrl-C while it runs.

Importing the command line (:mod:`workbench.cli`) takes numpy, pandas, scipy and the
stages: a second or more on a loaded machine. An interrupt in that time would otherwise
print a ``KeyboardInterrupt`` traceback from deep inside an import; this module imports
nothing heavy itself, so it can catch it.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from .errors import EXIT_INTERRUPTED


def main(argv: Sequence[str] | None = None) -> int:
    """Import the command line and run it; ``interrupted`` and exit 130 on Ctrl-C.

    For ``identify``, the input files named first on the command line are hashed for the
    store's fingerprints while the command line imports (:mod:`workbench.fingerprints`).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv[:1] == ["identify"]:
            from .fingerprints import prefetch

            prefetch(argv[1:])
        from .cli import main as run
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return run(argv)
