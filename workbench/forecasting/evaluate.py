"""Evaluation of SSI-only, model-only and Kalman frequency estimates against ground truth."""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["evaluate_against_truth"]

_ESTIMATES = {
    "ssi": "ssi_frequency_hz",
    "model": "model_frequency_hz",
    "kalman": "kalman_frequency_hz",
}


def evaluate_against_truth(
    forecast_table: pd.DataFrame,
    truth_modal: pd.DataFrame,
    *,
    phase: str | None = "forecast",
) -> pd.DataFrame:
    """Cumulative absolute errors of the three estimates per mode, and the improvements.

    Parameters
    ----------
    forecast_table : DataFrame
        FORECAST table (:func:`~workbench.forecasting.sliding_forecast`).
    truth_modal : DataFrame
        True modal parameters: block, mode, frequency_hz (MODAL contract or a subset).
    phase : {"forecast", "train"} or None
        Rows evaluated; ``None`` for all.

    Returns
    -------
    DataFrame
        One row per option and mode: ``n_blocks`` (rows with a truth value), ``n_ssi``
        (of those, with an SSI estimate); cumulative absolute errors [Hz] over the blocks
        with an SSI estimate, ``ssi_cumulative_error_hz``, ``model_cumulative_error_hz``,
        ``kalman_cumulative_error_hz`` (NaN when ``n_ssi`` is 0: nothing to compare on);
        over all blocks, ``model_cumulative_error_all_hz``
        and ``kalman_cumulative_error_all_hz``; ``improvement_vs_ssi_pct`` and
        ``improvement_vs_model_pct``. When the table holds option A's rows (``--option
        both``), against the tracked pole (A's SSI estimate, the raw SSI every option must
        beat) over the blocks that have one: ``tracked_cumulative_error_hz``,
        ``kalman_cumulative_error_tracked_hz`` and ``improvement_vs_tracked_pct`` (NaN
        without option A's rows). For option B the SSI columns above are its own chosen
        pole, so only these show a B that is worse than the tracked pole.

    Notes
    -----
    The cumulative absolute error of estimate e over the blocks B is
    E = Σ_{k∈B} |e_k - f_k| with f the true frequency. The improvement of the Kalman
    estimates over the SSI estimates is 100 (1 - E_kalman / E_ssi) %, over the model
    100 (1 - E_kalman / E_model) %; both use the blocks with an SSI estimate, so that the
    three estimates are compared on the same blocks.
    """
    for name, frame, needed in (
        ("forecast_table", forecast_table, ("block", "mode", *_ESTIMATES.values())),
        ("truth_modal", truth_modal, ("block", "mode", "frequency_hz")),
    ):
        missing = [c for c in needed if c not in frame.columns]
        if missing:
            raise ValueError(f"{name} lacks column(s) {missing}")
    table = forecast_table
    if phase is not None:
        if "phase" not in table.columns:
            raise ValueError("forecast_table lacks column 'phase'")
        table = table[table["phase"] == phase]
    truth = truth_modal[["block", "mode", "frequency_hz"]].rename(
        columns={"frequency_hz": "truth_hz"}
    )
    merged = table.merge(truth, on=["block", "mode"], how="inner", validate="many_to_one")
    if "option" not in merged.columns:
        merged = merged.assign(option="A")
    tracked = (
        merged.loc[merged["option"] == "A", ["block", "mode", "ssi_frequency_hz"]]
        .rename(columns={"ssi_frequency_hz": "tracked_hz"})
        .drop_duplicates(["block", "mode"])
    )
    if not tracked.empty:
        merged = merged.merge(tracked, on=["block", "mode"], how="left")
    rows = []
    for (option, mode), group in merged.groupby(["option", "mode"], sort=True):
        truth_hz = group["truth_hz"].to_numpy(dtype=float)
        tracked_error = kalman_tracked_error = vs_tracked = np.nan
        if not tracked.empty:
            on_tracked = np.abs(group["tracked_hz"].to_numpy(dtype=float) - truth_hz)
            kalman_error = np.abs(group["kalman_frequency_hz"].to_numpy(dtype=float) - truth_hz)
            rows_tracked = np.isfinite(on_tracked)
            if rows_tracked.any():
                tracked_error = float(on_tracked[rows_tracked].sum())
                kalman_tracked_error = float(np.nansum(kalman_error[rows_tracked]))
                vs_tracked = _improvement(kalman_tracked_error, tracked_error)
        error = {
            key: np.abs(group[column].to_numpy(dtype=float) - truth_hz)
            for key, column in _ESTIMATES.items()
        }
        common = np.isfinite(error["ssi"]) & np.isfinite(truth_hz)
        # no SSI estimate in these rows: no data to compare on (NaN), not an error of 0 Hz
        cumulative = {
            key: float(value[common].sum()) if common.any() else float("nan")
            for key, value in error.items()
        }
        # no SSI estimate in the evaluated rows (or zero error): no improvement to state
        vs_ssi = _improvement(cumulative["kalman"], cumulative["ssi"])
        vs_model = _improvement(cumulative["kalman"], cumulative["model"])
        rows.append(
            {
                "option": option,
                "mode": int(mode),
                "n_blocks": int(np.isfinite(truth_hz).sum()),
                "n_ssi": int(common.sum()),
                "ssi_cumulative_error_hz": cumulative["ssi"],
                "model_cumulative_error_hz": cumulative["model"],
                "kalman_cumulative_error_hz": cumulative["kalman"],
                "model_cumulative_error_all_hz": float(np.nansum(error["model"])),
                "kalman_cumulative_error_all_hz": float(np.nansum(error["kalman"])),
                "improvement_vs_ssi_pct": vs_ssi if common.any() else np.nan,
                "improvement_vs_model_pct": vs_model if common.any() else np.nan,
                "tracked_cumulative_error_hz": tracked_error,
                "kalman_cumulative_error_tracked_hz": kalman_tracked_error,
                "improvement_vs_tracked_pct": vs_tracked,
            }
        )
    columns = [
        "option",
        "mode",
        "n_blocks",
        "n_ssi",
        "ssi_cumulative_error_hz",
        "model_cumulative_error_hz",
        "kalman_cumulative_error_hz",
        "model_cumulative_error_all_hz",
        "kalman_cumulative_error_all_hz",
        "improvement_vs_ssi_pct",
        "improvement_vs_model_pct",
        "tracked_cumulative_error_hz",
        "kalman_cumulative_error_tracked_hz",
        "improvement_vs_tracked_pct",
    ]
    return pd.DataFrame(rows, columns=columns)


def _improvement(error: float, baseline: float) -> float:
    """100 (1 - error / baseline) %, NaN when the baseline error is zero or undefined."""
    if not (np.isfinite(baseline) and baseline > 0):
        return float("nan")
    return 100.0 * (1.0 - error / baseline)
