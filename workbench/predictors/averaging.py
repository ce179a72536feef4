"""Ship-log predictors averaged over the blocks of the voyage's block grid.

:func:`block_predictors` turns the canonical ship log (:func:`data_contracts.read_dship`;
rows at 1 s to 1 min, cells empty where a sensor has no reading, stretches without rows)
into the PREDICTORS table: one row per block with the mean of each column over the block's
window ``[block_start, block_end)``. It works on cumulative sums over the time-sorted
samples and ``searchsorted`` on the block edges, so a 51-day log at 1 s (4.4 million rows,
about 15 000 blocks) takes about a second, two to four with despiking; there is no Python
loop over blocks.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence

import numpy as np
import pandas as pd

from data_contracts import LOG_COVERAGE, PREDICTOR_KEYS, PREDICTORS, column_log_coverage_name

from ..blocks import DEFAULT_BLOCK_LENGTH_S, DEFAULT_BLOCK_STEP_S, BlockGrid
from ._common import (
    BLOCK_COLUMNS,
    CANONICAL_NAMES,
    PredictorWarning,
    check_numeric_columns,
    numeric_columns,
    time_ns,
)
from .faults import LogFaultOptions, flag_faulty

__all__ = [
    "block_coverage",
    "block_predictors",
    "circular_mean_deg",
    "excitation_weighted_predictors",
]

_NS = 1_000_000_000


def circular_mean_deg(angles_deg: np.ndarray, axis: int | None = None) -> np.ndarray:
    """Circular (vector) mean of angles, in [0, 360). NaN are ignored.

    Notes
    -----
    :math:`\\bar\\theta = \\operatorname{atan2}(\\overline{\\sin\\theta},
    \\overline{\\cos\\theta})` wrapped to [0, 360): the direction of the mean unit vector.
    350° and 10° average to 0°, not 180°. NaN where no angle is valid or the mean vector
    vanishes (e.g. 0° and 180°).
    """
    radians = np.deg2rad(np.asarray(angles_deg, dtype=float))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN slices give NaN
        sin = np.nanmean(np.sin(radians), axis=axis)
        cos = np.nanmean(np.cos(radians), axis=axis)
    return _angle(sin, cos)


def _angle(sin: np.ndarray, cos: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        angle = np.mod(np.rad2deg(np.arctan2(sin, cos)), 360.0)
        angle = np.where(angle >= 360.0, 0.0, angle)  # mod of -tiny rounds to 360.0
        vanished = np.hypot(sin, cos) < 1e-12
    return np.where(vanished, np.nan, angle)


def _block_table(
    log_times: np.ndarray,
    grid: BlockGrid | None,
    blocks,
    length_s: float | None,
    step_s: float | None,
) -> pd.DataFrame:
    """block, block_start, block_end of the blocks to average over."""
    if isinstance(blocks, pd.DataFrame):
        missing = [c for c in BLOCK_COLUMNS if c not in blocks.columns]
        if missing:
            raise ValueError(f"blocks table lacks column(s) {', '.join(missing)}")
        table = (
            blocks[list(BLOCK_COLUMNS)]
            .drop_duplicates("block")
            .sort_values("block", kind="stable")
            .reset_index(drop=True)
        )
        table["block_start"] = pd.to_datetime(table["block_start"], utc=True)
        table["block_end"] = pd.to_datetime(table["block_end"], utc=True)
        return table
    if grid is None:
        if len(log_times) == 0:
            raise ValueError("the log is empty; give a grid and blocks")
        grid = BlockGrid.from_first_time(
            pd.Timestamp(int(log_times[0]), tz="UTC"),
            DEFAULT_BLOCK_LENGTH_S if length_s is None else length_s,
            DEFAULT_BLOCK_STEP_S if step_s is None else step_s,
        )
    else:
        for name, value, own in (
            ("length_s", length_s, grid.length_s),
            ("step_s", step_s, grid.step_s),
        ):
            if value is not None and float(value) != own:
                raise ValueError(f"{name}={value:g} contradicts the grid's {name}={own:g}")
    if blocks is None:
        if len(log_times) == 0:
            return grid.frame([])
        interval = np.median(np.diff(log_times)) if len(log_times) > 1 else 0
        first = pd.Timestamp(int(log_times[0]), tz="UTC")
        last = pd.Timestamp(int(log_times[-1] + interval), tz="UTC")
        return grid.frame(grid.complete_blocks(first, last))
    return grid.frame(np.unique(np.asarray(list(blocks), dtype=np.int64)))


def _prefix_sums(rows: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """``rows[:, :i].sum(axis=1)`` for every i in *indices* (0 <= i <= n), shape (c, len).

    Sums the segments between the sorted distinct indices with one ``np.add.reduceat``
    (a vectorised pass, much faster than a full cumulative sum) and accumulates those.
    """
    n = rows.shape[1]
    edges = np.unique(np.concatenate(([0], indices)))
    edges = edges[edges < n]
    if n == 0:
        return np.zeros((rows.shape[0], len(indices)))
    segments = np.add.reduceat(rows, edges, axis=1, dtype=np.float64)
    prefix = np.zeros((rows.shape[0], len(edges) + 1))
    np.cumsum(segments, axis=1, out=prefix[:, 1:])
    # prefix[:, i] = sum before edges[i]; index n maps to the total (last column)
    position = np.where(indices >= n, len(edges), np.searchsorted(edges, indices))
    return prefix[:, position]


def _window_sums(
    times: np.ndarray, rows: np.ndarray, starts: np.ndarray, ends: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per window: sum of the finite values and their count.

    *rows* has one contiguous row per column, shape (n_columns, n_samples); returns two
    arrays of shape (n_windows, n_columns).
    """
    lo = np.searchsorted(times, starts, side="left")
    hi = np.searchsorted(times, ends, side="left")
    finite = np.isfinite(rows)
    # centre each column on its first valid value: sums of small numbers keep precision
    first = np.argmax(finite, axis=1) if rows.shape[1] else np.zeros(rows.shape[0], int)
    centre = np.zeros((rows.shape[0], 1))
    if rows.shape[1]:
        centre[:, 0] = np.nan_to_num(rows[np.arange(rows.shape[0]), first])
    filled = np.where(finite, rows - centre, 0.0)
    indices = np.concatenate((lo, hi))
    sums = _prefix_sums(filled, indices)
    counts = np.rint(_prefix_sums(finite, indices)).astype(np.int64)
    k = len(lo)
    n = (counts[:, k:] - counts[:, :k]).T
    total = (sums[:, k:] - sums[:, :k]).T + n * centre[:, 0]
    return total, n


