"""Figures of the signals and of identification: spectra and spectrograms per operating
case, channel moments over time, and one block's stabilisation diagram."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from .view_style import (
    FIGURE_WIDTH,
    mode_colour,
    naive_utc,
    regular_columns,
    time_axis,
)


def plot_spectra_by_case(
    spectra: Mapping[str, tuple[np.ndarray, np.ndarray]],
    spectrogram: tuple[np.ndarray, np.ndarray, np.ndarray],
    case_ranges: Mapping[str, tuple[pd.Timestamp, pd.Timestamp]],
    *,
    band_hz: tuple[float, float] | None = None,
    mode_frequencies: Mapping[int, float] | None = None,
):
    """Singular values of the cross-spectral matrix per operating case, each beside the
    spectrogram (first singular value over time) of that case.

    Parameters
    ----------
    spectra : mapping case -> (frequency_hz, singular_values (n_freq, k))
        Mean spectral matrix of the case's data, its largest singular values.
        [(m/s²)²/Hz]
    spectrogram : (times, frequency_hz, first_singular_value (n_times, n_freq))
    case_ranges : mapping case -> (start, end)
        Time range shown in the case's spectrogram.
    mode_frequencies : mapping mode -> Hz, optional
        Marked on the spectra.
    """
    cases = list(spectra)
    fig, axes = plt.subplots(
        len(cases), 2, figsize=(FIGURE_WIDTH, 2.5 * len(cases) + 0.4),
        layout="constrained", squeeze=False, width_ratios=[1.0, 1.4],
    )  # fmt: skip
    times, sg_frequency, sg_values = spectrogram
    times = naive_utc(times)
    inside = np.ones_like(sg_frequency, dtype=bool)
    if band_hz is not None:
        inside = (sg_frequency >= band_hz[0]) & (sg_frequency <= band_hz[1])
    with np.errstate(divide="ignore"):
        decibel = 10 * np.log10(sg_values[:, inside])
    finite = decibel[np.isfinite(decibel)]
    low, high = np.percentile(finite, [5, 99.5]) if finite.size else (0.0, 1.0)
    for row, case in enumerate(cases):
        frequency, values = spectra[case]
        ax = axes[row, 0]
        keep = np.ones_like(frequency, dtype=bool)
        if band_hz is not None:
            keep = (frequency >= band_hz[0]) & (frequency <= band_hz[1])
        for j in range(values.shape[1]):
            ax.semilogy(frequency[keep], values[keep, j], lw=1.0 if j == 0 else 0.7,
                        color=("k", "0.45", "0.7")[min(j, 2)], label=f"SV{j + 1}")  # fmt: skip
        for mode, f in (mode_frequencies or {}).items():
            ax.axvline(f, color=mode_colour(mode), lw=0.7, ls=":")
        ax.set_title(f"{case}: singular values of the spectral matrix", fontsize=9)
        ax.set_ylabel("[(m/s²)²/Hz]", fontsize=8)
        ax.grid(True, alpha=0.3)
        if row == 0:
            ax.legend(fontsize=7, loc="upper right")
        if row == len(cases) - 1:
            ax.set_xlabel("frequency [Hz]")
        ax = axes[row, 1]
        start, end = case_ranges.get(case, (None, None))
        mask = np.ones(len(times), dtype=bool)
        if start is not None:
            mask = (times >= naive_utc([start])[0]) & (times < naive_utc([end])[0])
        if mask.sum() >= 1:
            columns, n_columns, start_num, step = regular_columns(times[mask])
            grid = np.full((int(inside.sum()), n_columns), np.nan)
            grid[:, columns] = decibel[mask].T
            shown_f = sg_frequency[inside]
            image = ax.imshow(
                grid, origin="lower", aspect="auto", interpolation="nearest",
                extent=(start_num - step / 2, start_num + (n_columns - 0.5) * step,
                        shown_f[0], shown_f[-1]),
                vmin=low, vmax=high, cmap="magma",
            )  # fmt: skip
            ax.xaxis_date()
            time_axis(ax)
            fig.colorbar(image, ax=ax, label="SV1 [dB]", pad=0.01)
        else:
            ax.text(0.5, 0.5, "no data in this case", ha="center", transform=ax.transAxes)
        ax.set_title(f"{case}: spectrogram (SV1)", fontsize=9)
        ax.set_ylabel("frequency [Hz]", fontsize=8)
    return fig


def plot_channel_moments(
    moments: pd.DataFrame,
    *,
    dropped: pd.DataFrame | None = None,
    statistics: Sequence[str] = ("rms", "skewness", "kurtosis"),
):
    """Statistical moments of every channel over time, as channel x time maps, with the
    (time, channel) cells where a channel was dropped marked.

    Parameters
    ----------
    moments : DataFrame
        ``time`` (UTC), ``channel`` and the *statistics* columns (RMS [m/s²], skewness and
        kurtosis [-], kurtosis not excess: 3 for Gaussian data).
    dropped : DataFrame, optional
        ``time`` and ``channel`` of dropped channel-blocks (e.g. ``faults.csv``).
    """
    statistics = [s for s in statistics if s in moments.columns]
    channels = list(pd.unique(moments["channel"]))
    times = sorted(pd.unique(pd.to_datetime(moments["time"], utc=True)))
    fig, axes = plt.subplots(
        len(statistics), 1, figsize=(FIGURE_WIDTH, 0.18 * len(channels) * len(statistics) + 1.5),
        sharex=True, layout="constrained", squeeze=False,
    )  # fmt: skip
    t = naive_utc(times)
    columns, n_columns, start_num, step_num = regular_columns(t)
    end_num = start_num + n_columns * step_num
    step = pd.Timedelta(days=step_num)
    position = {time: int(c) for time, c in zip(times, columns, strict=True)}
    for ax, statistic in zip(axes[:, 0], statistics, strict=True):
        grid = np.full((len(channels), n_columns), np.nan)
        table = moments.pivot_table(index="channel", columns="time", values=statistic)
        table.columns = pd.to_datetime(table.columns, utc=True)
        for i, channel in enumerate(channels):
            if channel in table.index:
                row = table.loc[channel]
                grid[i, [position[c] for c in row.index]] = row.to_numpy()
        if statistic == "rms":
            with np.errstate(divide="ignore", invalid="ignore"):
                shown, label, cmap = np.log10(grid), "log10 RMS [m/s²]", "viridis"
        elif statistic == "kurtosis":
            shown, label, cmap = grid, "kurtosis [-] (3 = Gaussian)", "PuOr_r"
        else:
            shown, label, cmap = grid, f"{statistic} [-]", "RdBu_r"
        finite = shown[np.isfinite(shown)]
        kwargs = {}
        if finite.size:
            if statistic == "kurtosis":
                spread = max(np.percentile(np.abs(finite - 3), 98), 0.5)
                kwargs = {"vmin": 3 - spread, "vmax": 3 + spread}
            elif statistic == "skewness":
                spread = max(np.percentile(np.abs(finite), 98), 0.2)
                kwargs = {"vmin": -spread, "vmax": spread}
            else:
                kwargs = {"vmin": np.percentile(finite, 1), "vmax": np.percentile(finite, 99)}
        # columns are equally spaced chunks or blocks (a gap shows as its neighbours)
        image = ax.imshow(
            shown, aspect="auto", interpolation="nearest", cmap=cmap,
            extent=(start_num, end_num, len(channels), 0), **kwargs,
        )  # fmt: skip
        ax.xaxis_date()
        fig.colorbar(image, ax=ax, label=label, pad=0.01)
        if dropped is not None and len(dropped):
            drop_t = naive_utc(dropped["time"])
            drop_c = [channels.index(c) + 0.5 for c in dropped["channel"] if c in channels]
            keep = dropped["channel"].isin(channels).to_numpy()
            ax.plot(drop_t[keep] + step / 2, drop_c, "x", color="red", ms=4, mew=1.2,
                    label="dropped")  # fmt: skip
            ax.legend(fontsize=7, loc="upper right")
        ax.set_yticks(np.arange(len(channels)) + 0.5, channels, fontsize=6)
        ax.set_ylim(len(channels), 0)
        ax.set_title(label, fontsize=9)
    time_axis(axes[-1, 0])
    axes[-1, 0].set_xlabel("time [UTC]")
    return fig


# --------------------------------------------------------------------------- identification
def plot_stabilisation_block(
    poles: pd.DataFrame,
    *,
    tracked: pd.DataFrame | None = None,
    singular_values: tuple[np.ndarray, np.ndarray] | None = None,
    band_hz: tuple[float, float] | None = None,
    title: str = "",
):
    """Stabilisation diagram of one block from its pole table, the block's tracked modes
    marked with their labels, and the singular values of its spectral matrix beneath on the
    same frequency axis.

    Parameters
    ----------
    poles : DataFrame
        POLES rows of one block.
    tracked : DataFrame, optional
        MODAL rows of the same block (``mode``, ``frequency_hz``).
    singular_values : (frequency_hz, values (n_freq, k)), optional
    """
    rows = 2 if singular_values is not None else 1
    fig, axes = plt.subplots(
        rows, 1, figsize=(FIGURE_WIDTH / 2 - 0.1, 3.2 + 1.6 * (rows - 1)), sharex=True,
        layout="constrained", squeeze=False, height_ratios=[2.0, 1.0][:rows],
    )  # fmt: skip
    ax = axes[0, 0]
    stable = poles["stable"].to_numpy(dtype=bool)
    ax.plot(poles["frequency_hz"][~stable], poles["model_order"][~stable], ".", ms=2.5,
            color="0.7", label="unstable pole")  # fmt: skip
    ax.plot(poles["frequency_hz"][stable], poles["model_order"][stable], "o", ms=3,
            color="tab:blue", label="stable pole")  # fmt: skip
    top = float(poles["model_order"].max()) if len(poles) else 1.0
    if tracked is not None:
        for mode, f in zip(tracked["mode"], tracked["frequency_hz"], strict=True):
            ax.axvline(f, color=mode_colour(mode), lw=1.0, ls="--")
            ax.text(f, top * 1.02, str(int(mode)), color=mode_colour(mode), fontsize=8,
                    ha="center", va="bottom")  # fmt: skip
    ax.set_ylim(0, top * 1.1)
    ax.set_ylabel("model order")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(True, alpha=0.3)
    if singular_values is not None:
        frequency, values = singular_values
        keep = np.ones_like(frequency, dtype=bool)
        if band_hz is not None:
            keep = (frequency >= band_hz[0]) & (frequency <= band_hz[1])
        for j in range(values.shape[1]):
            axes[1, 0].semilogy(frequency[keep], values[keep, j], lw=0.9 if j == 0 else 0.6,
                                color=("k", "0.45", "0.7")[min(j, 2)], label=f"SV{j + 1}")  # fmt: skip
        axes[1, 0].set_ylabel("[(m/s²)²/Hz]", fontsize=8)
        axes[1, 0].legend(fontsize=7, loc="upper right")
        axes[1, 0].grid(True, alpha=0.3)
    if band_hz is not None:
        ax.set_xlim(*band_hz)
    axes[-1, 0].set_xlabel("frequency [Hz]")
    return fig
