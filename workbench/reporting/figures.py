"""Writing figures: one helper for every PNG a report or a command writes.

Nothing here (nor anywhere in :mod:`workbench.reporting`) chooses a matplotlib backend:
in a notebook figures go to the notebook's backend, and the command line selects the
non-interactive Agg backend itself (:func:`workbench.cli.main`). Without a display,
matplotlib falls back to Agg on its own.
"""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib.pyplot as plt

from data_contracts import atomic_path

__all__ = ["save_figure"]


def save_figure(fig, path: str | os.PathLike, *, dpi: int = 110) -> Path:
    """Write *fig* as PNG to *path* atomically (folders created) and close it.

    The figure is closed even when writing fails, so a long report run does not pile up
    open figures.
    """
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return path
