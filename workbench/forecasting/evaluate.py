"""A forecast against the true frequencies: cumulative absolute errors of the SSI-only,
model-only and Kalman estimates (:func:`evaluate_against_truth`), the pairing of tracked
mode labels with the true ones, and the evaluate stage's result (:class:`EvaluateResult`,
also :meth:`ForecastResult.evaluate <workbench.forecasting.results.ForecastResult.evaluate>`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import WorkbenchError
from ..results import StageResult, shown_once, table_path, write_frame
from ..sid.tracking import label_agreement

__all__ = [
    "EvaluateResult",
    "evaluate_against_truth",
    "evaluate_forecast",
    "pair_with_truth",
    "relabel_truth",
]

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
    rows = [
        {"option": option, "mode": int(mode), **_mode_errors(group, with_tracked=not tracked.empty)}
        for (option, mode), group in merged.groupby(["option", "mode"], sort=True)
    ]
    return pd.DataFrame(rows, columns=_COLUMNS)


#: Columns of :func:`evaluate_against_truth`, in order.
_COLUMNS = [
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


def _mode_errors(group: pd.DataFrame, *, with_tracked: bool) -> dict[str, float | int]:
    """The errors of one option and mode (:func:`evaluate_against_truth`'s row after the
    option and mode); *with_tracked*: *group* has the tracked pole's ``tracked_hz``."""
    truth_hz = group["truth_hz"].to_numpy(dtype=float)
    tracked_error = kalman_tracked_error = vs_tracked = np.nan
    if with_tracked:
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
    return {
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


def _improvement(error: float, baseline: float) -> float:
    """100 (1 - error / baseline) %, NaN when the baseline error is zero or undefined."""
    if not (np.isfinite(baseline) and baseline > 0):
        return float("nan")
    return 100.0 * (1.0 - error / baseline)


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


def evaluate_forecast(
    forecast: pd.DataFrame, truth: pd.DataFrame, *, phase: str | None = "forecast"
) -> EvaluateResult:
    """Compare a forecast's SSI-only, model-only and Kalman estimates with the true
    frequencies: the evaluate stage (:func:`workbench.stages.evaluate`, which reads the
    tables) and :meth:`ForecastResult.evaluate
    <workbench.forecasting.results.ForecastResult.evaluate>`.

    Parameters
    ----------
    forecast : DataFrame
        Forecast table (FORECAST contract).
    truth : DataFrame
        True modal table (MODAL contract), e.g. of a simulated voyage.
    phase : {"forecast", "train", None}
        Rows compared: forecast blocks, training blocks, or all (None).
    """
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
