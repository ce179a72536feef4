"""The block grid shared by every stage: which time span each block number covers.

Block ``k`` covers ``[t0 + k * step, t0 + k * step + length)``. ``t0`` is the first data
time floored to the step (counted from the Unix epoch), so two data sets that start in the
same step share a grid. The default is 20-minute blocks every 5 minutes (75 % overlap).
Block numbers are never negative.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = [
    "DEFAULT_BLOCK_LENGTH_S",
    "DEFAULT_BLOCK_STEP_S",
    "MAX_BLOCKS",
    "MAX_BLOCKS_PER_SAMPLE",
    "BlockGrid",
    "block_grid_of",
    "utc_timestamp",
]

#: Default block length. [s]
DEFAULT_BLOCK_LENGTH_S = 1200.0
#: Default step between block starts (75 % overlap with the default length). [s]
DEFAULT_BLOCK_STEP_S = 300.0

#: Most blocks one sample may lie in (block length over step): finer steps repeat the same
#: identification for hardly different data (the default is 4).
MAX_BLOCKS_PER_SAMPLE = 100
#: Most blocks one plan may list (ten years of the default 5-min step). [-]
MAX_BLOCKS = 1_000_000

_NS = 1_000_000_000


def utc_timestamp(time, *, name: str = "time") -> pd.Timestamp:
    """*time* as a tz-aware UTC :class:`pandas.Timestamp` (naive times are taken as UTC).

    Raises
    ------
    ValueError
        When *time* is not a valid time (message names *name*).
    """
    try:
        stamp = pd.Timestamp(time)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name}={time!r} is not a time") from error
    if pd.isna(stamp):
        raise ValueError(f"{name} is missing (NaT)")
    return stamp.tz_localize("UTC") if stamp.tzinfo is None else stamp.tz_convert("UTC")


def _seconds(value, name: str) -> float:
    try:
        seconds = float(value)
    except (TypeError, ValueError) as error:
        raise TypeError(f"{name}={value!r} must be a number of seconds") from error
    if not math.isfinite(seconds) or seconds <= 0:
        raise ValueError(f"{name}={value!r} must be a positive number of seconds")
    return seconds


@dataclass(frozen=True)
class BlockGrid:
    """A grid of overlapping blocks anchored at *t0*.

    Parameters
    ----------
    t0 : pandas.Timestamp
        Start of block 0. Naive times are taken as UTC; stored tz-aware in UTC. [UTC]
    length_s : float
        Block length. [s]
    step_s : float
        Time between consecutive block starts; at most *length_s*. [s]

    Notes
    -----
    Block :math:`k` covers :math:`[t_0 + k\\,s,\\; t_0 + k\\,s + L)` with step :math:`s`
    and length :math:`L`. The overlap of consecutive blocks is :math:`1 - s/L`
    (75 % for the default 1200 s / 300 s). The length need not be a multiple of the step.

    Examples
    --------
    >>> grid = BlockGrid.from_first_time("2024-03-01T00:02:10Z")
    >>> grid.t0, grid.start(2), grid.end(2)  # doctest: +NORMALIZE_WHITESPACE
    (Timestamp('2024-03-01 00:00:00+0000', tz='UTC'),
     Timestamp('2024-03-01 00:10:00+0000', tz='UTC'),
     Timestamp('2024-03-01 00:30:00+0000', tz='UTC'))
    """

    t0: pd.Timestamp
    length_s: float = DEFAULT_BLOCK_LENGTH_S
    step_s: float = DEFAULT_BLOCK_STEP_S

    def __post_init__(self) -> None:
        object.__setattr__(self, "t0", utc_timestamp(self.t0, name="t0").as_unit("ns"))
        length = _seconds(self.length_s, "length_s")
        step = _seconds(self.step_s, "step_s")
        if length < step:
            raise ValueError(
                f"length_s={length:g} must be at least step_s={step:g} (blocks would leave gaps)"
            )
        if (
            abs(length * _NS - round(length * _NS)) > 1e-3
            or abs(step * _NS - round(step * _NS)) > 1e-3
        ):
            raise ValueError("length_s and step_s must be whole nanoseconds")
        object.__setattr__(self, "length_s", length)
        object.__setattr__(self, "step_s", step)

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def from_first_time(
        cls,
        time,
        length_s: float = DEFAULT_BLOCK_LENGTH_S,
        step_s: float = DEFAULT_BLOCK_STEP_S,
    ) -> BlockGrid:
        """The grid whose ``t0`` is *time* floored to a multiple of *step_s* (Unix epoch).

        Parameters
        ----------
        time : time-like
            First data time (naive times are taken as UTC). [UTC]
        length_s, step_s : float
            Block length and step. [s]
        """
        stamp = utc_timestamp(time, name="time").as_unit("ns")
        step_ns = int(round(_seconds(step_s, "step_s") * _NS))
        t0_ns = stamp.value - stamp.value % step_ns
        return cls(pd.Timestamp(t0_ns, tz="UTC"), length_s, step_s)

    # -- geometry -------------------------------------------------------------------------
    @property
    def _length_ns(self) -> int:
        return int(round(self.length_s * _NS))

    @property
    def _step_ns(self) -> int:
        return int(round(self.step_s * _NS))

    def start(self, block):
        """Start of block(s) *block* (inclusive): a Timestamp, or a DatetimeIndex for arrays."""
        k = self._numbers(block)
        ns = self.t0.value + k * self._step_ns
        if np.ndim(block) == 0:
            return pd.Timestamp(int(ns), tz="UTC")
        return pd.DatetimeIndex(ns.astype("datetime64[ns]")).tz_localize("UTC")

    def end(self, block):
        """End of block(s) *block* (exclusive): a Timestamp, or a DatetimeIndex for arrays."""
        k = self._numbers(block)
        ns = self.t0.value + k * self._step_ns + self._length_ns
        if np.ndim(block) == 0:
            return pd.Timestamp(int(ns), tz="UTC")
        return pd.DatetimeIndex(ns.astype("datetime64[ns]")).tz_localize("UTC")

    def blocks_covering(self, t_start, t_end) -> np.ndarray:
        """Numbers of the blocks that overlap ``[t_start, t_end)``, at least in part.

        Returns
        -------
        ndarray of int64
            Ascending; empty when the span ends before block 0 starts or is empty.
        """
        start_ns, end_ns = self._span(t_start, t_end)
        if end_ns <= start_ns:
            return np.empty(0, dtype=np.int64)
        # block k overlaps when start_k < t_end and end_k > t_start
        first = max((start_ns - self.t0.value - self._length_ns) // self._step_ns + 1, 0)
        # largest k with t0 + k*step < end
        last = (end_ns - 1 - self.t0.value) // self._step_ns
        if last < first:
            return np.empty(0, dtype=np.int64)
        return np.arange(first, last + 1, dtype=np.int64)

    def complete_blocks(self, t_first, t_last) -> np.ndarray:
        """Numbers of the blocks lying entirely inside the data span ``[t_first, t_last)``.

        Parameters
        ----------
        t_first : time-like
            First data time (inclusive). [UTC]
        t_last : time-like
            End of the data (exclusive): for sampled data, the time just after the last
            sample (last sample time + sampling interval). [UTC]

        Returns
        -------
        ndarray of int64
            Ascending block numbers k >= 0 with ``start(k) >= t_first`` and
            ``end(k) <= t_last``.
        """
        start_ns, end_ns = self._span(t_first, t_last)
        first = max(-((self.t0.value - start_ns) // self._step_ns), 0)  # ceil, >= 0
        last = (end_ns - self._length_ns - self.t0.value) // self._step_ns
        if last < first:
            return np.empty(0, dtype=np.int64)
        return np.arange(first, last + 1, dtype=np.int64)

    def frame(self, blocks: Iterable[int] | np.ndarray) -> pd.DataFrame:
        """A table of *blocks*: columns ``block`` (int64), ``block_start``, ``block_end`` (UTC)."""
        k = self._numbers(np.atleast_1d(np.asarray(list(blocks))))
        return pd.DataFrame(
            {
                "block": k.astype(np.int64),
                "block_start": self.start(k),
                "block_end": self.end(k),
            }
        )

    # -- helpers --------------------------------------------------------------------------
    def _span(self, t_start, t_end) -> tuple[int, int]:
        start = utc_timestamp(t_start, name="t_start").as_unit("ns")
        end = utc_timestamp(t_end, name="t_end").as_unit("ns")
        return start.value, end.value

    @staticmethod
    def _numbers(block) -> np.ndarray:
        k = np.asarray(block)
        if k.dtype.kind == "f":
            if not np.all(np.isfinite(k)) or np.any(k != np.round(k)):
                raise ValueError(f"block numbers must be whole numbers, got {block!r}")
            k = k.astype(np.int64)
        elif k.dtype.kind not in "iu":
            if k.size == 0:
                return np.empty(0, dtype=np.int64)
            raise TypeError(f"block numbers must be integers, got {block!r}")
        k = k.astype(np.int64)
        if np.any(k < 0):
            raise ValueError(f"block numbers must be >= 0, got {int(k.min())}")
        return k


def block_grid_of(table: pd.DataFrame) -> tuple[pd.Timestamp, float, float]:
    """Block grid ``(t0, length_s, step_s)`` of a table with block, block_start, block_end.

    The grid recorded with the table (``table.attrs["block_grid"]``, read from the file by
    :func:`~data_contracts.read_table`) is used when there is one. Otherwise it is inferred
    from the block starts; a single block does not tell the step, which is then taken as a
    quarter of the length (75 % overlap) with a warning.

    Raises
    ------
    WorkbenchError
        If the block starts do not lie on one grid (or not on the recorded one).
    """
    import warnings

    from data_contracts import recorded_grid
    from data_contracts.grid import grid_mismatch

    from .errors import WorkbenchError

    recorded = recorded_grid(table)
    if recorded is not None:
        off_grid = grid_mismatch(table, recorded)
        if off_grid is not None:
            raise WorkbenchError(off_grid)
        return pd.Timestamp(recorded["t0"]), recorded["length_s"], recorded["step_s"]
    blocks = table[["block", "block_start", "block_end"]].drop_duplicates("block")
    blocks = blocks.sort_values("block")
    start = pd.to_datetime(blocks["block_start"], utc=True)
    length = (pd.to_datetime(blocks["block_end"], utc=True) - start).dt.total_seconds()
    if len(blocks) > 1:
        steps = start.diff().dt.total_seconds().to_numpy()[1:] / np.diff(blocks["block"])
        step = float(np.median(steps))
    else:
        step = float(length.iat[0]) / 4.0
        warnings.warn(
            f"one block and no recorded block grid: the step between blocks is taken as a "
            f"quarter of the block length ({step:g} s, 75 % overlap)",
            UserWarning,
            stacklevel=2,
        )
    t0 = start.iat[0] - pd.Timedelta(seconds=step * int(blocks["block"].iat[0]))
    expected = t0 + pd.to_timedelta(blocks["block"].to_numpy() * step, unit="s")
    off = np.abs((start.to_numpy() - expected.to_numpy()) / np.timedelta64(1, "s")) > 1e-3
    if off.any():
        first = int(blocks["block"].to_numpy()[off][0])
        raise WorkbenchError(f"block {first}: block_start is off the block grid (step {step:g} s)")
    return t0, float(length.median()), step
