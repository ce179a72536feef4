"""Figures of the sliding forecast: one PNG per mode (matplotlib, Agg backend)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from ..results import save_figure

__all__ = ["plot_forecast_mode", "write_forecast_figures"]


def plot_forecast_mode(
    forecast_table: pd.DataFrame,
    mode: int,
    *,
    truth_modal: pd.DataFrame | None = None,
    option: str | None = None,
    ax=None,
):
    """Draw one mode's forecast: training data, model, 95 % bounds, SSI and Kalman estimates.

    Parameters
    ----------
    forecast_table : DataFrame
        FORECAST table (:func:`~workbench.forecasting.sliding_forecast`).
    mode : int
        Mode label.
    truth_modal : DataFrame, optional
        True frequencies (block, mode, frequency_hz), drawn as a thin black line.
    option : {"A", "B"}, optional
        Option to draw when the table holds both; default the first present.
    ax : matplotlib Axes, optional
        Axes to draw into; default a new figure.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (close it with ``plt.close(fig)``).
    """
    rows = forecast_table[forecast_table["mode"] == mode]
    if rows.empty:
        raise ValueError(f"mode={mode} has no rows in the forecast table")
    if "option" in rows.columns:
        option = option if option is not None else str(rows["option"].iloc[0])
        rows = rows[rows["option"] == option]
    rows = rows.sort_values("block")
    time = pd.to_datetime(rows["block_start"], utc=True).dt.tz_localize(None)
    train = (rows["phase"] == "train").to_numpy()
    fore = ~train
    if ax is None:
        fig, ax = plt.subplots(figsize=(10, 4.5), layout="constrained")
    else:
        fig = ax.figure
    ssi = rows["ssi_frequency_hz"].to_numpy(dtype=float)
    model = rows["model_frequency_hz"].to_numpy(dtype=float)
    lower = rows["model_lower_hz"].to_numpy(dtype=float)
    upper = rows["model_upper_hz"].to_numpy(dtype=float)
    kalman = rows["kalman_frequency_hz"].to_numpy(dtype=float)
    kalman_std = rows["kalman_std_hz"].to_numpy(dtype=float)
    t = time.to_numpy()
    ax.plot(t[train], ssi[train], "o", ms=3.5, color="0.45", label="SSI (training)")
    ax.plot(t[train], model[train], "-", color="tab:blue", lw=1.2, label="model (training fit)")
    ax.fill_between(
        t[fore],
        lower[fore],
        upper[fore],
        color="tab:orange",
        alpha=0.2,
        lw=0,
        label="95 % prediction bounds",
    )
    ax.plot(t[fore], model[fore], "-", color="tab:orange", lw=1.2, label="model forecast")
    ax.plot(t[fore], ssi[fore], ".", ms=4, color="tab:red", label="SSI estimates")
    ax.plot(t, kalman, "-", color="tab:green", lw=1.5, label="Kalman estimate")
    ax.fill_between(
        t, kalman - 2 * kalman_std, kalman + 2 * kalman_std, color="tab:green", alpha=0.12, lw=0
    )
    if truth_modal is not None:
        truth = truth_modal[truth_modal["mode"] == mode][["block", "frequency_hz"]]
        merged = rows[["block", "block_start"]].merge(truth, on="block", how="inner")
        if not merged.empty:
            ax.plot(
                pd.to_datetime(merged["block_start"], utc=True).dt.tz_localize(None),
                merged["frequency_hz"],
                "-",
                color="black",
                lw=0.8,
                label="truth",
            )
    if fore.any() and train.any():
        ax.axvline(t[fore][0], color="0.6", ls="--", lw=0.8)
    title = f"Mode {mode}: sliding forecast" + (f", option {option}" if option else "")
    ax.set_title(title)
    ax.set_xlabel("time (UTC)")
    ax.set_ylabel("frequency [Hz]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, ncols=2, loc="best")
    with np.errstate(invalid="ignore"):
        fig.autofmt_xdate()
    return fig


def write_forecast_figures(
    forecast_table: pd.DataFrame,
    out_dir: str | os.PathLike,
    *,
    truth_modal: pd.DataFrame | None = None,
    modes: Sequence[int] | None = None,
    prefix: str = "forecast_mode",
    dpi: int = 110,
) -> list[Path]:
    """Write one PNG per mode (``<prefix><mode>[_<option>].png``) into *out_dir*.

    Returns
    -------
    list of Path
        The files written, in mode order.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    modes = sorted(int(m) for m in forecast_table["mode"].unique()) if modes is None else modes
    options = (
        sorted(str(o) for o in forecast_table["option"].unique())
        if "option" in forecast_table.columns
        else [None]
    )
    paths = []
    for mode in modes:
        for option in options:
            suffix = f"_{option}" if option is not None and len(options) > 1 else ""
            path = out / f"{prefix}{mode}{suffix}.png"
            fig = plot_forecast_mode(forecast_table, mode, truth_modal=truth_modal, option=option)
            paths.append(save_figure(fig, path, dpi=dpi))
    return paths
