"""Faulty ship-log sensors: spikes, faulty stretches and faulty columns.

A sensor of the ship's data system can fail in ways that survive parsing: isolated spikes
(a bad reading, a transmission error), a stretch of bursts, a column that is wrong
throughout. :func:`flag_faulty` finds them:

* **spikes** -- samples whose robust z-score against a rolling median is above ``z``;
* **faulty stretches** -- consecutive ``stretch_s`` bins of a column where spikes are too
  frequent (``spike fraction 16.0 % > 5 %``) or the residuals that are left have heavy tails
  (``kurtosis 14.2 > 10``);
* **faulty columns** -- columns faulty in more than half of their stretches.

:meth:`FaultFlags.apply` sets spikes (and optionally faulty stretches) to NaN; the block
averaging (:func:`~workbench.predictors.averaging.block_predictors`) does that by default
and reports the counts in a :class:`~workbench.predictors.PredictorWarning`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import ndimage

from ._common import CANONICAL_NAMES, check_numeric_columns, time_ns

__all__ = ["FaultFlags", "LogFaultOptions", "flag_faulty"]

_NS = 1_000_000_000


@dataclass(frozen=True, eq=False)
class FaultFlags:
    """Where a ship log's sensors misbehave.

    Parameters
    ----------
    spikes : DataFrame of bool
        Same index as the log, one column per checked column: True for a spike.
    stretches : DataFrame
        One row per checked column and stretch with data: ``column``, ``start``, ``end``
        (UTC), ``n_samples``, ``n_spikes``, ``spike_fraction``, ``kurtosis`` (of the
        residuals from the rolling median, spikes left out; Gaussian 3), ``faulty``,
        ``reason``.
    columns : DataFrame
        One row per checked column: ``column``, ``n_samples``, ``n_spikes``,
        ``spike_fraction``, ``n_stretches``, ``n_faulty_stretches``, ``faulty``, ``reason``.
    """

    spikes: pd.DataFrame
    stretches: pd.DataFrame
    columns: pd.DataFrame

    @property
    def n_spikes(self) -> dict[str, int]:
        """Number of spikes per checked column."""
        return {c: int(self.spikes[c].sum()) for c in self.spikes.columns}

    def apply(self, log: pd.DataFrame, *, drop_faulty_stretches: bool = False) -> pd.DataFrame:
        """A copy of *log* with spikes (and, if asked, faulty stretches) set to NaN.

        Parameters
        ----------
        log : DataFrame
            The log these flags were computed from (same index).
        drop_faulty_stretches : bool
            Also blank every sample of a column inside its faulty stretches.
        """
        if not log.index.equals(self.spikes.index):
            raise ValueError("log does not have the index the flags were computed for")
        out = log.copy()
        for column in self.spikes.columns:
            mask = self.spikes[column].to_numpy().copy()
            if drop_faulty_stretches:
                times = time_ns(log)
                bad = self.stretches[
                    (self.stretches["column"] == column) & self.stretches["faulty"]
                ]
                for start, end in zip(bad["start"], bad["end"], strict=True):
                    mask |= (times >= pd.Timestamp(start).value) & (times < pd.Timestamp(end).value)
            if mask.any():
                values = out[column].to_numpy(dtype=float, copy=True)
                values[mask] = np.nan
                out[column] = values
        return out


def _resolution(values: np.ndarray) -> float:
    """Smallest step between distinct values (the logging resolution), from a sample."""
    sample = values if len(values) <= 200_000 else values[:: len(values) // 200_000 + 1]
    steps = np.diff(np.unique(sample))
    steps = steps[steps > 0]
    return float(steps.min()) if len(steps) else 0.0


def _rolling_median(values: np.ndarray, window: int) -> np.ndarray:
    """Centred rolling median; the ends are extended by point reflection.

    Point reflection about a robust end value (:math:`2 x_0 - x_k`, with :math:`x_0` the
    median of the first few samples) continues a linear trend, so a rising temperature is
    not taken for a spike at the end of the log, as it would be with mirrored or repeated
    end values. ``scipy.ndimage.median_filter`` is several times faster than a pandas
    rolling median on millions of samples.
    """
    pad = min(window // 2, len(values) - 1)
    if pad < 1:
        return values.copy()
    k = max(3, window // 8)
    head = np.median(values[:k])
    tail = np.median(values[-k:])
    extended = np.concatenate(
        (2 * head - values[pad:0:-1], values, 2 * tail - values[-2 : -pad - 2 : -1])
    )
    return ndimage.median_filter(extended, size=window, mode="nearest")[pad : pad + len(values)]


def _robust_residuals(
    values: np.ndarray, window: int, scale_window: int, direction: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals from the centred rolling median and their robust noise scale.

    The scale is the larger of 1.4826 MAD of the residuals and 1.4826 MAD of the first
    differences divided by sqrt(2), both rolling over *scale_window* (see
    :func:`flag_faulty`).
    """
    series = np.rad2deg(np.unwrap(np.deg2rad(values))) if direction else values
    residual = series - _rolling_median(series, window)
    difference = np.diff(series, prepend=series[0])
    if direction:
        residual = np.mod(residual + 180.0, 360.0) - 180.0
        difference = np.mod(difference + 180.0, 360.0) - 180.0
    size = scale_window
    mad_residual = ndimage.median_filter(np.abs(residual), size=size, mode="mirror")
    centred = difference - ndimage.median_filter(difference, size=size, mode="mirror")
    mad_difference = ndimage.median_filter(np.abs(centred), size=size, mode="mirror")
    return residual, 1.4826 * np.maximum(mad_residual, mad_difference / np.sqrt(2.0))