def _sample_interval_s(times: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Nominal sampling interval of each column: median step between its valid samples."""
    out = np.full(rows.shape[0], np.nan)
    for j in range(rows.shape[0]):
        t = times[np.isfinite(rows[j])]
        if len(t) > 1:
            out[j] = np.median(np.diff(t)) / _NS
    return out


def _rows(log: pd.DataFrame, names: Sequence[str]) -> np.ndarray:
    """The columns *names* as float rows, shape (len(names), len(log))."""
    if not names:
        return np.empty((0, len(log)))
    return np.vstack([log[c].to_numpy(dtype=float) for c in names])


def _coverage(
    times: np.ndarray, rows: np.ndarray, blocks: pd.DataFrame
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    starts = pd.DatetimeIndex(blocks["block_start"]).as_unit("ns").asi8
    ends = pd.DatetimeIndex(blocks["block_end"]).as_unit("ns").asi8
    total, n = _window_sums(times, rows, starts, ends)
    interval = _sample_interval_s(times, rows)
    duration = (ends - starts)[:, None] / _NS
    with np.errstate(invalid="ignore", divide="ignore"):
        coverage = np.minimum(1.0, n * np.nan_to_num(interval, nan=0.0) / duration)
    return coverage, total, n


def _prepare(log: pd.DataFrame) -> tuple[pd.DataFrame, np.ndarray]:
    times = time_ns(log)
    if len(times) > 1 and (np.diff(times) < 0).any():
        order = np.argsort(times, kind="stable")
        log = log.iloc[order].reset_index(drop=True)
        times = times[order]
    return log, times


def _selected_columns(log: pd.DataFrame, columns: Sequence[str] | None) -> list[str]:
    extras = [c for c in numeric_columns(log) if c not in CANONICAL_NAMES]
    if columns is None:
        return extras
    return [c for c in check_numeric_columns(log, columns) if c not in CANONICAL_NAMES]


def block_coverage(
    log: pd.DataFrame,
    *,
    grid: BlockGrid | None = None,
    blocks: pd.DataFrame | Iterable[int] | None = None,
    length_s: float | None = None,
    step_s: float | None = None,
    columns: Sequence[str] | None = None,
) -> pd.DataFrame:
    """Fraction of each block's window covered by valid samples, per column.

    Same arguments as :func:`block_predictors` (without the averaging options). Returns
    block, block_start, block_end and one column per predictor with the coverage in
    [0, 1]. See :func:`block_predictors`, Notes, for the definition.
    """
    log, times = _prepare(log)
    table = _block_table(times, grid, blocks, length_s, step_s)
    names = [c for c in CANONICAL_NAMES if c in log.columns] + _selected_columns(log, columns)
    coverage, _, _ = _coverage(times, _rows(log, names), table)
    out = table.copy()
    for j, name in enumerate(names):
        out[name] = coverage[:, j]
    return out


def block_predictors(
    log: pd.DataFrame,
    *,
    grid: BlockGrid | None = None,
    blocks: pd.DataFrame | Iterable[int] | None = None,
    length_s: float | None = None,
    step_s: float | None = None,
    min_coverage: float = 0.5,
    columns: Sequence[str] | None = None,
    direction_columns: Sequence[str] = ("wind_dir_rel_deg",),
    despike: bool = True,
    drop_faulty_stretches: bool = False,
    fault_options: LogFaultOptions | None = None,
) -> pd.DataFrame:
    """Average a ship log over the blocks of the block grid (PREDICTORS table).

    Parameters
    ----------
    log : DataFrame
        Canonical ship log: ``time`` (UTC) and numeric columns, as returned by
        :func:`data_contracts.read_dship`. Unsorted logs are sorted by time.
    grid : BlockGrid, optional
        Block grid; default: anchored at the first log time floored to *step_s*.
    blocks : DataFrame or iterable of int, optional
        Which blocks: a table with ``block``, ``block_start``, ``block_end`` (e.g. a
        tracked modal table -- one row per block is produced, with the table's block spans;
        *grid* is then not used), or block numbers on *grid*. Default: every block lying entirely inside the log's span.
    length_s, step_s : float, optional
        Block length and step when no *grid* is given (default 1200 s and 300 s). [s]
    min_coverage : float
        A block's value is NaN when the valid samples cover less than this fraction of its
        window (see Notes).
    columns : sequence of str, optional
        Extra numeric columns to average besides the canonical predictors (which are always
        produced, NaN when absent). Default: all other numeric columns of the log.
    direction_columns : sequence of str
        Angular columns averaged as circular (vector) means, result in [0, 360). [deg]
    despike : bool
        Set spikes found by :func:`~workbench.predictors.faults.flag_faulty` in the
        canonical columns to NaN first (a :class:`PredictorWarning` reports the counts and
        any faulty stretches).
    drop_faulty_stretches : bool
        With *despike*, also blank the canonical columns inside their faulty stretches.
    fault_options : LogFaultOptions, optional
        Thresholds of :func:`~workbench.predictors.faults.flag_faulty`.

    Returns
    -------
    DataFrame
        PREDICTORS contract: block, block_start, block_end, the canonical predictors, then
        the extra columns; one row per block, ascending.

    Notes
    -----
    Column :math:`c` of block :math:`k` is the mean of the valid samples with times in
    :math:`[s_k, e_k)`; from cumulative sums :math:`S` and counts :math:`N` over the
    time-sorted samples and the indices :math:`i = \\mathrm{searchsorted}(t, s_k)`,
    :math:`j = \\mathrm{searchsorted}(t, e_k)`: :math:`\\bar x = (S_j - S_i) / (N_j - N_i)`.
    Directions average :math:`\\sin` and :math:`\\cos` the same way
    (:func:`circular_mean_deg`). Coverage is :math:`\\min(1, n\\,\\Delta_c / (e_k - s_k))`
    with :math:`n` the valid samples in the window and :math:`\\Delta_c` the column's
    nominal sampling interval (median step between its valid samples): 20 one-minute
    readings cover a 20-min block fully, a 10-min outage halves the coverage.
    """
    if not 0 <= float(min_coverage) <= 1:
        raise ValueError(f"min_coverage={min_coverage} must be in [0, 1]")
    log, times = _prepare(log)
    table = _block_table(times, grid, blocks, length_s, step_s)
    extras = _selected_columns(log, columns)
    canonical = [c for c in CANONICAL_NAMES if c in log.columns]
    absent = [c for c in CANONICAL_NAMES if c not in log.columns]
    if absent:
        warnings.warn(
            f"log has no column {', '.join(absent)}; filled with NaN",
            PredictorWarning,
            stacklevel=2,
        )
    if despike and canonical and len(log):
        flags = flag_faulty(
            log,
            columns=canonical,
            direction_columns=tuple(direction_columns),
            options=fault_options,
        )
        log = flags.apply(log, drop_faulty_stretches=drop_faulty_stretches)
        _warn_faults(flags, drop_faulty_stretches)
    names = canonical + extras
    rows = _rows(log, names)
    coverage, total, n = _coverage(times, rows, table)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = total / n
    means[coverage < min_coverage] = np.nan
    means[n == 0] = np.nan

    directions = [c for c in direction_columns if c in names]
    if directions:
        starts = pd.DatetimeIndex(table["block_start"]).as_unit("ns").asi8
        ends = pd.DatetimeIndex(table["block_end"]).as_unit("ns").asi8
        index = [names.index(c) for c in directions]
        radians = np.deg2rad(rows[index])
        sin_sum, count = _window_sums(times, np.sin(radians), starts, ends)
        cos_sum, _ = _window_sums(times, np.cos(radians), starts, ends)
        with np.errstate(invalid="ignore", divide="ignore"):
            angle = _angle(sin_sum / count, cos_sum / count)
        angle[(coverage[:, index] < min_coverage) | (count == 0)] = np.nan
        means[:, index] = angle

    out = table.copy()
    for name in CANONICAL_NAMES:
        out[name] = means[:, names.index(name)] if name in names else np.nan
    for name in extras:
        out[name] = means[:, names.index(name)]
    used = _covered_columns(rows, len(canonical), coverage.shape[1])
    out[LOG_COVERAGE.name] = (
        np.clip(coverage[:, used].min(axis=1), 0.0, 1.0) if used.size else np.full(len(out), np.nan)
    )
    for name in CANONICAL_NAMES:
        k = names.index(name) if name in canonical else -1
        out[column_log_coverage_name(name)] = (
            np.clip(coverage[:, k], 0.0, 1.0) if k in used else np.full(len(out), np.nan)
        )
    return PREDICTORS.validate(out)


def _covered_columns(rows: np.ndarray, n_canonical: int, n_columns: int) -> np.ndarray:
    """Positions of the columns whose coverage marks a block: the canonical columns (every
    averaged column when there is none) with at least one valid reading, so a sensor the
    log never had a reading of does not mark every block. ``log_coverage`` is the least
    coverage over them (NaN when there is none), ``log_coverage_<column>`` each canonical
    one's own (NaN for a column not among them)."""
    used = np.arange(n_canonical if n_canonical else n_columns)
    if rows.size:
        used = used[np.isfinite(rows[used]).any(axis=1)]
    return used


def _warn_faults(flags, dropped_stretches: bool) -> None:
    counts = {c: n for c, n in flags.n_spikes.items() if n}
    faulty = flags.stretches[flags.stretches["faulty"]]
    if not counts and faulty.empty:
        return
    parts = []
    if counts:
        parts.append(
            "despiked (set to NaN) "
            + ", ".join(f"{n} {c} sample{'s' if n > 1 else ''}" for c, n in counts.items())
        )
    if not faulty.empty:
        stretches = [
            f"{row.column} {row.start:%Y-%m-%dT%H:%MZ}-{row.end:%H:%MZ} ({row.reason})"
            for row in faulty.itertuples()
        ]
        shown = "; ".join(stretches[:5]) + (
            f"; ... {len(stretches) - 5} more" if len(stretches) > 5 else ""
        )
        parts.append(("blanked" if dropped_stretches else "faulty") + f" stretches: {shown}")
    warnings.warn("ship log: " + "; ".join(parts), PredictorWarning, stacklevel=3)


def excitation_weighted_predictors(
    log: pd.DataFrame,
    blocks: pd.DataFrame,
    excitation: pd.DataFrame,
    *,
    min_coverage: float = 0.5,
    direction_columns: Sequence[str] = ("wind_dir_rel_deg",),
    **options,
) -> pd.DataFrame:
    """The ship log averaged over *blocks* as SSI reads a block: weighted by excitation.

    SSI identifies a block from its output covariances, the time average of the local
    covariances, each proportional to the local excitation power; where the excitation
    changes inside a block (the ship speeds up), the block's modal estimate leans toward
    its strongly excited part. The predictors the estimate is compared with are therefore
    averaged with the same weights.

    Parameters
    ----------
    log : DataFrame
        Canonical ship log (as :func:`block_predictors` takes it).
    blocks : DataFrame
        ``block``, ``block_start``, ``block_end``: each block's own span.
    excitation : DataFrame
        Consecutive intervals ``start``, ``end`` (UTC; in any order) and ``power`` (the
        excitation power of the conditioned accelerations, e.g. the half-steps of
        ``excitation.csv`` that ``identify --block-minutes auto`` writes). [(m/s²)²]
    min_coverage, direction_columns, **options
        As :func:`block_predictors` (applied to the intervals).

    Returns
    -------
    DataFrame
        PREDICTORS contract, one row per block. Column :math:`c` of block :math:`k` is
        :math:`\\sum_i w_i \\bar x_i / \\sum_i w_i` over the intervals :math:`i` inside
        the block with a valid mean :math:`\\bar x_i`, :math:`w_i` their power times their
        duration; directions are the weighted vector mean. A block no interval lies in
        keeps its plain mean (:func:`block_predictors`).
    """
    plain = block_predictors(
        log,
        blocks=blocks,
        min_coverage=min_coverage,
        direction_columns=direction_columns,
        **options,
    )
    # the blocks find their intervals by binary search: in time order, whatever the
    # table's (two files joined the wrong way round)
    excitation = (
        excitation.assign(_start=pd.to_datetime(excitation["start"], utc=True))
        .sort_values("_start", kind="stable")
        .reset_index(drop=True)
    )
    intervals = pd.DataFrame(
        {
            "block": np.arange(len(excitation), dtype=np.int64),
            "block_start": pd.to_datetime(excitation["start"], utc=True),
            "block_end": pd.to_datetime(excitation["end"], utc=True),
        }
    )
    if intervals.empty:
        return plain
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PredictorWarning)  # reported once, for the blocks
        parts = block_predictors(
            log,
            blocks=intervals,
            min_coverage=min_coverage,
            direction_columns=direction_columns,
            **options,
        )
    power = excitation["power"].to_numpy(dtype=float)
    duration = (intervals["block_end"] - intervals["block_start"]).dt.total_seconds().to_numpy()
    weight = np.where(np.isfinite(power) & (power > 0), power * duration, 0.0)
    part_start = pd.DatetimeIndex(intervals["block_start"]).as_unit("ns").asi8
    part_end = pd.DatetimeIndex(intervals["block_end"]).as_unit("ns").asi8
    starts = pd.DatetimeIndex(pd.to_datetime(plain["block_start"], utc=True)).as_unit("ns").asi8
    ends = pd.DatetimeIndex(pd.to_datetime(plain["block_end"], utc=True)).as_unit("ns").asi8
    first = np.searchsorted(part_start, starts, side="left")
    last = np.searchsorted(part_end, ends, side="right")  # intervals [first, last) inside
    columns = [c for c in plain.columns if c not in PREDICTOR_KEYS and c in parts.columns]
    out = plain.copy()
    for column in columns:
        values = parts[column].to_numpy(dtype=float)
        direction = column in direction_columns
        result = out[column].to_numpy(dtype=float).copy()
        for row in range(len(out)):  # one pass over the blocks, each over its intervals
            lo, hi = int(first[row]), int(last[row])
            if hi <= lo:
                continue
            x, w = values[lo:hi], weight[lo:hi]
            ok = np.isfinite(x) & (w > 0)
            if not ok.any():
                continue
            if direction:
                radians = np.deg2rad(x[ok])
                result[row] = float(
                    _angle(np.sum(w[ok] * np.sin(radians)), np.sum(w[ok] * np.cos(radians)))
                )
            else:
                result[row] = float(np.sum(w[ok] * x[ok]) / np.sum(w[ok]))
        out[column] = result
    return PREDICTORS.validate(out)
