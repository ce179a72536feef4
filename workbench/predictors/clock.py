"""Does the ship log's clock agree with the accelerations'? A check from the hull's
vibration.

A ship log written in local time without a UTC offset (``2024-03-01 14:00:00`` meant as
UTC+02:00) reads as UTC: every predictor then lands hours away from the blocks it belongs
to, and nothing in the files says so. The hull says so: its vibration level rises with the
speed and the shaft rate (the sea's and the propeller's excitation grow with them), so the
blocks' level follows the log's speed best when the two clocks agree.

:func:`clock_shift_scores` correlates the per-block level (the median over the channels of
the block's log RMS, each channel taken relative to its own median) with the log's speed
averaged over each block shifted by every candidate offset (whole and half hours,
:data:`CANDIDATE_SHIFTS_H`); :func:`clock_warning` says when a non-zero shift explains the
level clearly better than none. The thresholds come from the null distribution measured on
correct logs (benchmarks/results/dship_clock_50.txt). ``identify --dship`` runs the check
once (:func:`log_clock_warning`), the monitor as its blocks come
(:mod:`workbench.monitor.log_clock`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from ._common import time_ns

__all__ = [
    "CANDIDATE_SHIFTS_H",
    "block_level",
    "clock_agrees",
    "clock_shift_scores",
    "clock_warning",
    "log_clock_warning",
]

#: Shifts tried: the world's UTC offsets in half hours, UTC-12:00 to UTC+14:00. [h]
CANDIDATE_SHIFTS_H = np.arange(-24, 29) / 2.0
#: Blocks with a speed at a shift below which the shift is not judged.
MIN_BLOCKS = 24
#: Spread (standard deviation) of the blocks' speed (or, without a speed in the log, shaft
#: rate) below which a shift is not judged: a ship at rest (or at one speed) tells no clock
#: from another. [kn] or [rpm]
MIN_SPREAD = {"speed_kn": 1.0, "shaft_rpm": 10.0}
#: Share of a block the log must cover for its speed at a shift.
MIN_COVERAGE = 0.5
#: Rank correlation of level and speed the best shift must reach.
MIN_CORRELATION = 0.8
#: How much better than no shift the best shift must correlate (rank correlation).
MIN_GAIN = 0.3


def block_level(channels: pd.DataFrame) -> pd.DataFrame:
    """The hull's vibration level of each block: the median over the channels of
    ln(RMS), each channel relative to its own median over the blocks (a dropped channel
    does not move the level).

    Parameters
    ----------
    channels : DataFrame
        ``block``, ``block_start``, ``channel``, ``rms`` (identify's ``channels.csv``).

    Returns
    -------
    DataFrame
        ``block``, ``block_start`` (UTC), ``level`` [-], one row per block, ascending.
    """
    table = channels[["block", "block_start", "channel", "rms"]]
    rms = pd.to_numeric(table["rms"], errors="coerce").to_numpy(dtype=float)
    keep = np.isfinite(rms) & (rms > 0)
    table = table.loc[keep].assign(log_rms=np.log(rms[keep]))
    wide = table.pivot_table(index="block", columns="channel", values="log_rms")
    level = (wide - wide.median(axis=0)).median(axis=1)
    starts = table.drop_duplicates("block").set_index("block")["block_start"]
    return pd.DataFrame(
        {
            "block": level.index.to_numpy(),
            "block_start": pd.to_datetime(starts.reindex(level.index), utc=True).to_numpy(),
            "level": level.to_numpy(),
        }
    )


def _ranks(values: np.ndarray) -> np.ndarray:
    """Ranks of *values*, ties sharing their mean rank."""
    return pd.Series(values).rank(method="average").to_numpy()


def _rank_correlation(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman's rank correlation of *x* and *y* (NaN when either is constant)."""
    rx, ry = _ranks(x), _ranks(y)
    rx, ry = rx - rx.mean(), ry - ry.mean()
    denominator = np.sqrt((rx * rx).sum() * (ry * ry).sum())
    return float((rx * ry).sum() / denominator) if denominator > 0 else float("nan")


def _speed_column(log: pd.DataFrame) -> str | None:
    """The log's speed through the water or over ground, else its shaft rate (None)."""
    for column in ("speed_kn", "shaft_rpm"):
        if column in log.columns and np.isfinite(pd.to_numeric(log[column])).sum() > 1:
            return column
    return None


def clock_shift_scores(
    level: pd.DataFrame,
    block_length_s: float,
    log: pd.DataFrame,
    shifts_h=CANDIDATE_SHIFTS_H,
) -> pd.DataFrame:
    """Rank correlation of the blocks' level with the log's speed read *shift* hours
    later, for every shift.

    Parameters
    ----------
    level : DataFrame
        ``block_start`` (UTC) and ``level`` (:func:`block_level`).
    block_length_s : float or array of float
        Length of the blocks: one for all, or each block's own (one per row of *level*:
        blocks of varying length, ``--block-minutes auto``). [s] A block's speed at a
        shift is the log's mean over its own span, shifted.
    log : DataFrame
        Canonical ship log (:func:`data_contracts.read_dship`): ``time`` and ``speed_kn``
        (or, without a speed, ``shaft_rpm``).
    shifts_h : sequence of float
        Shifts tried. [h] A log whose times are local at UTC+02:00 but read as UTC follows
        the level best at +2: block [s, e) is at log times [s + 2 h, e + 2 h).

    Returns
    -------
    DataFrame
        ``shift_h``, ``n_blocks`` (blocks with a speed at that shift), ``speed_spread``
        (standard deviation of their speeds, in the column's unit) and ``correlation``
        (NaN below two blocks or for a constant speed); one row per shift; the log's
        column used in ``attrs["column"]``. Empty without a speed or shaft rate in the
        log.
    """
    columns = ["shift_h", "n_blocks", "speed_spread", "correlation"]
    column = _speed_column(log)
    if column is None or level.empty:
        return pd.DataFrame(columns=columns)
    values = pd.to_numeric(log[column]).to_numpy(dtype=float)
    times = time_ns(log)
    valid = np.isfinite(values)
    times, values = times[valid], values[valid]
    order = np.argsort(times, kind="stable")
    times, values = times[order], values[order]
    sums = np.concatenate([[0.0], np.cumsum(values)])
    step_ns = np.median(np.diff(times)) if len(times) > 1 else 1e9
    starts = pd.DatetimeIndex(pd.to_datetime(level["block_start"], utc=True)).as_unit("ns").asi8
    length_ns = np.rint(np.broadcast_to(np.asarray(block_length_s, float), len(starts)) * 1e9)
    length_ns = length_ns.astype(np.int64)
    wanted = level["level"].to_numpy(dtype=float)
    rows = []
    for shift in np.asarray(shifts_h, dtype=float):
        offset = int(round(shift * 3600e9))
        i = np.searchsorted(times, starts + offset)
        j = np.searchsorted(times, starts + offset + length_ns)
        count = j - i
        covered = count * step_ns >= MIN_COVERAGE * length_ns
        speed = (sums[j] - sums[i])[covered] / count[covered]
        ok = covered.nonzero()[0][np.isfinite(wanted[covered])]
        speed = speed[np.isfinite(wanted[covered])]
        spread = float(np.std(speed)) if len(speed) else float("nan")
        correlation = _rank_correlation(wanted[ok], speed) if len(ok) > 1 else float("nan")
        rows.append((float(shift), len(ok), spread, correlation))
    scores = pd.DataFrame(rows, columns=columns)
    scores.attrs["column"] = column
    return scores


def clock_warning(
    scores: pd.DataFrame,
    source: str,
    utc_offset: pd.Timedelta | None = None,
) -> str | None:
    """One warning line when a non-zero shift explains the level clearly better than none,
    else None.

    A shift is judged when at least :data:`MIN_BLOCKS` blocks have a speed at it, spread
    by at least :data:`MIN_SPREAD` (of the speed, else of the shaft rate). A log that as
    read gives that many blocks a speed, all about the same (a ship at rest or holding its
    speed), says nothing: the level then carries no speed to find elsewhere, and the check
    is silent. Otherwise the best judged shift must reach a rank correlation of
    :data:`MIN_CORRELATION` and beat the correlation at no shift by :data:`MIN_GAIN` (taken
    as 0 when the log as read covers too few blocks: the mark of a shifted clock).

    Parameters
    ----------
    scores : DataFrame
        :func:`clock_shift_scores`.
    source : str
        The ship log's file, named in the warning.
    utc_offset : Timedelta, optional
        The offset the log was read with (``--dship-utc-offset``); the warning names the
        offset that would place it.
    """
    from data_contracts.dship_names import format_utc_offset

    if scores.empty:
        return None
    enough = scores["n_blocks"] >= MIN_BLOCKS
    spread = scores["speed_spread"] >= MIN_SPREAD[scores.attrs.get("column", "speed_kn")]
    as_read = scores["shift_h"] == 0
    if (enough & as_read & ~spread).any():
        return None  # the log as read covers the blocks at one speed
    judged = scores[enough & spread & np.isfinite(scores["correlation"])]
    if judged.empty:
        return None
    best = judged.loc[judged["correlation"].idxmax()]
    if best["shift_h"] == 0:
        return None
    at_zero = judged.loc[judged["shift_h"] == 0, "correlation"]
    baseline = float(at_zero.iloc[0]) if len(at_zero) else 0.0
    if best["correlation"] < MIN_CORRELATION or best["correlation"] - baseline < MIN_GAIN:
        return None
    given = utc_offset if utc_offset is not None else pd.Timedelta(0)
    likely = format_utc_offset(given + pd.Timedelta(hours=float(best["shift_h"])))
    return (
        f"{source}: the hull's vibration level follows the log's speed best with the log's "
        f"times taken as UTC{likely} (rank correlation {best['correlation']:.2f}, against "
        f"{baseline:.2f} as read, UTC{format_utc_offset(given)}): if its times are local "
        f"time without an offset, give --dship-utc-offset {likely}"
    )


def clock_agrees(scores: pd.DataFrame) -> bool:
    """Whether the log as read is judged (:data:`MIN_BLOCKS` blocks with a speed, spread by
    :data:`MIN_SPREAD`) and follows the level best of all judged shifts, at a rank
    correlation of :data:`MIN_CORRELATION` or more: the two clocks agree, and more blocks
    will not say otherwise (the monitor then stops checking).

    Parameters
    ----------
    scores : DataFrame
        :func:`clock_shift_scores`.
    """
    if scores.empty:
        return False
    spread = scores["speed_spread"] >= MIN_SPREAD[scores.attrs.get("column", "speed_kn")]
    judged = scores[
        (scores["n_blocks"] >= MIN_BLOCKS) & spread & np.isfinite(scores["correlation"])
    ]
    at_zero = judged.loc[judged["shift_h"] == 0, "correlation"]
    return (
        len(at_zero) > 0
        and float(at_zero.iloc[0]) >= MIN_CORRELATION
        and float(at_zero.iloc[0]) >= float(judged["correlation"].max())
    )


def log_clock_warning(
    channels: str | os.PathLike,
    log: pd.DataFrame,
    source: str,
    utc_offset: pd.Timedelta | None = None,
    blocks: str | os.PathLike | None = None,
) -> str | None:
    """:func:`clock_warning` of identify's ``channels.csv`` (the blocks' RMS per channel)
    and the ship log *log* read from *source* (with *utc_offset*).

    Blocks of varying length (``--block-minutes auto``: ``channels.csv``'s grid has
    ``varying_length``) take each block's own span: its ``block_start`` and the
    ``block_length_s`` of identify's ``blocks.csv`` (*blocks*, required then)."""
    from data_contracts.grid import read_grid

    path = Path(channels)
    grid = read_grid(path, "csv") or {}
    table = pd.read_csv(path, usecols=["block", "block_start", "channel", "rms"])
    if table.empty:
        return None
    level = block_level(table)
    if grid.get("varying_length"):
        if blocks is None:
            raise ValueError(f"{path}: blocks of varying length: their blocks.csv is needed")
        lengths = pd.read_csv(blocks, usecols=["block", "block_length_s"])
        length_s = lengths.set_index("block")["block_length_s"].reindex(level["block"])
        level, length_s = level[length_s.notna().to_numpy()], length_s.dropna().to_numpy(float)
    else:
        length_s = float(grid.get("length_s", 1200.0))
    scores = clock_shift_scores(level, length_s, log)
    return clock_warning(scores, source, utc_offset)
