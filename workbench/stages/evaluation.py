"""Evaluate stage: SSI-only, model-only and Kalman estimates against the true frequencies."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from data_contracts import FORECAST, MODAL

from ..errors import WorkbenchError
from ..forecasting import evaluate_against_truth
from ..results import StageResult, read_any_table, shown_once, table_path, write_frame
from ..sid.tracking import label_agreement

__all__ = ["EvaluateResult", "evaluate", "pair_with_truth", "relabel_truth"]


def pair_with_truth(
    forecast: pd.DataFrame, truth: pd.DataFrame
) -> tuple[pd.DataFrame, float, dict[int, int]]:
    """The forecast's rows of modes paired with a true mode, under the true labels.

    The forecast's mode labels come from tracking; they are paired with the true modes by
    :func:`workbench.sid.tracking.label_agreement` on the SSI estimates, so that extra
    tracked modes (e.g. a shaft harmonic) or a different numbering do not matter.

    Returns
    -------
    relabelled : DataFrame
        Rows of the paired modes, ``mode`` the true label.
    agreement : float
        Share of measured rows whose label agrees with the pairing.
    mapping : dict of int -> int
        Tracked label -> true label.
    """
    measured = forecast.dropna(subset=["ssi_frequency_hz"])
    pseudo = (
        measured[["block", "mode", "ssi_frequency_hz"]]
        .rename(columns={"ssi_frequency_hz": "frequency_hz"})
        .drop_duplicates(["block", "mode"])
    )
    agreement, mapping = label_agreement(pseudo, truth)
    if not mapping:
        raise WorkbenchError("no forecast mode could be paired with a true mode")
    relabelled = forecast[forecast["mode"].isin(mapping)].copy()
    relabelled["mode"] = relabelled["mode"].map(mapping).astype("int64")
    return relabelled, agreement, mapping


def relabel_truth(truth: pd.DataFrame, mapping: dict[int, int]) -> pd.DataFrame:
    """The truth table under the tracked labels of *mapping* (tracked -> true label), e.g.
    for drawing it beside a forecast."""
    inverse = {true: label for label, true in mapping.items()}
    part = truth[truth["mode"].isin(inverse)].copy()
    part["mode"] = part["mode"].map(inverse).astype("int64")
    return part


#: Columns the CLI prints.
SUMMARY_COLUMNS = [
    "option",
    "mode",
    "n_ssi",
    "ssi_cumulative_error_hz",
    "model_cumulative_error_hz",
    "kalman_cumulative_error_hz",
    "improvement_vs_ssi_pct",
    "improvement_vs_tracked_pct",
]


@dataclass
class EvaluateResult(StageResult):
    """Cumulative absolute errors per option and mode against the truth.

    Attributes
    ----------
    table : DataFrame
        One row per option and mode (:func:`~workbench.forecasting.evaluate_against_truth`).
    mapping : dict of int -> int
        Tracked label -> true label.
    agreement : float
        Share of measured rows whose label agrees with the pairing.
    """

    table: pd.DataFrame
    mapping: dict[int, int]
    agreement: float
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    title = "forecast against the truth"

    def plot(self, ax=None):
        """Cumulative absolute error of SSI, model and Kalman per mode and option."""
        import matplotlib.pyplot as plt

        drawn_here = ax is None
        if ax is None:
            _, ax = plt.subplots(figsize=(9, 4), layout="constrained")
        table = self.table.sort_values(["option", "mode"])
        labels = [f"{o}{m}" for o, m in zip(table["option"], table["mode"], strict=True)]
        x = np.arange(len(table))
        for k, (column, name) in enumerate(
            (
                ("ssi_cumulative_error_hz", "SSI"),
                ("model_cumulative_error_hz", "model"),
                ("kalman_cumulative_error_hz", "Kalman"),
            )
        ):
            ax.bar(x + (k - 1) * 0.27, table[column], width=0.27, label=name)
        ax.set_xticks(x, labels)
        ax.set_xlabel("option and true mode")
        ax.set_ylabel("cumulative |error| [Hz]")
        ax.legend(fontsize=8)
        return shown_once(ax.figure) if drawn_here else ax.figure

    def save(self, out: str | os.PathLike) -> dict[str, Path]:
        """The table (``out`` a .csv/.parquet file, or a folder: evaluation.csv)."""
        return {"evaluation": write_frame(self.table, table_path(out, "evaluation.csv"))}


def evaluate(
    forecast: pd.DataFrame | str | os.PathLike,
    truth: pd.DataFrame | str | os.PathLike,
    *,
    phase: str | None = "forecast",
) -> EvaluateResult:
    """Compare SSI-only, model-only and Kalman estimates with the true frequencies.

    Parameters
    ----------
    forecast : DataFrame
        Forecast table (FORECAST contract).
    truth : DataFrame
        True modal table (MODAL contract), e.g. of a simulated voyage.
    phase : {"forecast", "train", None}
        Rows compared: forecast blocks, training blocks, or all (None).
    """
    forecast = read_any_table(forecast, FORECAST, name="forecast")
    truth = read_any_table(truth, MODAL, name="truth")
    if phase is not None and "phase" in forecast.columns and not (forecast["phase"] == phase).any():
        found = ", ".join(map(str, pd.unique(forecast["phase"].dropna()))) or "none"
        raise ValueError(
            f"the forecast table has no {phase!r} rows to evaluate (phases in it: {found}); "
            "evaluate another phase or forecast further"
        )
    relabelled, agreement, mapping = pair_with_truth(forecast, truth)
    table = evaluate_against_truth(relabelled, truth, phase=phase)
    if table.empty:
        raise ValueError(
            f"no {'' if phase is None else phase + ' '}row of the forecast has a true "
            "frequency of its mode: nothing to evaluate"
        )
    result = EvaluateResult(table=table, mapping=mapping, agreement=agreement)
    for row in table[table["n_ssi"] == 0].itertuples(index=False):
        result.warnings.append(
            f"option {row.option}, mode {row.mode}: no SSI estimate in the "
            f"{'evaluated' if phase is None else phase} rows ({row.n_blocks} with a true "
            "frequency): its errors are not reported (NaN)"
        )
    for option, part in table.groupby("option"):
        total = part[
            ["ssi_cumulative_error_hz", "model_cumulative_error_hz", "kalman_cumulative_error_hz"]
        ].sum()
        ssi_error = float(total["ssi_cumulative_error_hz"])
        verdict = (
            f"{100.0 * (1.0 - total['kalman_cumulative_error_hz'] / ssi_error):+.1f} % vs SSI"
            if ssi_error > 0
            else "no gain vs SSI defined (SSI error is zero)"
        )
        tracked_error = float(part["tracked_cumulative_error_hz"].sum(min_count=1))
        versus_tracked = ""
        if option != "A" and np.isfinite(tracked_error) and tracked_error > 0:
            # option B's SSI column is its own chosen pole: also against the tracked pole
            gain = 100.0 * (
                1.0 - float(part["kalman_cumulative_error_tracked_hz"].sum()) / tracked_error
            )
            versus_tracked = f", {gain:+.1f} % vs the tracked pole (option A's SSI)"
            if gain < 0:
                result.warnings.append(
                    f"option {option}: the Kalman estimate is {-gain:.1f} % worse than the "
                    "tracked pole (option A's SSI estimate); use option A"
                )
        result.lines.append(
            f"option {option}: cumulative |error| SSI {ssi_error:.3f} Hz,"
            f" model {total['model_cumulative_error_hz']:.3f} Hz, Kalman "
            f"{total['kalman_cumulative_error_hz']:.3f} Hz -> Kalman {verdict}{versus_tracked}"
        )
        if ssi_error == 0 and part["n_ssi"].sum() > 0:
            result.warnings.append(
                f"option {option}: the truth equals the SSI estimates on every measured block "
                "(an observed table, not an independent reference): errors measure the model "
                "and the Kalman filter against the measurements, and gains vs SSI are undefined"
            )
    result.lines.append(
        f"tracked labels paired with true modes {mapping} ({100 * agreement:.1f} % of "
        "measured rows agree)"
    )
    return result
