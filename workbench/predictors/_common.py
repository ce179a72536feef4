"""Shared helpers of the predictors package."""

from __future__ import annotations

import numpy as np
import pandas as pd

from data_contracts import CANONICAL_PREDICTORS

CANONICAL_NAMES: tuple[str, ...] = tuple(c.name for c in CANONICAL_PREDICTORS)
BLOCK_COLUMNS = ("block", "block_start", "block_end")


class PredictorWarning(UserWarning):
    """Something was done to the ship log that the user should know (despiking, faulty
    stretches, constant columns, missing columns)."""


def time_ns(log: pd.DataFrame) -> np.ndarray:
    """The ``time`` column as int64 nanoseconds since the epoch (UTC)."""
    if "time" not in log.columns:
        raise ValueError("log has no 'time' column (read it with data_contracts.read_dship)")
    times = pd.DatetimeIndex(pd.to_datetime(log["time"], utc=True))
    if times.hasnans:
        raise ValueError("log column 'time' has missing values")
    return times.as_unit("ns").asi8


def numeric_columns(log: pd.DataFrame) -> list[str]:
    """Numeric columns of *log* other than time and block columns, in order."""
    return [
        c
        for c in log.columns
        if c != "time"
        and c not in BLOCK_COLUMNS
        and pd.api.types.is_numeric_dtype(log[c])
        and not pd.api.types.is_bool_dtype(log[c])
    ]


def check_numeric_columns(log: pd.DataFrame, columns) -> list[str]:
    """*columns* as a list, checked to be numeric columns of *log*.

    Raises
    ------
    ValueError
        Naming the columns that are not in the log, or not numeric.
    """
    columns = list(columns)
    missing = [c for c in columns if c not in log.columns]
    if missing:
        raise ValueError(f"columns {', '.join(missing)} are not in the log")
    numeric = set(numeric_columns(log))
    not_numeric = [c for c in columns if c not in numeric]
    if not_numeric:
        raise ValueError(f"columns {', '.join(not_numeric)} are not numeric")
    return columns
