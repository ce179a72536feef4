"""Figures of the statistics and forecasts: the correlation heatmap per case, the
forecast of every mode with its bounds, and observed against predicted."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from .view_style import (
    FIGURE_WIDTH,
    mode_colour,
    naive_utc,
    time_axis,
)


def plot_correlation_heatmap(table: pd.DataFrame, *, alpha: float = 0.05):
    """Pearson r of every mode quantity with every predictor, one panel per case.

    Cells: r on a diverging scale; ``*`` significant with the effective sample size,
    ``°`` significant only when blocks are (wrongly) taken as independent. Cases flagged
    ``small`` are greyed out and say so.
    """
    part = table[table["y"].str.startswith("mode")]
    cases = list(pd.unique(part["case"]))
    predictors = list(pd.unique(part["x"]))
    quantities = list(pd.unique(part["y"]))
    n_cols = min(len(cases), 4)
    n_rows = int(np.ceil(len(cases) / n_cols))
    width = min(FIGURE_WIDTH, 1.2 + n_cols * (0.45 * len(predictors) + 1.3))
    fig, axes = plt.subplots(
        n_rows, n_cols, figsize=(width, n_rows * (0.2 * len(quantities) + 1.6)),
        layout="constrained", squeeze=False, sharey=True,
    )  # fmt: skip
    for k, case in enumerate(cases):
        ax = axes[k // n_cols, k % n_cols]
        rows = part[part["case"] == case].set_index(["y", "x"])
        grid = np.full((len(quantities), len(predictors)), np.nan)
        for i, y in enumerate(quantities):
            for j, x in enumerate(predictors):
                if (y, x) in rows.index:
                    grid[i, j] = rows.at[(y, x), "r"]
        small = bool(rows["small"].all()) if "small" in rows else False
        ax.imshow(grid, vmin=-1, vmax=1, cmap="RdBu_r", aspect="auto",
                  alpha=0.25 if small else 1.0)  # fmt: skip
        for i, y in enumerate(quantities):
            for j, x in enumerate(predictors):
                if (y, x) not in rows.index:
                    continue
                row = rows.loc[(y, x)]
                mark = ""
                if row.get("significant_effective", False):
                    mark = "*"
                elif row["p_value"] < alpha:
                    mark = "°"
                if mark and not small:
                    ax.text(j, i, mark, ha="center", va="center", fontsize=9)
        n_blocks = int(rows["n"].max()) if len(rows) else 0
        suffix = "\ntoo few blocks: not judged" if small else ""
        ax.set_title(f"{case} (n ≤ {n_blocks}){suffix}", fontsize=8,
                     color="0.5" if small else "black")  # fmt: skip
        ax.set_xticks(range(len(predictors)), predictors, rotation=40, ha="right", fontsize=7)
        ax.set_yticks(range(len(quantities)), [_short(q) for q in quantities], fontsize=7)
    for ax in axes.ravel()[len(cases) :]:
        ax.set_visible(False)
    scale = plt.cm.ScalarMappable(norm=plt.Normalize(-1, 1), cmap="RdBu_r")
    fig.colorbar(scale, ax=axes, label="Pearson r", shrink=0.6)
    return fig


def _short(name: str) -> str:
    """``mode3_frequency_hz`` -> ``f3 [Hz]``, ``mode3_damping_ratio`` -> ``ζ3``."""
    if name.startswith("mode") and "_" in name:
        mode, quantity = name[4:].split("_", 1)
        return f"f{mode}" if quantity == "frequency_hz" else f"ζ{mode}"
    return name


# --------------------------------------------------------------------------- forecast
def plot_forecast_overview(
    forecast: pd.DataFrame, *, option: str, truth: pd.DataFrame | None = None
):
    """Per mode against time: SSI estimates, the model's prediction with its 95 % band and
    the Kalman-blended estimate (forecast phase shaded), and the truth when known."""
    part = forecast[forecast["option"] == option]
    modes = sorted(part["mode"].unique())
    n_cols = 2
    n_rows = int(np.ceil(len(modes) / n_cols))
    fig, axes = plt.subplots(
        n_rows, n_cols, figsize=(FIGURE_WIDTH, 2.2 * n_rows + 0.4), layout="constrained",
        squeeze=False, sharex=True,
    )  # fmt: skip
    for k, mode in enumerate(modes):
        ax = axes[k // n_cols, k % n_cols]
        rows = part[part["mode"] == mode].sort_values("block")
        t = naive_utc(rows["block_start"])
        ax.fill_between(t, rows["model_lower_hz"], rows["model_upper_hz"], color="0.85",
                        label="model 95 % band", step="mid")  # fmt: skip
        ax.plot(t, rows["model_frequency_hz"], color="0.4", lw=0.8, label="model")
        ax.plot(t, rows["ssi_frequency_hz"], ".", color=mode_colour(mode), ms=4, label="SSI")
        ax.plot(t, rows["kalman_frequency_hz"], color="k", lw=1.0, label="Kalman")
        if truth is not None:
            true = truth[truth["mode"] == mode].sort_values("block")
            ax.plot(naive_utc(true["block_start"]), true["frequency_hz"], color="tab:green",
                    lw=0.8, ls="--", label="truth")  # fmt: skip
        ax.set_title(f"mode {mode}", fontsize=9, color=mode_colour(mode))
        ax.set_ylabel("frequency [Hz]", fontsize=8)
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7, ncols=5, loc="lower left", bbox_to_anchor=(0, 1.12))
        time_axis(ax)
    for ax in axes.ravel()[len(modes) :]:
        ax.set_visible(False)
    return fig


def plot_observed_vs_predicted(forecast: pd.DataFrame, *, phase: str | None = "forecast"):
    """SSI-observed frequency against the model's prediction, per option, coloured by
    mode, with the 1:1 line; the panel titles give the RMS difference."""
    part = forecast if phase is None else forecast[forecast["phase"] == phase]
    part = part.dropna(subset=["ssi_frequency_hz", "model_frequency_hz"])
    options = sorted(part["option"].unique()) or ["A"]
    fig, axes = plt.subplots(
        1, len(options), figsize=(min(FIGURE_WIDTH, 4.6 * len(options) + 0.6), 4.4),
        layout="constrained", squeeze=False,
    )  # fmt: skip
    for ax, option in zip(axes[0], options, strict=True):
        rows = part[part["option"] == option]
        for mode, group in rows.groupby("mode"):
            ax.plot(group["model_frequency_hz"], group["ssi_frequency_hz"], "o", ms=3,
                    color=mode_colour(mode), label=f"mode {mode}")  # fmt: skip
        if len(rows):
            low = float(min(rows["ssi_frequency_hz"].min(), rows["model_frequency_hz"].min()))
            high = float(max(rows["ssi_frequency_hz"].max(), rows["model_frequency_hz"].max()))
            ax.plot([low, high], [low, high], color="k", lw=0.7)
            rms = float(
                np.sqrt(np.mean((rows["ssi_frequency_hz"] - rows["model_frequency_hz"]) ** 2))
            )
            ax.set_title(f"option {option}: RMS(observed - predicted) = {1000 * rms:.1f} mHz",
                         fontsize=9)  # fmt: skip
        ax.set_xlabel("predicted (model) [Hz]")
        ax.set_ylabel("observed (SSI) [Hz]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, ncols=2)
    return fig
