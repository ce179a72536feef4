"""Figures of the tracked modes: frequency and damping against time with the operating
conditions, the AutoMAC of the mean shapes, and the mean shapes on the sensor layout."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from data_contracts import geometry_directions, shapes_from_frame
from workbench.sid.assurance import mac

from .view_style import (
    FIGURE_WIDTH,
    block_times,
    mode_colour,
    time_axis,
)


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
        times = block_times(part)
        style = dict(ms=2.5, lw=0.8, color=mode_colour(mode), marker="o")
        axes[0].plot(times, part["frequency_hz"], label=f"mode {mode}", **style)
        axes[1].plot(times, 100 * part["damping_ratio"], **style)
    axes[0].set_ylabel("frequency [Hz]")
    axes[1].set_ylabel("damping ratio [%]")
    axes[0].legend(fontsize=8, ncols=min(len(modes), 8), loc="lower left", bbox_to_anchor=(0, 1))
    if has_predictors:
        ax = axes[2]
        times = block_times(predictors)
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
    time_axis(axes[-1])
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


def _listed(names, limit: int = 8) -> str:
    names = [str(n) for n in names]
    more = len(names) - limit
    return ", ".join(names[:limit]) + (f" (+{more} more)" if more > 0 else "")


def check_geometry_channels(
    channels, geometry: pd.DataFrame, *, geometry_name: str = "the sensor geometry"
) -> None:
    """Refuse a sensor geometry none of whose channels is among the mode shapes' *channels*.

    Raises
    ------
    ValueError
        One line naming both sides' channels.
    """
    placed = [str(c) for c in geometry["channel"]]
    if channels and not set(map(str, channels)) & set(placed):
        raise ValueError(
            f"channel names of {geometry_name} ({_listed(placed)}) match none of the mode "
            f"shapes' channels, i.e. the acceleration files' ({_listed(channels)}); name the "
            "geometry's channels as the files do"
        )


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
    check_geometry_channels(channels, geometry)
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


def plot_campbell(
    selected: pd.DataFrame,
    shaft: pd.DataFrame,
    *,
    modal: pd.DataFrame | None = None,
    orders: Sequence[float] = (),
    shaft_hz_per_kn: float | None = None,
):
    """Campbell view: frequency against shaft speed, the orders drawn, the modes marked.

    Parameters
    ----------
    selected : DataFrame
        Selected modes (SELECTED contract) with their ``harmonic`` column.
    shaft : DataFrame
        Per block ``block``, ``shaft_rpm`` [rpm] (weighted by rpm⁴, where the harmonics'
        energy is) and ``speed_kn`` [kn] (``shaft.csv`` of identify). Without a logged
        shaft speed the abscissa is the speed (``speed_energy_kn`` when given, the speed
        the speed-following test used).
    modal : DataFrame, optional
        Tracked modal table: its modes drawn in their colours.
    orders : sequence of float
        Orders drawn as lines f = k x rpm / 60, or without a logged shaft speed
        f = k x *shaft_hz_per_kn* x speed (none without it).
    shaft_hz_per_kn : float, optional
        Shaft rate per knot the speed-following test found (``harmonics.json``). [Hz/kn]
    """
    use_rpm = "shaft_rpm" in shaft and shaft["shaft_rpm"].notna().any()
    # the orders' frequency per unit of the abscissa
    per_unit = 1.0 / 60.0 if use_rpm else shaft_hz_per_kn
    if per_unit is None or not np.isfinite(per_unit):
        orders = ()
    column = "shaft_rpm" if use_rpm else "speed_kn"
    if not use_rpm and "speed_energy_kn" in shaft and shaft["speed_energy_kn"].notna().any():
        column = "speed_energy_kn"
    abscissa = shaft.set_index("block")[column]
    fig, ax = plt.subplots(figsize=(FIGURE_WIDTH, 4.8), layout="constrained")
    x = selected["block"].map(abscissa)
    marked = (
        selected["harmonic"].notna() if "harmonic" in selected else pd.Series(False, selected.index)
    )
    tracked = pd.Series(False, selected.index)
    if modal is not None and len(modal):
        keys = set(zip(modal["block"], modal["frequency_hz"].round(9), strict=True))
        tracked = pd.Series(
            [
                (b, f) in keys
                for b, f in zip(selected["block"], selected["frequency_hz"].round(9), strict=True)
            ],
            index=selected.index,
        )
    other = ~tracked & ~marked
    ax.plot(
        x[other],
        selected.loc[other, "frequency_hz"],
        ".",
        color="0.7",
        ms=3,
        label="selected mode, not tracked",
        zorder=1,
    )
    harmonic = marked & ~tracked
    ax.plot(
        x[harmonic],
        selected.loc[harmonic, "frequency_hz"],
        "x",
        color="tab:red",
        ms=4,
        mew=1.0,
        label="harmonic (kept out of the modes)",
        zorder=2,
    )
    if modal is not None and len(modal):
        for mode, part in modal.groupby("mode"):
            ax.plot(
                part["block"].map(abscissa),
                part["frequency_hz"],
                "o",
                ms=2.5,
                color=mode_colour(mode),
                label=f"mode {mode}",
                zorder=3,
            )
    top = float(selected["frequency_hz"].max()) * 1.05 if len(selected) else 1.0
    if len(orders):
        x_line = np.linspace(0.0, float(np.nanmax(abscissa.to_numpy())) * 1.05, 50)
        for order in orders:
            ax.plot(x_line, order * per_unit * x_line, "--", color="k", lw=0.7, alpha=0.6)
            end = min(x_line[-1], top / (order * per_unit))
            ax.annotate(
                f"{order:g}×",
                (end, min(order * per_unit * end, 0.97 * top)),
                fontsize=7,
                ha="right",
                va="top" if order * per_unit * end >= 0.97 * top else "bottom",
            )
    ax.set_ylim(0.0, top)
    ax.set_xlim(left=0.0)
    if use_rpm:
        ax.set_xlabel("shaft speed [rpm]")
    elif len(orders):
        ax.set_xlabel(f"speed [kn] (no shaft speed logged; shaft rate {per_unit:.4f} Hz/kn)")
    else:
        ax.set_xlabel("speed [kn] (no shaft speed logged)")
    ax.set_ylabel("frequency [Hz]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncols=4, loc="lower left", bbox_to_anchor=(0, 1))
    return fig
