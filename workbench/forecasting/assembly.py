"""Output assembly of the sliding forecast: the per-row arrays to the forecast table.

:func:`drop_unusable` leaves out rows without a model or Kalman value, :func:`assemble_rows`
turns the (grid row, mode) arrays of a forecast run into the FORECAST contract table with
its ``warning`` column (and option B's selected-pole columns). Shared by the window and
memory forecasts.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from .predictor_grid import block_log_coverage

__all__ = ["ASSEMBLED", "assemble_rows", "drop_unusable", "log_coverage_of", "with_log_coverage"]

#: The (grid row, mode) arrays :func:`assemble_rows` reads: SSI, model with bounds, Kalman
#: with its standard deviation, and option B's chosen pole (order, damping ratio, MAC).
ASSEMBLED = ("ssi", "model", "lower", "upper", "kalman", "std", "order", "damping", "mac")


def log_coverage_of(predictors: pd.DataFrame) -> pd.Series | None:
    """The ship log's coverage of each block (``log_coverage`` of the predictor table,
    indexed by block; the last row of a repeated block), or None when the table has none."""
    rows = predictors.drop_duplicates("block", keep="last")
    coverage = block_log_coverage(rows)
    if coverage is None:
        return None
    return pd.Series(coverage, index=rows["block"].to_numpy(dtype=np.int64))


def with_log_coverage(table: pd.DataFrame, coverage: pd.Series | None) -> pd.DataFrame:
    """*table* with each row's ``log_coverage`` (its block's; NaN for a block *coverage*
    lacks): the forecast table marks the rows whose predictors are means of part of the
    block, or were filled. Unchanged when *coverage* is None or the table is empty."""
    if coverage is None or table.empty or "block" not in table.columns:
        return table
    values = coverage.reindex(table["block"].to_numpy(dtype=np.int64)).to_numpy(dtype=float)
    return table.assign(log_coverage=values)


def drop_unusable(out_phase, model, kalman, notes) -> None:
    """Rows without a model or Kalman value (a mode without any data yet) get phase 0:
    no row rather than a NaN row; counted in *notes*."""
    unusable = (out_phase > 0) & ~(np.isfinite(model) & np.isfinite(kalman))
    if unusable.any():
        notes["rows left out: no model value available (mode without data so far)"] += int(
            unusable.sum()
        )
        out_phase[unusable] = 0


def assemble_rows(
    blocks: np.ndarray,
    block_start,
    mode_labels: np.ndarray,
    option: str,
    phase: np.ndarray,
    out: Mapping[str, np.ndarray],
    windows: tuple[np.ndarray, np.ndarray],
    warning_map: Mapping[tuple[int, int], list[str]],
) -> pd.DataFrame:
    """FORECAST table of the rows with a phase (1 train, 2 forecast): the arrays of
    :data:`ASSEMBLED` in *out*, the training window's first and last block per row
    (*windows*) and the row warnings."""
    ssi, model, lower, upper, kalman, std, order, damping, selected_mac = (
        out[name] for name in ASSEMBLED
    )
    w0, w1 = windows
    rows, cols = np.nonzero(phase)
    n = rows.size
    warning_text = np.full(n, "", dtype=object)
    if warning_map:
        position = {(int(r), int(c)): p for p, (r, c) in enumerate(zip(rows, cols, strict=True))}
        for key, messages in warning_map.items():
            p = position.get(key)
            if p is not None:
                warning_text[p] = "; ".join(dict.fromkeys(m for m in messages if m))
    frame = pd.DataFrame(
        {
            "block": blocks[rows],
            "block_start": pd.to_datetime(block_start[rows], utc=True),
            "mode": mode_labels[cols].astype(np.int64),
            "phase": np.where(phase[rows, cols] == 1, "train", "forecast"),
            "ssi_frequency_hz": ssi[rows, cols],
            "model_frequency_hz": model[rows, cols],
            "model_lower_hz": lower[rows, cols],
            "model_upper_hz": upper[rows, cols],
            "kalman_frequency_hz": kalman[rows, cols],
            "kalman_std_hz": std[rows, cols],
            "option": option,
            "window_start_block": w0[rows, cols],
            "window_end_block": w1[rows, cols],
        }
    )
    if option == "B":
        frame["selected_model_order"] = pd.array(
            np.where(np.isfinite(order[rows, cols]), order[rows, cols], np.nan)
        ).astype("Int64")
        frame["selected_damping_ratio"] = damping[rows, cols]
        frame["selected_mac"] = selected_mac[rows, cols]
    frame["warning"] = pd.array(warning_text.tolist(), dtype="string")
    frame = frame.sort_values(["mode", "block"], kind="stable").reset_index(drop=True)
    return frame
