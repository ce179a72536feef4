"""The figures of a run report: what structural engineers look at first.

Every function takes contract tables (or arrays) and returns a matplotlib figure; nothing
here reads files or knows the report layout (:mod:`workbench.reporting.report` does).
Damping ratios are drawn in percent and labelled so; mode colours follow the tracked mode
label (:func:`mode_colour`), the same in every figure.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.dates as mdates
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from data_contracts import geometry_directions, shapes_from_frame
from workbench.sid.assurance import mac

__all__ = [
    "mean_mode_shapes",
    "mode_colour",
    "plot_automac",
    "plot_channel_moments",
    "plot_correlation_heatmap",
    "plot_forecast_overview",
    "plot_mode_shapes",
    "plot_observed_vs_predicted",
    "plot_spectra_by_case",
    "plot_stabilisation_block",
    "plot_tracked_modes",
]

#: Width of report figures: 12 in at 100 dpi fits a 1400 px page with margins. [inch]
FIGURE_WIDTH = 12.0
_PALETTE = plt.get_cmap("tab10").colors + plt.get_cmap("Dark2").colors


def mode_colour(mode: int):
    """The colour of tracked mode *mode* in every report figure."""
    return _PALETTE[(int(mode) - 1) % len(_PALETTE)]


def _time_axis(ax) -> None:
    locator = mdates.AutoDateLocator(minticks=4, maxticks=10)
    ax.xaxis.set_major_locator(locator)
    ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))


def _naive_utc(times) -> pd.DatetimeIndex:
    """Times as naive UTC for matplotlib (labels say UTC)."""
    index = pd.DatetimeIndex(pd.to_datetime(times, utc=True))
    return index.tz_convert("UTC").tz_localize(None)


def _regular_columns(times: pd.DatetimeIndex) -> tuple[np.ndarray, int, float, float]:
    """Columns of *times* (naive UTC) on a regular grid of their median step, so that gaps
    stay gaps in an image: column index per time, number of columns, and the grid's start
    and step in matplotlib date units."""
    numbers = mdates.date2num(times.to_numpy())
    step = float(np.median(np.diff(numbers))) if len(numbers) > 1 else 1.0 / 1440
    step = step if step > 0 else 1.0 / 1440
    index = np.rint((numbers - numbers[0]) / step).astype(int)
    return index, int(index.max()) + 1, float(numbers[0]), step


def _block_times(frame: pd.DataFrame) -> pd.DatetimeIndex:
    """Block mid-times (start + half the length when ``block_end`` is known)."""
    start = pd.to_datetime(frame["block_start"], utc=True)
    if "block_end" in frame.columns:
        end = pd.to_datetime(frame["block_end"], utc=True)
        start = start + (end - start) / 2
    return _naive_utc(start)


# --------------------------------------------------------------------------- tracked modes
def plot_tracked_modes(
    modal: pd.DataFrame,
    predictors: pd.DataFrame | None = None,
    *,
    modes: Sequence[int] | None = None,
):
    """Frequency and damping of every tracked mode against time, the ship's speed and
    temperatures beneath on the same time axis.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract).
    predictors : DataFrame, optional
        Block predictors (PREDICTORS contract): ``speed_kn``, ``water_temp_c``,
        ``air_temp_c`` drawn when present.
    modes : sequence of int, optional
        Modes drawn (default all).
    """
    modes = sorted(modal["mode"].unique()) if modes is None else list(modes)
    has_predictors = predictors is not None and len(predictors) > 0
    rows = 3 if has_predictors else 2
    fig, axes = plt.subplots(
        rows,
        1,
        figsize=(FIGURE_WIDTH, 2.6 * rows + 0.6),
        sharex=True,
        layout="constrained",
        height_ratios=[1.6, 1.0, 0.9][:rows],
    )
    for mode in modes:
        part = modal[modal["mode"] == mode].sort_values("block")
        times = _block_times(part)
        style = dict(ms=2.5, lw=0.8, color=mode_colour(mode), marker="o")
        axes[0].plot(times, part["frequency_hz"], label=f"mode {mode}", **style)
        axes[1].plot(times, 100 * part["damping_ratio"], **style)
    axes[0].set_ylabel("frequency [Hz]")
    axes[1].set_ylabel("damping ratio [%]")
    axes[0].legend(fontsize=8, ncols=min(len(modes), 8), loc="lower left", bbox_to_anchor=(0, 1))
    if has_predictors:
        ax = axes[2]
        times = _block_times(predictors)
        if "speed_kn" in predictors:
            ax.plot(times, predictors["speed_kn"], color="k", lw=1.2, label="speed [kn]")
        ax.set_ylabel("speed [kn]")
        twin = ax.twinx()
        for column, colour, label in (
            ("water_temp_c", "tab:blue", "water temperature [°C]"),
            ("air_temp_c", "tab:red", "air temperature [°C]"),
        ):
            if column in predictors:
                twin.plot(times, predictors[column], color=colour, lw=1.0, label=label)
        twin.set_ylabel("temperature [°C]")
        handles = ax.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
        ax.legend(handles=handles, fontsize=8, ncols=3, loc="upper left")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    _time_axis(axes[-1])
    axes[-1].set_xlabel("block centre [UTC]")
    return fig


def mean_mode_shapes(modal: pd.DataFrame) -> tuple[list[int], list[str], np.ndarray]:
    """One representative shape per tracked mode: the mean of its block shapes after
    aligning each to the first (phase of the inner product), normalised to unit norm.

    Returns the modes, the channels and the complex shapes, shape (n_channels, n_modes);
    a channel missing in every block of a mode is NaN there.
    """
    channels, shapes = shapes_from_frame(modal)
    modes = sorted(int(m) for m in modal["mode"].unique())
    out = np.full((len(channels), len(modes)), np.nan, dtype=complex)
    labels = modal["mode"].to_numpy()
    for k, mode in enumerate(modes):
        block_shapes = shapes[labels == mode]
        finite = np.isfinite(block_shapes)
        reference = np.nan_to_num(block_shapes[np.argmax(finite.sum(axis=1))])
        filled = np.where(finite, block_shapes, 0.0)
        phase = filled @ reference.conj()
        aligned = filled * np.exp(-1j * np.angle(phase))[:, None]
        count = finite.sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(count > 0, aligned.sum(axis=0) / count, np.nan)
        norm = np.sqrt(np.nansum(np.abs(mean) ** 2))
        out[:, k] = mean / norm if norm > 0 else mean
    return modes, channels, out


def plot_automac(modal: pd.DataFrame):
    """AutoMAC of the tracked modes' mean shapes (channels seen in every mode)."""
    modes, channels, shapes = mean_mode_shapes(modal)
    common = np.isfinite(shapes).all(axis=1)
    matrix = mac(shapes[common], shapes[common]) if common.any() else np.full((1, 1), np.nan)
    size = min(7.0, 1.2 + 0.55 * len(modes))
    fig, ax = plt.subplots(figsize=(size + 1.2, size), layout="constrained")
    image = ax.imshow(matrix, vmin=0, vmax=1, cmap="Blues")
    for i in range(len(modes)):
        for j in range(len(modes)):
            value = matrix[i, j]
            ax.text(
                j, i, f"{value:.2f}", ha="center", va="center", fontsize=8,
                color="white" if value > 0.6 else "black",
            )  # fmt: skip
    labels = [str(m) for m in modes]
    ax.set_xticks(range(len(modes)), labels)
    ax.set_yticks(range(len(modes)), labels)
    ax.set_xlabel("mode")
    ax.set_ylabel("mode")
    ax.set_title(f"AutoMAC of the tracked modes ({int(common.sum())} channels)")
    fig.colorbar(image, ax=ax, label="MAC [-]", shrink=0.8)
    return fig


