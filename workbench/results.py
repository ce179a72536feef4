"""What every stage result has: a table, a summary, an HTML view, atomic saving (tables,
JSON, figures)."""

from __future__ import annotations

import html
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from data_contracts import atomic_path, read_table, write_table

__all__ = [
    "StageResult",
    "Summary",
    "read_any_table",
    "save_figure",
    "shown_once",
    "table_path",
    "write_frame",
    "write_json",
]

#: Suffixes of the table files a stage writes or reads.
TABLE_SUFFIXES = (".csv", ".parquet", ".pq")


class Summary:
    """What a result found, as statsmodels' ``Summary``: text lines and tables, shown as
    text by ``print`` / ``str`` and as HTML in a notebook.

    Parameters
    ----------
    title : str
    lines : sequence of str
        Sentences a person reads (warnings start with ``warning:``).
    tables : sequence of (caption, DataFrame)
        Tables shown below the lines.
    """

    def __init__(self, title: str, lines=(), tables=()):
        self.title = str(title)
        self.lines = [str(line) for line in lines]
        self.tables = [(str(caption), table) for caption, table in tables]

    def as_text(self) -> str:
        parts = ["\n".join(self.lines)] if self.lines else []
        for caption, table in self.tables:
            text = table.to_string() if isinstance(table, pd.DataFrame) else str(table)
            parts.append(f"{caption}\n{text}" if caption else text)
        return "\n".join(parts)

    def as_html(self) -> str:
        body = [f"<strong>{html.escape(self.title)}</strong>"] if self.title else []
        if self.lines:
            body.append("<pre>" + html.escape("\n".join(self.lines)) + "</pre>")
        for caption, table in self.tables:
            if caption:
                body.append(f"<p>{html.escape(caption)}</p>")
            if isinstance(table, pd.DataFrame):
                named = any(name is not None for name in table.index.names)
                body.append(table.to_html(index=named, border=0, max_rows=60, max_cols=14))
            else:
                body.append("<pre>" + html.escape(str(table)) + "</pre>")
        return "<div>" + "".join(body) + "</div>"

    def __str__(self) -> str:
        return self.as_text()

    def __repr__(self) -> str:  # the text view where no HTML is shown (a terminal)
        return self.as_text()

    def _repr_html_(self) -> str:
        return self.as_html()

    def __contains__(self, text: str) -> bool:
        return text in self.as_text()


def shown_once(figure):
    """*figure*, taken out of pyplot's list of open figures when a notebook's inline
    backend draws them: the notebook then shows the returned figure once (not also as
    a figure left open at the end of the cell). In scripts and GUI sessions the figure
    stays with pyplot, so ``plt.show()`` shows it."""
    import sys

    pyplot = sys.modules.get("matplotlib.pyplot")
    if pyplot is None or figure is None:
        return figure
    import matplotlib

    if "inline" in matplotlib.get_backend().lower():
        pyplot.close(figure)
    return figure


class StageResult:
    """Base of the stage results: ``table``, ``summary()``, ``_repr_html_``, ``save()``.

    Subclasses are dataclasses with a ``table`` field (a DataFrame following its contract)
    and ``lines`` / ``warnings`` lists; they implement :meth:`save`.
    """

    table: pd.DataFrame
    lines: list[str]
    warnings: list[str]

    #: Title of the notebook view.
    title = "result"

    def summary(self) -> Summary:
        """What the stage found, in a few lines a person reads (``print`` it; a notebook
        shows it as HTML)."""
        return Summary(self.title, [*self.lines, *(f"warning: {w}" for w in self.warnings)])

    def __str__(self) -> str:
        return str(self.summary())

    def _repr_html_(self) -> str:
        rows = len(self.table)
        named = any(name is not None for name in self.table.index.names)  # e.g. mode
        head = self.table.head(10).to_html(index=named, border=0, max_cols=12)
        more = f"<p>{rows} rows; first 10 shown.</p>" if rows > 10 else ""
        return (
            f"<div><strong>{html.escape(self.title)}</strong>"
            f"<pre>{html.escape(str(self.summary()))}</pre>{head}{more}</div>"
        )

    def save(self, out_dir: str | os.PathLike) -> dict[str, Path]:  # pragma: no cover
        raise NotImplementedError


def table_path(out: str | os.PathLike, default_name: str) -> Path:
    """*out* when it names a table file (.csv/.parquet), else *out* / *default_name*."""
    out = Path(out)
    return out if out.suffix.lower() in TABLE_SUFFIXES else out / default_name


def write_frame(frame: pd.DataFrame, path: str | os.PathLike, contract=None, **csv) -> Path:
    """Write *frame* atomically (CSV or Parquet from the suffix), validated against
    *contract* when one is given; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if contract is not None:
        return write_table(frame, path, contract)
    with atomic_path(path) as tmp:
        if path.suffix.lower() in (".parquet", ".pq"):
            frame.to_parquet(tmp, index=False)
        else:
            frame.to_csv(tmp, index=csv.pop("index", False), **csv)
    return path


def save_figure(fig, path: str | os.PathLike, *, dpi: int = 110) -> Path:
    """Write *fig* as PNG to *path* atomically (folders created) and close it: the one
    helper for every PNG a result, a report or a command writes.

    The figure is closed even when writing fails, so a long report run does not pile up
    open figures. Nothing in the library chooses a matplotlib backend: in a notebook
    figures go to the notebook's backend, and the command line selects the non-interactive
    Agg backend itself (:func:`workbench.cli.main`). Without a display, matplotlib falls
    back to Agg on its own.
    """
    import matplotlib.pyplot as plt  # only when a figure is written

    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return path


def write_json(data: Mapping[str, Any], path: str | os.PathLike) -> Path:
    """Write *data* as indented JSON, atomically (NumPy scalars and times as plain values)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2, default=_json_default), encoding="utf-8")
    return path


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, pd.Timestamp):
        return value.isoformat()
    return str(value)


def read_any_table(
    table: pd.DataFrame | str | os.PathLike, contract=None, *, name: str = "table"
) -> pd.DataFrame:
    """*table* itself, or the table in the file it names (CSV/Parquet, UTC block times).

    With *contract* the file is read and checked by :func:`~data_contracts.read_table`;
    without, times in ``block_start`` / ``block_end`` are parsed as UTC.
    """
    from .errors import WorkbenchError

    if isinstance(table, pd.DataFrame):
        return table
    if not isinstance(table, str | os.PathLike):
        raise TypeError(f"{name} must be a DataFrame or a path, got {type(table).__name__}")
    if contract is not None:
        return read_table(table, contract)
    path = Path(table)
    try:
        if path.suffix.lower() in (".parquet", ".pq"):
            frame = pd.read_parquet(path)
        else:
            frame = pd.read_csv(path)
    except FileNotFoundError:
        raise WorkbenchError(f"{path}: no such file") from None
    except (OSError, ValueError) as error:
        raise WorkbenchError(f"{path}: unreadable ({str(error).splitlines()[0]})") from None
    for column in ("block_start", "block_end"):
        if column in frame.columns:
            frame[column] = pd.to_datetime(frame[column], utc=True)
    return frame
