"""The matrices of a forecast: the predictors and the tracked modes, one row per block of
the predictor table."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from data_contracts import PREDICTOR_KEYS, column_log_coverage_name

from ..errors import DataError, PredictorError
from ..predictors.directions import direction_source, model_columns, with_direction_components

__all__ = [
    "block_centre_ns",
    "block_column_coverage",
    "block_log_coverage",
    "forecast_span",
    "mode_matrix",
    "modes_to_forecast",
    "predictor_matrix",
]

#: Nanoseconds in an hour. [ns/h]
NS_PER_HOUR = 3.6e12


def predictor_matrix(
    predictors: pd.DataFrame, predictor_columns: Sequence[str] | None
) -> tuple[pd.DataFrame, np.ndarray, np.ndarray, list[str], np.ndarray]:
    """``(grid, blocks, block_start, columns, X)`` of *predictors*, one row per block.

    *grid* is the predictor table sorted by block (the last row of a repeated block kept);
    consecutive rows are consecutive Kalman steps. *columns* are *predictor_columns*, or
    every numeric, non-boolean column but the keys when None, with a direction column
    (``wind_dir_rel_deg``) as its cosine (``wind_dir_rel_cos``:
    :mod:`workbench.predictors.directions`); *X* holds their values
    (NaN where missing). *grid* keeps the direction in degrees.

    Raises
    ------
    PredictorError
        When a named predictor column is not in *predictors*.
    """
    grid = predictors.sort_values("block").drop_duplicates("block", keep="last")
    blocks = grid["block"].to_numpy(dtype=np.int64)
    block_start = pd.to_datetime(grid["block_start"], utc=True).to_numpy()
    inputs = with_direction_components(grid)
    if predictor_columns is None:
        columns = [
            c
            for c in inputs.columns
            if c not in PREDICTOR_KEYS
            and pd.api.types.is_numeric_dtype(inputs[c].dtype)
            and not pd.api.types.is_bool_dtype(inputs[c].dtype)
        ]
    else:
        named = list(predictor_columns)
        missing = [c for c in named if c not in grid.columns and c not in inputs.columns]
        if missing:
            raise PredictorError(
                f"the predictor table has no column {', '.join(map(repr, missing))}",
                parameter="predictor_columns",
                value=named,
            )
        columns = model_columns(named)
    X = (
        inputs[columns].to_numpy(dtype=float, na_value=np.nan)
        if columns
        else np.empty((len(grid), 0))
    )
    return grid, blocks, block_start, columns, X


def block_log_coverage(table: pd.DataFrame) -> np.ndarray | None:
    """The table's ``log_coverage`` (the ship log's share of each block) as floats, NaN
    where missing; None when the table has no such column."""
    if "log_coverage" not in table.columns:
        return None
    return table["log_coverage"].to_numpy(dtype=float, na_value=np.nan)


def block_column_coverage(table: pd.DataFrame, columns: Sequence[str]) -> np.ndarray | None:
    """The ship log's share of each block per predictor *columns*, shape (rows of *table*,
    len(*columns*)): a column's own ``log_coverage_<column>`` (a direction's cosine:
    the direction's), NaN where the table has none (a column the averaging gives
    no share of, such as the time trend); None when the table has no ``log_coverage``
    (it does not say how much of a block is logged)."""
    if block_log_coverage(table) is None:
        return None
    out = np.full((len(table), len(columns)), np.nan)
    for j, column in enumerate(columns):
        name = column_log_coverage_name(direction_source(column))
        if name in table.columns:
            out[:, j] = table[name].to_numpy(dtype=float, na_value=np.nan)
    return out


def block_centre_ns(grid: pd.DataFrame) -> np.ndarray:
    """The blocks' centres as int64 nanoseconds since the epoch (UTC).

    Without ``block_end`` the starts stand for the centres (blocks of one length: the
    same hours of elapsed time). The times are read in nanoseconds whatever the
    resolution the table was stored with (pandas parses text at microsecond resolution).
    """
    start_ns = pd.DatetimeIndex(pd.to_datetime(grid["block_start"], utc=True))
    start_ns = start_ns.as_unit("ns").asi8
    if "block_end" in grid.columns:
        end_ns = pd.DatetimeIndex(pd.to_datetime(grid["block_end"], utc=True))
        end_ns = end_ns.as_unit("ns").asi8
        start_ns = start_ns + (end_ns - start_ns) // 2
    return start_ns


def modes_to_forecast(modal: pd.DataFrame, modes: Sequence[int] | None) -> np.ndarray:
    """The mode labels to forecast: *modes*, or every label of *modal* in ascending order.

    Raises
    ------
    ValueError
        When there is no mode to forecast.
    """
    labels = (
        np.array(sorted(int(m) for m in modal["mode"].dropna().unique()))
        if modes is None
        else np.asarray(modes, dtype=np.int64)
    )
    if labels.size == 0:
        raise ValueError("modal has no modes to forecast")
    return labels


def mode_matrix(
    modal: pd.DataFrame, blocks: np.ndarray, mode_labels: np.ndarray, column: str
) -> np.ndarray:
    """*column* of the modal table as a (block, mode) matrix on the rows *blocks* (sorted)
    and the columns *mode_labels*; NaN where a mode was not measured in a block, and rows of
    *modal* outside those blocks or modes ignored."""
    n_blocks = len(blocks)
    matrix = np.full((n_blocks, len(mode_labels)), np.nan)
    if n_blocks == 0:
        return matrix
    modal_blocks = modal["block"].to_numpy(dtype=np.int64)
    rows = np.searchsorted(blocks, modal_blocks)
    rows_ok = (rows < n_blocks) & (blocks[np.minimum(rows, n_blocks - 1)] == modal_blocks)
    mode_index = {int(m): j for j, m in enumerate(mode_labels)}
    cols = np.array([mode_index.get(int(m), -1) for m in modal["mode"].to_numpy()])
    keep = rows_ok & (cols >= 0)
    matrix[rows[keep], cols[keep]] = modal[column].to_numpy(dtype=float)[keep]
    return matrix


def forecast_span(
    blocks, start_block, end_block, train_blocks: int, modal_blocks=None
) -> tuple[int, int]:
    """Grid rows of the first training block and of the last block forecast.

    Parameters
    ----------
    blocks : ndarray of int
        The predictor table's blocks, sorted (the grid's rows).
    start_block, end_block : int or None
        The span to forecast (None: from the first row, to the last).
    train_blocks : int
        The training window. [blocks]
    modal_blocks : array-like of int, optional
        The modal table's blocks: when the predictor table has a row for each of them in
        the span, a span too short is the modal table's (the voyage's), not the
        predictor table's.

    Raises
    ------
    ValueError
        When *start_block* is not a block of the predictor table.
    PredictorError
        When the predictor table holds fewer than *train_blocks* + 1 blocks in the span
        and misses blocks of the modal table there.
    DataError
        When it holds every block of the modal table there, and they are too few.
    """
    n_blocks = len(blocks)
    if start_block is None:
        first = 0
    else:
        first = int(np.searchsorted(blocks, start_block))
        if first >= n_blocks or blocks[first] != start_block:
            raise ValueError(f"start_block={start_block} is not a block of predictors")
    last = n_blocks - 1
    if end_block is not None:
        last = int(np.searchsorted(blocks, int(end_block), side="right")) - 1
    if last - first + 1 >= train_blocks + 1:
        return first, last
    held = max(last - first + 1, 0)
    need = (
        f"a training window of {train_blocks} blocks and one block to forecast need at "
        f"least {train_blocks + 1}"
    )
    if modal_blocks is not None:
        voyage = np.unique(np.asarray(modal_blocks, dtype=np.int64))
        if start_block is not None:
            voyage = voyage[voyage >= start_block]
        if end_block is not None:
            voyage = voyage[voyage <= int(end_block)]
        if held and np.isin(voyage, blocks[first : last + 1]).all():
            raise DataError(
                f"the modal table holds only {voyage.size} block(s) in the span to forecast"
                f"{_which(voyage)}, each with predictors: {need}",
                parameter="train_blocks",
                value=train_blocks,
            )
    raise PredictorError(
        f"the predictor table holds only {held} block(s) in the span to forecast"
        f"{_which(blocks[first : last + 1])}: {need}",
        parameter="train_blocks",
        value=train_blocks,
    )


def _which(blocks) -> str:
    """`` (blocks 0 to 20)`` for consecutive *blocks*, `` (6 of blocks 0 to 20)`` else."""
    if len(blocks) == 0:
        return ""
    low, high = int(blocks[0]), int(blocks[-1])
    if len(blocks) == high - low + 1:
        return f" (blocks {low} to {high})"
    return f" ({len(blocks)} of blocks {low} to {high})"
