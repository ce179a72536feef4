"""Progress bars that show where the user looks: a terminal, a notebook, or nowhere.

:func:`progress_bar` is the one place the library makes a bar (blocks identified, tracked,
modes forecast). In a Jupyter kernel it is the notebook widget when ``ipywidgets`` is
installed, else a text bar written to the cell's stderr (no "IProgress not found" warning:
tqdm's automatic choice asks for the widget and warns without it). In a terminal that
reports no size (some IDE consoles, ``docker exec`` without one), tqdm would draw nothing
(a bar 0 columns wide on a screen of 0 rows): the size is then ``COLUMNS`` x ``LINES`` or
100 x 24.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import sys
from collections.abc import Iterable

__all__ = ["in_notebook", "progress_bar"]

#: Width of a text bar where the output reports none (a notebook's stderr, a 0-column pty).
FALLBACK_COLUMNS = 100
#: Height where the terminal reports none (tqdm hides bars below the screen's last row).
FALLBACK_ROWS = 24


def in_notebook() -> bool:
    """Whether the code runs in a Jupyter kernel (a notebook or a Jupyter console)."""
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None
    return shell is not None and type(shell).__name__ == "ZMQInteractiveShell"


def _stderr_columns() -> int:
    """Columns of the terminal behind stderr (0: not a terminal, or one without a size)."""
    try:
        return os.get_terminal_size(sys.stderr.fileno()).columns
    except (AttributeError, OSError, ValueError):  # replaced, closed or not a terminal
        return 0


def progress_bar(
    iterable: Iterable | None = None,
    *,
    total: float | None = None,
    description: str = "",
    unit: str = "block",
    enabled: bool = True,
    smoothing: float = 0.3,
):
    """A tqdm bar on stderr (see the module's notes), or a silent one when not *enabled*.

    Parameters
    ----------
    iterable : iterable, optional
        Wrapped as tqdm wraps it; else update the bar by hand (``bar.update(n)``).
    total : float, optional
        Steps to completion (default ``len(iterable)`` when it has one).
    description, unit : str
        Shown before and after the count.
    enabled : bool
        False: a bar that draws nothing (same interface).
    smoothing : float
        Weight of the latest rate in the ETA (tqdm's exponential moving average).
    """
    options = {
        "total": total,
        "desc": description,
        "unit": unit,
        "disable": not enabled,
        "smoothing": smoothing,
    }
    notebook = enabled and in_notebook()
    if notebook and importlib.util.find_spec("ipywidgets") is not None:
        from tqdm.notebook import tqdm as notebook_bar

        return notebook_bar(iterable, **options)
    from tqdm.std import tqdm as text_bar

    options["file"] = sys.stderr
    if notebook:  # the cell's stderr has no size
        options["ncols"] = FALLBACK_COLUMNS
    elif _stderr_columns() > 0:
        options["dynamic_ncols"] = True  # follows the window's width
    else:  # tqdm hides a bar on a screen of 0 columns or 0 rows
        size = shutil.get_terminal_size((FALLBACK_COLUMNS, FALLBACK_ROWS))
        options["ncols"], options["nrows"] = size.columns, size.lines
    return text_bar(iterable, **options)
