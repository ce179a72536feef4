"""The state folder's format version: an older folder is migrated, a newer one refused.

``<state>/state_format.json`` holds ``{"schema": STATE_FORMAT}``. Format 2 (this one)
stores the tables that grow with the voyage (``tracked``, ``forecast``, ``health``,
``data_health``) as parted tables, one Parquet file per day of blocks
(:mod:`data_contracts.parts`); format 1 (folders without the file) wrote each as one
file, rewritten whole at every block.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from data_contracts import atomic_path

from ..errors import WorkbenchError

__all__ = ["FORMAT_FILE", "GROWING_TABLES", "STATE_FORMAT", "check_state_format"]

#: ``schema`` of ``state_format.json``: the state folder's format version.
STATE_FORMAT = "workbench.monitor.state/2"
#: The file naming the format.
FORMAT_FILE = "state_format.json"
#: The tables written a day of blocks per part (format 2).
GROWING_TABLES = ("tracked.parquet", "forecast.parquet", "health.parquet", "data_health.parquet")


def check_state_format(state: Path) -> str | None:
    """Check (and write) the format of the state folder *state*; migrate a format-1
    folder. Returns the one-line note of a migration or of the format file written
    again (None otherwise).

    Format 1 to 2: the tracked and data-health tables are rebuilt from the store at the
    restart (as always); the forecast and health tables and the saved outlook are removed,
    so the forecast and the health chart are computed again from the first block once.

    Raises
    ------
    WorkbenchError
        The folder is of another (newer) format, or its format file is unreadable and
        its tables do not show the format (one line naming the file). An unreadable
        format file of a folder whose tables are of this format is written again (the
        note says so).
    """
    state = Path(state)
    path = state / FORMAT_FILE
    note = None
    if path.is_file():
        try:
            found = json.loads(path.read_text(encoding="utf-8"))
            schema = found.get("schema") if isinstance(found, dict) else None
        except (OSError, ValueError) as error:
            return _rewrite(state, path, str(error).splitlines()[0])
        if schema == STATE_FORMAT:
            return None
        raise WorkbenchError(
            f"{path}: state folder of format {schema!r}, this workbench writes "
            f"{STATE_FORMAT!r}: use the workbench that wrote it, or another --state"
        )
    old = [name for name in GROWING_TABLES if (state / name).is_file()]
    if old:
        for name in old:
            (state / name).unlink()
        shutil.rmtree(state / "outlook", ignore_errors=True)
        note = (
            f"{state}: state folder of format 1 (whole tables) migrated to {STATE_FORMAT} "
            "(tables written a day per part): tracked and data-health tables rebuilt from "
            "the store, forecast and health chart computed again from the first block"
        )
    _write(path)
    return note


def _write(path: Path) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps({"schema": STATE_FORMAT}), encoding="utf-8")


def _rewrite(state: Path, path: Path, why: str) -> str:
    """Write the unreadable format file *path* again when the folder's tables show this
    format: every growing table present is parted with an index of this workbench's
    parted-table format (a format-1 table is one file; a newer format's could be neither).
    Returns the note saying so.

    Raises
    ------
    WorkbenchError
        A table shows no such layout: one line naming the file and the table.
    """
    from data_contracts.parts import PARTS_SCHEMA, read_index

    for name in GROWING_TABLES:
        table = state / name
        if not table.exists():
            continue
        try:
            if not table.is_dir():
                raise ValueError(f"{table}: one file, not parted")
            read_index(table)
        except ValueError as error:
            raise WorkbenchError(
                f"{path}: unreadable ({why}), and the folder does not show its format "
                f"({str(error).splitlines()[0]}); use the workbench that wrote the folder, "
                "or another --state"
            ) from None
    _write(path)
    return (
        f"{path}: unreadable ({why}); written again: the folder's tables are of this "
        f"format ({STATE_FORMAT}, tables parted as {PARTS_SCHEMA})"
    )
