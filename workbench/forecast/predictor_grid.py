"""The predictor matrix of a forecast: one row per block of the predictor table."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

__all__ = ["predictor_matrix"]


def predictor_matrix(
    predictors: pd.DataFrame, predictor_columns: Sequence[str] | None
) -> tuple[pd.DataFrame, np.ndarray, np.ndarray, list[str], np.ndarray]:
    """``(grid, blocks, block_start, columns, X)`` of *predictors*, one row per block.

    *grid* is the predictor table sorted by block (the last row of a repeated block kept);
    consecutive rows are consecutive Kalman steps. *columns* are *predictor_columns*, or
    every numeric, non-boolean column but ``block`` when None; *X* holds their values
    (NaN where missing).

    Raises
    ------
    ValueError
        When a named predictor column is not in *predictors*.
    """
    grid = predictors.sort_values("block").drop_duplicates("block", keep="last")
    blocks = grid["block"].to_numpy(dtype=np.int64)
    block_start = pd.to_datetime(grid["block_start"], utc=True).to_numpy()
    if predictor_columns is None:
        columns = [
            c
            for c in grid.columns
            if c != "block"
            and pd.api.types.is_numeric_dtype(grid[c].dtype)
            and not pd.api.types.is_bool_dtype(grid[c].dtype)
        ]
    else:
        columns = list(predictor_columns)
        missing = [c for c in columns if c not in grid.columns]
        if missing:
            raise ValueError(f"predictor_columns {missing} are not columns of predictors")
    X = (
        grid[columns].to_numpy(dtype=float, na_value=np.nan)
        if columns
        else np.empty((len(grid), 0))
    )
    return grid, blocks, block_start, columns, X