def _real_shape(shape: np.ndarray) -> np.ndarray:
    """Rotate a complex shape to its best real approximation (largest real part)."""
    finite = np.isfinite(shape)
    values = np.where(finite, shape, 0.0)
    angle = 0.5 * np.angle(np.sum(values**2))
    real = np.real(values * np.exp(-1j * angle))
    if real[np.argmax(np.abs(real))] < 0:
        real = -real
    return np.where(finite, real, np.nan)


def plot_mode_shapes(
    modal: pd.DataFrame,
    geometry: pd.DataFrame,
    *,
    frequencies: Mapping[int, float] | None = None,
    max_modes: int = 12,
):
    """Mode shapes drawn on the sensor layout: side view (x-z) and plan view (x-y).

    Each channel's shape component (mean shape, rotated to real) is drawn as an arrow from
    its node along its measuring direction, scaled so that the largest is 12 % of the
    layout's extent; grey dots are the nodes, hollow circles channels without a value.
    The axes are not to scale (a hull's length would flatten the side view).

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table with shape columns.
    geometry : DataFrame
        SENSOR_GEOMETRY table.
    frequencies : mapping of int -> float, optional
        Frequency per mode for the panel titles. [Hz]
    """
    modes, channels, shapes = mean_mode_shapes(modal)
    modes, shapes = modes[:max_modes], shapes[:, :max_modes]
    place = geometry.set_index("channel")
    known = [c for c in channels if c in place.index]
    rows_of = [channels.index(c) for c in known]
    xyz = place.loc[known, ["x_m", "y_m", "z_m"]].to_numpy(dtype=float)
    direction = geometry_directions(place.loc[known].reset_index())
    extent = float(np.max(np.ptp(xyz, axis=0))) if len(xyz) else 1.0
    extent = extent if extent > 0 else 1.0
    views = (("side view", 0, 2, "x [m]", "z [m]"), ("plan view", 0, 1, "x [m]", "y [m]"))
    per_row = 2
    n_rows = int(np.ceil(len(modes) / per_row))
    fig, axes = plt.subplots(
        n_rows, 2 * per_row, figsize=(FIGURE_WIDTH, 2.4 * n_rows + 0.3),
        layout="constrained", squeeze=False,
    )  # fmt: skip
    for k, mode in enumerate(modes):
        real = _real_shape(shapes[rows_of, k])
        scale = 0.12 * extent / np.nanmax(np.abs(real)) if np.any(np.isfinite(real)) else 0.0
        for v, (name, a, b, xlabel, ylabel) in enumerate(views):
            ax = axes[k // per_row, 2 * (k % per_row) + v]
            ax.plot(xyz[:, a], xyz[:, b], "o", color="0.6", ms=3, zorder=1)
            missing = ~np.isfinite(real)
            ax.plot(xyz[missing, a], xyz[missing, b], "o", mfc="none", mec="tab:red", ms=7)
            value = np.nan_to_num(real) * scale
            ax.quiver(
                xyz[:, a], xyz[:, b], value * direction[:, a], value * direction[:, b],
                angles="xy", scale_units="xy", scale=1.0, color=mode_colour(mode), width=0.006,
            )  # fmt: skip
            # limits cover nodes and arrow tips (quiver does not extend the data limits);
            # no equal aspect: a hull is 8-10 times longer than deep
            for values, set_limits in (
                (np.r_[xyz[:, a], xyz[:, a] + value * direction[:, a]], ax.set_xlim),
                (np.r_[xyz[:, b], xyz[:, b] + value * direction[:, b]], ax.set_ylim),
            ):
                low, high = float(np.min(values)), float(np.max(values))
                pad = 0.08 * (high - low) if high > low else 0.1 * extent
                set_limits(low - pad, high + pad)
            ax.tick_params(labelsize=7)
            ax.set_xlabel(xlabel, fontsize=8)
            ax.set_ylabel(ylabel, fontsize=8)
            freq = f", {frequencies[mode]:.3f} Hz" if frequencies and mode in frequencies else ""
            ax.set_title(f"mode {mode}{freq}: {name}", fontsize=9, color=mode_colour(mode))
    for ax in axes.ravel()[2 * len(modes) :]:
        ax.set_visible(False)
    return fig


# --------------------------------------------------------------------------- signals
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
    times = _naive_utc(times)
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
            mask = (times >= _naive_utc([start])[0]) & (times < _naive_utc([end])[0])
        if mask.sum() >= 1:
            columns, n_columns, start_num, step = _regular_columns(times[mask])
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
            _time_axis(ax)
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
    t = _naive_utc(times)
    columns, n_columns, start_num, step_num = _regular_columns(t)
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
            drop_t = _naive_utc(dropped["time"])
            drop_c = [channels.index(c) + 0.5 for c in dropped["channel"] if c in channels]
            keep = dropped["channel"].isin(channels).to_numpy()
            ax.plot(drop_t[keep] + step / 2, drop_c, "x", color="red", ms=4, mew=1.2,
                    label="dropped")  # fmt: skip
            ax.legend(fontsize=7, loc="upper right")
        ax.set_yticks(np.arange(len(channels)) + 0.5, channels, fontsize=6)
        ax.set_ylim(len(channels), 0)
        ax.set_title(label, fontsize=9)
    _time_axis(axes[-1, 0])
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


# --------------------------------------------------------------------------- correlation
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
        t = _naive_utc(rows["block_start"])
        ax.fill_between(t, rows["model_lower_hz"], rows["model_upper_hz"], color="0.85",
                        label="model 95 % band", step="mid")  # fmt: skip
        ax.plot(t, rows["model_frequency_hz"], color="0.4", lw=0.8, label="model")
        ax.plot(t, rows["ssi_frequency_hz"], ".", color=mode_colour(mode), ms=4, label="SSI")
        ax.plot(t, rows["kalman_frequency_hz"], color="k", lw=1.0, label="Kalman")
        if truth is not None:
            true = truth[truth["mode"] == mode].sort_values("block")
            ax.plot(_naive_utc(true["block_start"]), true["frequency_hz"], color="tab:green",
                    lw=0.8, ls="--", label="truth")  # fmt: skip
        ax.set_title(f"mode {mode}", fontsize=9, color=mode_colour(mode))
        ax.set_ylabel("frequency [Hz]", fontsize=8)
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7, ncols=5, loc="lower left", bbox_to_anchor=(0, 1.12))
        _time_axis(ax)
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
