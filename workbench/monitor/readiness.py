"""When a block's data can no longer change: the monitor's rule for deciding a block."""

from __future__ import annotations

import numpy as np

__all__ = ["settled"]

_NS = 1_000_000_000


def settled(
    low: int,
    high: int,
    starts: np.ndarray,
    ends: np.ndarray,
    *,
    newest: int,
    first_ns: int,
    sampling_rate_hz: float,
    late_s: float,
) -> bool:
    """No data can still arrive for [*low*, *high*) ns: the span is covered by files, or
    every uncovered stretch of it lies *late_s* or more before the newest data.

    Parameters
    ----------
    low, high : int
        The span, in ns since the epoch.
    starts, ends : ndarray of int64
        Start and end [ns] of every file taken, in time order.
    newest : int
        End of the newest data [ns].
    first_ns : int
        Start of the first block: nothing comes before it. [ns]
    sampling_rate_hz : float
        Half a sample is the tolerance of "contiguous". [Hz]
    late_s : float
        How long (in data time) missing data is waited for. [s]
    """
    half = int(0.5 / sampling_rate_hz * _NS)
    late = int(late_s * _NS)
    low = max(low, first_ns)
    cursor = low
    first = max(0, int(np.searchsorted(ends, low, side="left")) - 1)
    for start, end in zip(starts[first:], ends[first:], strict=True):
        if end <= cursor + half:
            continue
        if start > high - half:
            break
        if start > cursor + half and newest < start + late:  # a hole [cursor, start)
            return False
        cursor = max(cursor, end)
    return not (cursor < high - half and newest < high + late)
