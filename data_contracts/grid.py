"""The block grid recorded with every block-level table.

A block-level table (poles, selected modes, tracked modal table, predictors, forecasts,
health chart) numbers its rows by block ``k`` of a grid: block ``k`` covers
``[t0 + k * step, t0 + k * step + length)``. The grid is recorded with the table so that
later stages need not guess it back from the block starts (which cannot tell the step of a
table with a single block):

* in memory: ``frame.attrs["block_grid"]``, a dict ``{"t0": ISO-8601 UTC, "length_s":
  float, "step_s": float}`` (see :func:`grid_record`);
* in Parquet files: the same JSON under the key-value metadata key
  ``workbench.block_grid`` (readable by any Parquet tool);
* beside CSV files: a sidecar ``<file name>.grid.json`` holding the same JSON (the CSV
  itself stays a plain table any tool reads).

Blocks of varying length (``identify --block-minutes auto``) record ``"varying_length":
true``: block ``k`` is then centred at ``t0 + k * step + length / 2`` (the centres of the
fixed grid of *length*), and its own span is the table's ``block_start`` / ``block_end``.

:func:`~data_contracts.read_table` attaches a recorded grid to the frame it returns and
:func:`~data_contracts.write_table` writes the frame's grid (or the one it is given). A
recorded grid that contradicts the table's ``block``/``block_start``/``block_end`` columns
(a sidecar left beside a CSV another tool rewrote) is ignored with a warning. Tables
without a recorded grid (older files, other tools) read as before.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = [
    "GRID_ATTR",
    "GRID_METADATA_KEY",
    "grid_mismatch",
    "grid_record",
    "grid_sidecar",
    "read_grid",
    "recorded_grid",
    "set_grid",
]

#: Key of the grid in ``DataFrame.attrs``.
GRID_ATTR = "block_grid"
#: Key of the grid in a Parquet file's key-value metadata.
GRID_METADATA_KEY = b"workbench.block_grid"


def grid_record(grid: Any) -> dict[str, Any]:
    """The grid *grid* as a plain dict ``{"t0": str, "length_s": float, "step_s": float}``.

    Parameters
    ----------
    grid : mapping or object
        A mapping with keys ``t0``, ``length_s``, ``step_s``, or an object with those
        attributes (e.g. :class:`workbench.blocks.BlockGrid`). ``t0`` is a time (naive times
        are taken as UTC); lengths are in seconds.

    Raises
    ------
    ValueError
        When a field is missing or not valid (a positive length at least the step).
    """
    fields = ("t0", "length_s", "step_s")
    if isinstance(grid, Mapping):
        t0, length, step = (grid.get(name) for name in fields)
        varying = grid.get("varying_length", False)
    else:
        t0, length, step = (getattr(grid, name, None) for name in fields)
        varying = getattr(grid, "varying_length", False)
    if t0 is None or length is None or step is None:
        raise ValueError("a block grid needs t0, length_s and step_s")
    try:
        stamp = pd.Timestamp(t0)
        length, step = float(length), float(step)
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"block grid {dict(t0=t0, length_s=length, step_s=step)}: {error}"
        ) from None
    if pd.isna(stamp):
        raise ValueError("block grid: t0 is missing (NaT)")
    stamp = stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")
    if not (math.isfinite(length) and math.isfinite(step) and 0 < step <= length):
        raise ValueError(
            f"block grid: length_s={length:g} and step_s={step:g} must be positive with "
            "step_s <= length_s"
        )
    record = {"t0": stamp.isoformat(), "length_s": length, "step_s": step}
    if varying is True:
        record["varying_length"] = True
    elif varying is not False:
        raise ValueError(f"block grid: varying_length={varying!r} must be true or false")
    return record


def recorded_grid(frame: pd.DataFrame) -> dict[str, Any] | None:
    """The grid recorded with *frame* (``frame.attrs["block_grid"]``), or None."""
    grid = frame.attrs.get(GRID_ATTR)
    return None if grid is None else grid_record(grid)


def set_grid(frame: pd.DataFrame, grid: Any) -> pd.DataFrame:
    """Record *grid* with *frame* (in place; None removes it) and return *frame*."""
    if grid is None:
        frame.attrs.pop(GRID_ATTR, None)
    else:
        frame.attrs[GRID_ATTR] = grid_record(grid)
    return frame


def grid_sidecar(path: str | os.PathLike) -> Path:
    """The sidecar file holding the grid of the CSV table *path* (``<name>.grid.json``)."""
    path = Path(path)
    return path.with_name(path.name + ".grid.json")


def grid_mismatch(frame: pd.DataFrame, grid: Mapping[str, Any]) -> str | None:
    """Why *grid* cannot be the grid of *frame*'s blocks, or None when it fits.

    Checked where the columns exist: ``block_start == t0 + block * step`` and
    ``block_end - block_start == length`` (to a millisecond); for a grid of varying
    length, that each block's centre is ``t0 + block * step + length / 2``.
    """
    if "block" not in frame.columns or frame.empty:
        return None
    t0 = pd.Timestamp(grid["t0"])
    block = pd.to_numeric(frame["block"], errors="coerce").to_numpy(dtype=float)
    tolerance = 1e-3
    if grid.get("varying_length") and not {"block_start", "block_end"} <= set(frame.columns):
        return None  # a block's start alone does not tell where a block of its own length lies
    if grid.get("varying_length"):
        start = pd.to_datetime(frame["block_start"], utc=True, errors="coerce")
        end = pd.to_datetime(frame["block_end"], utc=True, errors="coerce")
        centre = ((start - t0).dt.total_seconds() + (end - t0).dt.total_seconds()) / 2
        expected = block * float(grid["step_s"]) + float(grid["length_s"]) / 2
        with np.errstate(invalid="ignore"):
            off = np.abs(centre.to_numpy(dtype=float) - expected) > tolerance
        if off.any():
            row = int(np.flatnonzero(off)[0])
            return (
                f"block {block[row]:.0f}: centre of {start.iat[row].isoformat()} .. "
                f"{end.iat[row].isoformat()} is not on the recorded grid of varying length "
                f"(t0 {grid['t0']}, centres every {grid['step_s']:g} s from "
                f"{float(grid['length_s']) / 2:g} s)"
            )
        return None
    for column, offset in (("block_start", 0.0), ("block_end", float(grid["length_s"]))):
        if column not in frame.columns:
            continue
        times = pd.to_datetime(frame[column], utc=True, errors="coerce")
        seconds = ((times - t0).dt.total_seconds()).to_numpy(dtype=float)
        expected = block * float(grid["step_s"]) + offset
        with np.errstate(invalid="ignore"):
            off = np.abs(seconds - expected) > tolerance
        if off.any():
            row = int(np.flatnonzero(off)[0])
            return (
                f"block {block[row]:.0f}: {column} {times.iat[row].isoformat()} is not on the "
                f"recorded grid (t0 {grid['t0']}, length {grid['length_s']:g} s, step "
                f"{grid['step_s']:g} s)"
            )
    return None


# --------------------------------------------------------------------------- file I/O
def _parse(text: str | bytes, source: Path) -> dict[str, Any] | None:
    try:
        return grid_record(json.loads(text))
    except (ValueError, TypeError, AttributeError) as error:
        warnings.warn(f"{source}: recorded block grid ignored ({error})", UserWarning, stacklevel=4)
        return None


def read_grid(path: Path, fmt: str) -> dict[str, Any] | None:
    """The grid recorded with the table file *path* (``fmt`` csv or parquet), or None."""
    if fmt == "parquet":
        import pyarrow.parquet as pq

        try:
            metadata = pq.read_schema(path).metadata or {}
        except (OSError, ValueError):
            return None
        text = metadata.get(GRID_METADATA_KEY)
        return None if text is None else _parse(text, path)
    sidecar = grid_sidecar(path)
    if not sidecar.is_file():
        return None
    try:
        text = sidecar.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        warnings.warn(
            f"{sidecar}: recorded block grid ignored ({error})", UserWarning, stacklevel=2
        )
        return None
    return _parse(text, sidecar)


def attach_grid(frame: pd.DataFrame, grid: dict[str, Any] | None, source: Path) -> pd.DataFrame:
    """Record *grid* (read from *source*) with *frame* unless it contradicts the blocks."""
    if grid is None:
        return frame
    reason = grid_mismatch(frame, grid)
    if reason is not None:
        warnings.warn(
            f"{source}: recorded block grid ignored ({reason})", UserWarning, stacklevel=3
        )
        return frame
    return set_grid(frame, grid)


def grid_json(grid: Mapping[str, Any]) -> str:
    """The grid as the JSON text stored in files."""
    return json.dumps(grid_record(grid), sort_keys=True)
