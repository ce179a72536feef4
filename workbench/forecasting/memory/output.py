"""Output table of the memory forecast: the sliding forecast's columns plus, for option B,
the chosen pole cluster's orders and scatter.

Used by :func:`~workbench.forecasting.memory.forecast.memory_forecast`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..assembly import assemble_rows

__all__ = ["OUTPUT_ARRAYS", "assemble_table"]

#: Per-row x per-mode float outputs of the forecast (NaN where a row has none).
OUTPUT_ARRAYS = (
    "ssi",
    "model",
    "lower",
    "upper",
    "kalman",
    "std",
    "order",
    "damping",
    "mac",
    "n_orders",
    "scatter",
    "min_order",
    "max_order",
    "seen",
    "probability",
    "guard",
)


def assemble_table(
    blocks: np.ndarray,
    block_start,
    mode_labels: np.ndarray,
    option: str,
    out_phase: np.ndarray,
    out: dict[str, np.ndarray],
    windows: tuple[np.ndarray, np.ndarray],
    out_warning: dict[tuple[int, int], list[str]],
) -> pd.DataFrame:
    """Forecast table from the per-row outputs (rows without a phase left out:
    :func:`~workbench.forecasting.assembly.drop_unusable` first)."""
    table = assemble_rows(
        blocks, block_start, mode_labels, option, out_phase, out, windows, out_warning
    )
    rows_, cols_ = np.nonzero(out_phase)
    probability = pd.DataFrame(
        {
            "block": blocks[rows_],
            "mode": mode_labels[cols_].astype(np.int64),
            "model_probability": out["probability"][rows_, cols_],
            "guard_weight": out["guard"][rows_, cols_],
        }
    )
    table = table.merge(probability, on=["block", "mode"], how="left", validate="one_to_one")
    if option == "B":
        extra = pd.DataFrame(
            {
                "block": blocks[rows_],
                "mode": mode_labels[cols_].astype(np.int64),
                "selected_n_orders": _counts(out["n_orders"][rows_, cols_]),
                "selected_min_order": _counts(out["min_order"][rows_, cols_]),
                "selected_scatter_hz": out["scatter"][rows_, cols_],
            }
        )
        table = table.merge(extra, on=["block", "mode"], how="left", validate="one_to_one")
        table = table.rename(columns={"selected_model_order": "selected_max_order"})
        table["selected_model_order"] = table["selected_max_order"]
    return table


def _counts(values: np.ndarray) -> pd.api.extensions.ExtensionArray:
    """Whole numbers held as floats (NaN where none) as a nullable integer column."""
    return pd.array(np.where(np.isfinite(values), values, np.nan)).astype("Int64")
