"""The monitor's data-health table: per block, channels kept and dropped, gaps, latency."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import atomic_path

__all__ = ["DATA_HEALTH_COLUMNS", "data_health_frame", "data_health_row", "write_data_health"]

_NS = 1_000_000_000

#: Columns of ``data_health.parquet`` (the agreed interface first, then status and reason).
DATA_HEALTH_COLUMNS = (
    "block",
    "block_start",
    "n_channels",
    "dropped_channels",
    "gap_seconds",
    "last_file_landed",
    "identified_at",
    "latency_s",
    "status",
    "reason",
)


def data_health_row(planned, outcome, identified_at: pd.Timestamp, files: Sequence) -> dict:
    """The data-health row of one decided block.

    Parameters
    ----------
    planned : PlannedBlock
        The block as planned (its span and files).
    outcome : BlockOutcome
        What identification gave (tables, skip reason).
    identified_at : Timestamp
        When identification finished (UTC).
    files : sequence of LandedFile
        The block's files as taken (with their landing times; others are ignored).
    """
    by_path = {f.path: f for f in files}
    used = [by_path[Path(p)] for p in planned.files if Path(p) in by_path]
    landed = max((f.landed for f in used), default=pd.NaT)
    start, end = planned.block_start.value, planned.block_end.value
    covered = sum(
        max(0, min(end, f.info.end_time.value) - max(start, f.info.start_time.value)) for f in used
    )
    faults = outcome.tables.get("faults")
    dropped = [] if faults is None or faults.empty else [str(c) for c in faults["channel"]]
    channels = outcome.tables.get("channels")
    n_channels = 0 if channels is None or outcome.skipped else int(len(channels))
    gap = max(0.0, (end - start - covered) / _NS)
    return {
        "block": int(outcome.block),
        "block_start": pd.Timestamp(outcome.block_start).tz_convert("UTC"),
        "n_channels": n_channels,
        "dropped_channels": ",".join(dropped),
        "gap_seconds": round(gap, 6),
        "last_file_landed": landed,
        "identified_at": identified_at,
        "latency_s": (identified_at - landed).total_seconds() if landed is not pd.NaT else np.nan,
        "status": "skipped" if outcome.skipped else "ok",
        "reason": outcome.skipped,
    }


def write_data_health(rows: Sequence[dict], path: Path) -> None:
    """Write the rows, sorted by block, to *path* (Parquet, atomically)."""
    with atomic_path(path) as tmp:
        data_health_frame(rows).to_parquet(tmp, index=False)


def data_health_frame(rows: Sequence[dict]) -> pd.DataFrame:
    """The data-health table of *rows*, sorted by block, with its column types."""
    frame = pd.DataFrame(list(rows), columns=list(DATA_HEALTH_COLUMNS))
    frame = frame.sort_values("block", kind="stable").reset_index(drop=True)
    frame["block"] = frame["block"].astype("int64")
    frame["n_channels"] = frame["n_channels"].astype("int64")
    for column in ("block_start", "last_file_landed", "identified_at"):
        frame[column] = pd.to_datetime(frame[column], utc=True)
    for column in ("gap_seconds", "latency_s"):
        frame[column] = frame[column].astype(float)
    for column in ("dropped_channels", "status", "reason"):
        frame[column] = frame[column].fillna("").astype(str)
    return frame
