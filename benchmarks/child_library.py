"""Child processes of a benchmark import the library this process imported.

``python -m workbench.cli`` and ``python -c CODE`` put the current folder first on the
module path. A benchmark run from one checkout with ``PYTHONPATH`` naming another (the way
two trees are compared) would then score or time one library in itself and another in its
child processes, and print the mixture as one result. :func:`pin_library` puts the root of
the imported ``workbench`` first on ``PYTHONPATH`` and sets ``PYTHONSAFEPATH`` (Python
3.11: no current folder on the path), so every child, and every child of a child, imports
the same library. Benchmarks that run the command line call it once at import.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

import workbench

__all__ = ["pin_library"]


def pin_library(environ: MutableMapping[str, str] | None = None) -> Path:
    """Make child processes import this process's ``workbench``; returns its root folder.

    Parameters
    ----------
    environ : mutable mapping, optional
        The environment the children inherit (default :data:`os.environ`).
    """
    env = os.environ if environ is None else environ
    root = Path(workbench.__file__).resolve().parents[1]
    parts = [str(root), *(p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p)]
    env["PYTHONPATH"] = os.pathsep.join(dict.fromkeys(parts))
    env["PYTHONSAFEPATH"] = "1"
    return root