@dataclass(frozen=True)
class LogFaultOptions:
    """Thresholds of the ship-log fault check (:func:`flag_faulty`; Notes there).

    Attributes
    ----------
    window : int
        Length (odd) of the centred rolling window, in valid samples of each column (a
        column logged every 60 s gets a 21-min window with the default 21, one logged
        every second a 21-s window). The ends are extended by point reflection (keeps trends).
    scale_window : int, optional
        Length (odd) of the rolling window of the noise scale; default ``3 * window``
        (rounded up to odd): a steadier scale than one from *window* samples.
    z : float
        A sample is a spike when :math:`|x - \\tilde x| / s > z`.
    kurtosis_limit : float
        A stretch whose residual kurtosis exceeds this is faulty.
    max_spike_fraction : float
        A stretch with a larger fraction of spikes is faulty.
    stretch_s : float
        Length of the stretches (bins aligned to multiples of it since the epoch). [s]
    """

    window: int = 21
    scale_window: int | None = None
    z: float = 7.0
    kurtosis_limit: float = 10.0
    max_spike_fraction: float = 0.05
    stretch_s: float = 3600.0


def flag_faulty(
    log: pd.DataFrame,
    *,
    columns: Sequence[str] | None = None,
    direction_columns: Sequence[str] = ("wind_dir_rel_deg",),
    options: LogFaultOptions | None = None,
) -> FaultFlags:
    """Find spikes, faulty stretches and faulty columns in a ship log.

    Parameters
    ----------
    log : DataFrame
        Canonical log (``time`` and numeric columns), e.g. from
        :func:`data_contracts.read_dship`.
    columns : sequence of str, optional
        Columns to check; default the canonical predictor columns present.
    direction_columns : sequence of str
        Angular columns [deg]: unwrapped before the rolling median, residuals wrapped to
        [-180, 180).

    options : LogFaultOptions, optional
        Window lengths and thresholds; default ``LogFaultOptions()``.

    Returns
    -------
    FaultFlags

    Notes
    -----
    For each column, over its valid (non-NaN) samples: rolling median :math:`\\tilde x`
    over *window* samples, residual :math:`r = x - \\tilde x`, robust noise scale

    .. math:: s = \\max\\left(1.4826\\,\\mathrm{MAD}(r),\\;
              1.4826\\,\\mathrm{MAD}(\\Delta x) / \\sqrt 2,\\; \\delta\\right)

    with the MADs rolling over *scale_window* samples, :math:`\\Delta x` the first differences and
    :math:`\\delta` the logging resolution (smallest step between distinct values). 1.4826
    MAD estimates the standard deviation of Gaussian noise [1]_. The residual MAD alone
    underestimates the noise of a trending, finely sampled signal (the median of a
    monotone window is the centre sample itself, so most residuals are 0); differences
    remove the trend (white noise of standard deviation :math:`\\sigma` has differences of
    :math:`\\sigma\\sqrt 2`); :math:`\\delta` keeps rounded, locally constant values from
    giving infinite z. With a known scale, ``z=7`` flags a Gaussian sample with probability
    3e-12; the estimated scale varies by some 15 % (MAD of 63 samples), which the margin
    absorbs (simulated Gaussian samples and the demo voyages' injected spikes:
    ``benchmarks/results/docstring_numbers.txt``).

    References
    ----------
    .. [1] P. J. Rousseeuw, C. Croux, "Alternatives to the median absolute deviation",
       JASA 88(424), 1993. doi:10.1080/01621459.1993.10476408
    """
    times = time_ns(log)
    if columns is None:
        columns = [c for c in CANONICAL_NAMES if c in log.columns]
    columns = check_numeric_columns(log, columns)
    options = options or LogFaultOptions()
    scale_window, z, kurtosis_limit = options.scale_window, options.z, options.kurtosis_limit
    max_spike_fraction, stretch_s = options.max_spike_fraction, options.stretch_s
    window = int(options.window)
    if window < 5 or window % 2 == 0:
        raise ValueError(f"window={window} must be an odd number of samples, at least 5")
    scale_window = 3 * window if scale_window is None else int(scale_window)
    scale_window += 1 - scale_window % 2
    if scale_window < 5:
        raise ValueError(f"scale_window={scale_window} must be at least 5 samples")
    if not z > 0 or not kurtosis_limit > 0 or not 0 <= max_spike_fraction <= 1:
        raise ValueError("z and kurtosis_limit must be positive, max_spike_fraction in [0, 1]")
    stretch_ns = int(round(float(stretch_s) * _NS))
    if stretch_ns <= 0:
        raise ValueError(f"stretch_s={stretch_s} must be positive")
    directions = set(direction_columns)

    spikes = pd.DataFrame(False, index=log.index, columns=list(columns))
    stretch_rows: list[dict] = []
    column_rows: list[dict] = []
    for column in columns:
        values = log[column].to_numpy(dtype=float)
        valid = np.flatnonzero(np.isfinite(values))
        v = values[valid]
        spike = np.zeros(len(v), dtype=bool)
        residual = np.full(len(v), np.nan)
        if len(v) >= 5:
            residual, scale = _robust_residuals(v, window, scale_window, column in directions)
            floor = _resolution(v)
            with np.errstate(invalid="ignore", divide="ignore"):
                score = np.abs(residual) / np.maximum(scale, floor)
            spike = np.nan_to_num(score, nan=0.0) > z
            spike &= np.abs(residual) > 0
        mask = np.zeros(len(values), dtype=bool)
        mask[valid[spike]] = True
        spikes[column] = mask

        # stretches: bins of stretch_s, statistics by bincount
        bins = (times[valid] // stretch_ns) if len(v) else np.empty(0, dtype=np.int64)
        n_faulty = 0
        n_stretches = 0
        if len(v):
            first = bins.min()
            index = bins - first
            n_bins = int(index.max()) + 1
            count = np.bincount(index, minlength=n_bins)
            n_spike = np.bincount(index, weights=spike, minlength=n_bins)
            clean = ~spike & np.isfinite(residual)
            m = np.bincount(index[clean], minlength=n_bins).astype(float)
            with np.errstate(invalid="ignore", divide="ignore"):
                mean = np.bincount(index[clean], residual[clean], n_bins) / m
                d = residual[clean] - mean[index[clean]]
                m2 = np.bincount(index[clean], d * d, n_bins) / m
                m4 = np.bincount(index[clean], d**4, n_bins) / m
                kurtosis = np.where(m2 > 0, m4 / np.where(m2 > 0, m2, 1.0) ** 2, np.nan)
            for b in np.flatnonzero(count):
                fraction = n_spike[b] / count[b]
                why = []
                if fraction > max_spike_fraction:
                    why.append(
                        f"spike fraction {100 * fraction:.1f} % > {100 * max_spike_fraction:g} %"
                    )
                if m[b] >= 10 and kurtosis[b] > kurtosis_limit:
                    why.append(f"kurtosis {kurtosis[b]:.1f} > {kurtosis_limit:g}")
                start = (first + b) * stretch_ns
                stretch_rows.append(
                    {
                        "column": column,
                        "start": pd.Timestamp(int(start), tz="UTC"),
                        "end": pd.Timestamp(int(start + stretch_ns), tz="UTC"),
                        "n_samples": int(count[b]),
                        "n_spikes": int(n_spike[b]),
                        "spike_fraction": float(fraction),
                        "kurtosis": float(kurtosis[b]),
                        "faulty": bool(why),
                        "reason": "; ".join(why),
                    }
                )
                n_stretches += 1
                n_faulty += bool(why)
        n_total_spikes = int(spike.sum())
        faulty_column = n_stretches > 0 and n_faulty > n_stretches / 2
        column_rows.append(
            {
                "column": column,
                "n_samples": len(v),
                "n_spikes": n_total_spikes,
                "spike_fraction": n_total_spikes / len(v) if len(v) else math.nan,
                "n_stretches": n_stretches,
                "n_faulty_stretches": n_faulty,
                "faulty": bool(faulty_column),
                "reason": f"faulty in {n_faulty} of {n_stretches} stretches"
                if faulty_column
                else "",
            }
        )
    stretch_columns = [
        "column",
        "start",
        "end",
        "n_samples",
        "n_spikes",
        "spike_fraction",
        "kurtosis",
        "faulty",
        "reason",
    ]
    stretches = pd.DataFrame(stretch_rows, columns=stretch_columns)
    if stretches.empty:
        stretches = stretches.astype(
            {"start": "datetime64[ns, UTC]", "end": "datetime64[ns, UTC]", "faulty": bool}
        )
    return FaultFlags(spikes, stretches, pd.DataFrame(column_rows))
