"""Statistical moments over sliding windows and faulty-channel detection.

Faulty-channel policy
---------------------
:func:`faulty_channels` checks every channel of one block and gives each a verdict and a
reason. A faulty channel is **dropped for that block only**: the block builder
(:func:`workbench.signals.block_builder.iter_blocks`) removes it before filtering and
identification, lists it with its reason in the block's ``dropped`` field and notes, and
uses it again in the next block if it has recovered. A channel is faulty when

* it has too many NaN samples (``nan fraction 7.5 % > 5 %``),
* it has a NaN run longer than can be bridged by interpolation (``nan run 60.0 s``),
* it is flat (``flat (variance 0)``), or repeats one value for longer than a NaN run may
  last (``flat run 60.0 s``: a sensor stuck, or a recorder filling a dropout with zeros),
* its kurtosis is outside the limits (``kurtosis 25.3 > 10``): spikes and bursts give large
  kurtosis, clipping or a pure hum small kurtosis (a sine has 1.5, Gaussian noise 3). A
  *high* kurtosis is a fault only when it is out of line with the other channels (robust
  z-score of the log-kurtosis above ``max_kurtosis_z``): impulsive excitation - fan gusts,
  ice impacts, slamming - reaches every channel at once and raises every kurtosis; a
  faulty sensor's spikes are its own,
* its variance is far from that of the other channels (robust z-score of the log-variance
  across channels, ``variance z 8.1 > 6``) *and* it has lost coherence with every other
  channel: a disconnected or broken sensor records noise of its own. Channels of other
  quantities or units (velocity beside acceleration, a sensor at a node of most modes)
  also have variances out of line, but they see the same modes: their coherence with the
  others is significant, and they are kept.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .conditioning import (
    MAX_INTERPOLATED_NAN_RUN_S,
    _as_2d,
    _positive,
    constant_runs,
    detrend,
    nan_runs,
)

__all__ = [
    "ChannelCheckOptions",
    "CoherenceNeeded",
    "WindowMoments",
    "channel_verdicts",
    "coherent_with_others",
    "faulty_channels",
    "moments",
]

#: Smallest robust spread of the natural log-variance across channels used in the
#: variance z-score (channels with nearly equal variance would otherwise give huge z).
MIN_LOG_VARIANCE_SPREAD = 0.5
#: Smallest robust spread of the natural log-kurtosis across channels in the kurtosis
#: z-score: with the default z limit 3, a kurtosis must exceed the channels' median by a
#: factor exp(0.75) = 2.1 at least (impulsive excitation spreads kurtosis over channels
#: by less; a spiking sensor exceeds it by far).
MIN_LOG_KURTOSIS_SPREAD = 0.25
#: Significance level of the zero-coherence test of one frequency line (see
#: :func:`coherent_with_others`).
COHERENCE_ALPHA = 0.01


@dataclass(frozen=True, eq=False)
class WindowMoments:
    """Moments of each channel over sliding windows.

    Parameters
    ----------
    start_s : ndarray, shape (n_windows,)
        Window starts relative to the first sample. [s]
    window_s, step_s : float
        Window length and step. [s]
    n_valid : ndarray of int, shape (n_windows, n_channels)
        Finite samples in each window.
    mean, variance, skewness, kurtosis : ndarray, shape (n_windows, n_channels)
        Sample mean [unit of x], variance [unit²], skewness and kurtosis (Pearson's, 3 for
        a Gaussian) of the finite samples; NaN where fewer than the required samples are
        finite, skewness and kurtosis NaN where the variance is 0.
    """

    start_s: np.ndarray
    window_s: float
    step_s: float
    n_valid: np.ndarray
    mean: np.ndarray
    variance: np.ndarray
    skewness: np.ndarray
    kurtosis: np.ndarray

    def to_frame(self, channels: Sequence[str] | None = None) -> pd.DataFrame:
        """Long table: start_s, channel, n_valid, mean, variance, skewness, kurtosis."""
        n_windows, n_channels = self.mean.shape
        names = list(channels) if channels is not None else [str(j) for j in range(n_channels)]
        if len(names) != n_channels:
            raise ValueError(f"{len(names)} channel names for {n_channels} channels")
        return pd.DataFrame(
            {
                "start_s": np.repeat(self.start_s, n_channels),
                "channel": np.tile(np.array(names, dtype=object), n_windows),
                "n_valid": self.n_valid.ravel(),
                "mean": self.mean.ravel(),
                "variance": self.variance.ravel(),
                "skewness": self.skewness.ravel(),
                "kurtosis": self.kurtosis.ravel(),
            }
        )


def _central_moments(values: np.ndarray, axis: int) -> tuple[np.ndarray, ...]:
    """count, mean, m2, m3, m4 of the finite values along *axis* (NaN-aware)."""
    finite = np.isfinite(values)
    count = finite.sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(finite, values, 0.0).sum(axis=axis) / count
        deviation = np.where(finite, values - np.expand_dims(mean, axis), 0.0)
        square = deviation * deviation
        m2 = square.sum(axis=axis) / count
        m3 = (square * deviation).sum(axis=axis) / count
        m4 = (square * square).sum(axis=axis) / count
    return count, mean, m2, m3, m4


def _shape_statistics(m2, m3, m4) -> tuple[np.ndarray, np.ndarray]:
    with np.errstate(invalid="ignore", divide="ignore"):
        positive = m2 > 0
        skewness = np.where(positive, m3 / np.where(positive, m2, 1.0) ** 1.5, np.nan)
        kurtosis = np.where(positive, m4 / np.where(positive, m2, 1.0) ** 2, np.nan)
    return skewness, kurtosis


def _channel_groups(n_samples: int, n_channels: int, max_elements: int = 4_000_000):
    """Slices of channels holding at most about *max_elements* samples each."""
    size = max(1, min(n_channels, max_elements // max(n_samples, 1)))
    return [slice(j, min(j + size, n_channels)) for j in range(0, n_channels, size)]


def moments(
    x: np.ndarray,
    sampling_rate_hz: float,
    window_s: float,
    *,
    step_s: float | None = None,
    min_valid_fraction: float = 0.5,
) -> WindowMoments:
    """Mean, variance, skewness and kurtosis of each channel over sliding windows.

    Parameters
    ----------
    x : ndarray, shape (n_samples, n_channels) or (n_samples,)
        Signal; NaN samples are ignored.
    sampling_rate_hz : float
        Sampling rate. [Hz]
    window_s : float
        Window length. [s]
    step_s : float, optional
        Step between window starts; default *window_s* (adjacent windows). [s]
    min_valid_fraction : float
        Windows with fewer finite samples than this fraction of the window give NaN.

    Returns
    -------
    WindowMoments
        Only whole windows are used; samples after the last whole window are ignored.

    Notes
    -----
    With the central moments :math:`m_r = \\frac1n \\sum (x_i - \\bar x)^r` of the
    :math:`n` finite samples of a window: variance :math:`m_2`, skewness
    :math:`m_3 / m_2^{3/2}`, kurtosis :math:`m_4 / m_2^2` (the biased estimators of
    ``scipy.stats.skew`` / ``kurtosis(fisher=False)``). Computed for all windows and
    channels at once from a strided view (two passes, no raw-moment cancellation).
    """
    array, _ = _as_2d(x)
    rate = _positive(sampling_rate_hz, "sampling_rate_hz")
    window = int(round(_positive(window_s, "window_s") * rate))
    step = window if step_s is None else int(round(_positive(step_s, "step_s") * rate))
    if window < 2:
        raise ValueError(f"window_s={window_s} holds {window} sample(s); needs at least 2")
    if step < 1:
        raise ValueError(f"step_s={step_s} is shorter than one sample")
    if not 0 <= min_valid_fraction <= 1:
        raise ValueError(f"min_valid_fraction={min_valid_fraction} must be in [0, 1]")
    n_samples, n_channels = array.shape
    if n_samples < window:
        empty = np.empty((0, n_channels))
        return WindowMoments(
            np.empty(0), window / rate, step / rate, empty.astype(int), empty, empty, empty, empty
        )
    # view shape (n_windows, n_channels, window)
    views = np.lib.stride_tricks.sliding_window_view(array, window, axis=0)[::step]
    count, mean, m2, m3, m4 = _central_moments(views, axis=2)
    skewness, kurtosis = _shape_statistics(m2, m3, m4)
    enough = count >= max(2, math.ceil(min_valid_fraction * window))
    nan = np.nan
    return WindowMoments(
        start_s=np.arange(views.shape[0]) * step / rate,
        window_s=window / rate,
        step_s=step / rate,
        n_valid=count,
        mean=np.where(enough, mean, nan),
        variance=np.where(enough, m2, nan),
        skewness=np.where(enough, skewness, nan),
        kurtosis=np.where(enough, kurtosis, nan),
    )


@dataclass(frozen=True)
class ChannelCheckOptions:
    """Thresholds of the channel check (:func:`faulty_channels`, :func:`channel_verdicts`).

    Attributes
    ----------
    max_nan_fraction : float
        Largest accepted fraction of NaN samples.
    max_nan_run_s : float
        Longest accepted NaN run (shorter runs are bridged by interpolation), and longest
        accepted run of one repeated value (a stuck or zero-filled sensor). [s]
    kurtosis_limits : (float, float)
        Accepted range of the kurtosis of the linearly detrended channel (Gaussian: 3). A
        kurtosis above the upper limit is a fault only when also out of line with the
        other channels (*max_kurtosis_z*).
    flat_variance : float
        Variances at or below this mean a flat (dead or stuck) sensor. [(m/s²)²]
    max_variance_z : float
        Largest accepted robust z-score |z| of the channel's log-variance among the
        channels (beyond it, the channel is faulty if it is also incoherent with the
        others); ``inf`` switches the check off.
    max_kurtosis_z : float
        A kurtosis above the upper limit is a fault when its robust z-score (log-kurtosis
        among the channels) exceeds this; ``-inf`` makes the upper limit absolute (the
        former rule, which takes impulsive excitation for faults).
    coherence_check : bool
        Confirm a variance outlier by a lost coherence with every other channel
        (:func:`coherent_with_others`); False drops on the variance z-score alone.
    """

    max_nan_fraction: float = 0.05
    max_nan_run_s: float = MAX_INTERPOLATED_NAN_RUN_S
    kurtosis_limits: tuple[float, float] = (1.3, 10.0)
    flat_variance: float = 1e-12
    max_variance_z: float = 6.0
    max_kurtosis_z: float = 3.0
    coherence_check: bool = True

    def __post_init__(self) -> None:
        low, high = (float(v) for v in self.kurtosis_limits)
        if not low < high:
            raise ValueError(f"kurtosis_limits={self.kurtosis_limits} must be (lower, upper)")


def faulty_channels(
    x: np.ndarray,
    sampling_rate_hz: float,
    channels: Sequence[str] | None = None,
    *,
    options: ChannelCheckOptions | None = None,
) -> pd.DataFrame:
    """Check each channel of one block and say which are faulty and why.

    Parameters
    ----------
    x : ndarray, shape (n_samples, n_channels)
        Raw accelerations of one block, NaN for dropouts. [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    channels : sequence of str, optional
        Channel names (default ``"0"``, ``"1"``, ...).
    options : ChannelCheckOptions, optional
        The thresholds; default ``ChannelCheckOptions()``.

    Returns
    -------
    DataFrame
        One row per channel: ``channel``, ``faulty`` (bool), ``reason`` (empty when fine,
        several reasons joined by ``"; "``), ``nan_fraction``, ``longest_nan_run_s``,
        ``variance``, ``kurtosis``, ``variance_z``, ``kurtosis_z``, ``coherent`` (1.0 /
        0.0 for channels whose coherence was tested, NaN otherwise).

    Notes
    -----
    Kurtosis and variance are those of the whole block after a linear detrend, over the
    finite samples. The variance z-score is
    :math:`z_j = (\\ln v_j - \\operatorname{med}\\ln v) / \\max(1.4826\\,
    \\operatorname{MAD}, 0.5)` over channels that are not flat and have finite variance
    (needs at least 3 such channels); the floor keeps channels of nearly equal variance
    from being flagged for small differences. The kurtosis z-score is the same statistic
    of :math:`\\ln \\kappa_j` with the floor 0.25; with fewer than 3 usable channels the
    kurtosis limits are absolute. See the module docstring for the policy.
    """
    array, _ = _as_2d(x)
    rate = _positive(sampling_rate_hz, "sampling_rate_hz")
    n_samples, n_channels = array.shape
    names = (
        [str(c) for c in channels] if channels is not None else [str(j) for j in range(n_channels)]
    )
    if len(names) != n_channels:
        raise ValueError(f"{len(names)} channel names for {n_channels} channels")

    nan_fraction = np.ones(n_channels)
    longest = np.zeros(n_channels)
    longest_flat = np.zeros(n_channels)
    variance = np.full(n_channels, np.nan)
    kurtosis = np.full(n_channels, np.nan)
    # a few channels at a time: temporaries stay small for long, fast-sampled blocks
    for group in _channel_groups(n_samples, n_channels):
        part = array[:, group]
        missing = np.isnan(part)
        if n_samples:
            nan_fraction[group] = missing.mean(axis=0)
        for j in np.flatnonzero(missing.any(axis=0)):
            longest[group.start + j] = nan_runs(missing[:, j])[1].max() / rate
        longest_flat[group] = constant_runs(part)[2] / rate
        _, _, m2, _, m4 = _central_moments(detrend(part), axis=0)
        variance[group] = m2
        kurtosis[group] = _shape_statistics(m2, np.zeros_like(m2), m4)[1]

    return channel_verdicts(
        names,
        nan_fraction,
        longest,
        variance,
        kurtosis,
        options=options,
        coherence=lambda outliers, healthy: coherent_with_others(array, rate, outliers, healthy),
        longest_flat_s=longest_flat,
    )


class CoherenceNeeded(LookupError):
    """:func:`channel_verdicts` needs the block's samples (a variance outlier whose
    coherence with the other channels decides its verdict) but was given none."""


def channel_verdicts(
    channels: Sequence[str],
    nan_fraction: np.ndarray,
    longest: np.ndarray,
    variance: np.ndarray,
    kurtosis: np.ndarray,
    *,
    options: ChannelCheckOptions | None = None,
    coherence: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    longest_flat_s: np.ndarray | None = None,
) -> pd.DataFrame:
    """The verdicts of :func:`faulty_channels` from the block statistics it computes.

    Parameters
    ----------
    channels : sequence of str
    nan_fraction, longest, variance, kurtosis : ndarray, shape (n_channels,)
        Fraction of NaN samples, longest NaN run [s], variance [(m/s²)²] and kurtosis of
        the linearly detrended block (NaN where undefined).
    options : ChannelCheckOptions, optional
        The thresholds; default ``ChannelCheckOptions()``.
    coherence : callable, optional
        ``coherence(outliers, healthy)`` -> 1.0 / 0.0 per outlier channel: whether it is
        coherent with any healthy channel (:func:`coherent_with_others` on the block).
    longest_flat_s : ndarray, shape (n_channels,), optional
        Longest run of one repeated value (:func:`~workbench.signals.conditioning.
        constant_runs`) [s]; not checked when not given.

    Returns
    -------
    DataFrame
        As :func:`faulty_channels` returns.

    Raises
    ------
    CoherenceNeeded
        A variance outlier must be checked for coherence and *coherence* is None.
    """
    names = [str(c) for c in channels]
    n_channels = len(names)
    check = options or ChannelCheckOptions()
    max_nan_fraction, max_nan_run_s = check.max_nan_fraction, check.max_nan_run_s
    flat_variance, max_variance_z = check.flat_variance, check.max_variance_z
    low, high = (float(v) for v in check.kurtosis_limits)
    usable = np.isfinite(variance) & (variance > flat_variance)
    z = _robust_z(np.log(np.where(usable, variance, 1.0)), usable, MIN_LOG_VARIANCE_SPREAD)
    usable_kurtosis = usable & np.isfinite(kurtosis) & (kurtosis > 0)
    kurtosis_z = _robust_z(
        np.log(np.where(usable_kurtosis, kurtosis, 1.0)), usable_kurtosis, MIN_LOG_KURTOSIS_SPREAD
    )
    # variance outliers: faulty only if they also lost coherence with every other channel
    outliers = np.flatnonzero(np.isfinite(z) & (np.abs(z) > max_variance_z))
    coherent = np.full(n_channels, np.nan)
    if check.coherence_check and outliers.size:
        healthy = usable & (nan_fraction <= max_nan_fraction) & (longest <= max_nan_run_s)
        if coherence is None:
            raise CoherenceNeeded(f"variance outliers {outliers.tolist()} need the block's samples")
        coherent[outliers] = coherence(outliers, healthy)

    reasons: list[str] = []
    for j in range(n_channels):
        why = []
        if nan_fraction[j] >= 1.0:
            why.append("no data (all NaN)")
        else:
            if nan_fraction[j] > max_nan_fraction:
                why.append(
                    f"nan fraction {100 * nan_fraction[j]:.1f} % > {100 * max_nan_fraction:g} %"
                )
            if longest[j] > max_nan_run_s:
                why.append(f"nan run {longest[j]:.1f} s")
            flat_run = np.nan if longest_flat_s is None else float(longest_flat_s[j])
            if flat_run > max_nan_run_s and variance[j] > flat_variance:
                why.append(f"flat run {flat_run:.1f} s")
            if not variance[j] > flat_variance:
                shown = 0.0 if variance[j] < 1e-30 else variance[j]  # round-off of a constant
                why.append(f"flat (variance {shown:.3g})")
            elif kurtosis[j] > high and not (kurtosis_z[j] <= check.max_kurtosis_z):
                # out of line with the other channels (or too few channels to compare)
                why.append(f"kurtosis {kurtosis[j]:.1f} > {high:g}")
            elif kurtosis[j] < low:
                why.append(f"kurtosis {kurtosis[j]:.2f} < {low:g}")
            if np.isfinite(z[j]) and abs(z[j]) > max_variance_z and coherent[j] != 1.0:
                lost = "; no coherence with any other channel" if coherent[j] == 0.0 else ""
                why.append(f"variance z {z[j]:.1f} beyond ±{max_variance_z:g}{lost}")
        reasons.append("; ".join(why))
    return pd.DataFrame(
        {
            "channel": pd.Series(names),
            "faulty": np.array([bool(r) for r in reasons]),
            "reason": pd.Series(reasons),
            "nan_fraction": nan_fraction,
            "longest_nan_run_s": longest,
            "variance": variance,
            "kurtosis": kurtosis,
            "variance_z": z,
            "kurtosis_z": kurtosis_z,
            "coherent": coherent,
        }
    )


def _robust_z(values: np.ndarray, usable: np.ndarray, min_spread: float) -> np.ndarray:
    """(v - median) / max(1.4826 MAD, min_spread) over the usable entries (NaN elsewhere,
    and everywhere with fewer than 3 usable entries)."""
    z = np.full(values.size, np.nan)
    if usable.sum() >= 3:
        centre = np.median(values[usable])
        spread = max(1.4826 * np.median(np.abs(values[usable] - centre)), min_spread)
        z[usable] = (values[usable] - centre) / spread
    return z


def coherent_with_others(
    x: np.ndarray,
    sampling_rate_hz: float,
    channels: Sequence[int] | np.ndarray,
    others: np.ndarray | None = None,
    *,
    n_segments: int = 64,
    alpha: float = COHERENCE_ALPHA,
) -> np.ndarray:
    """Whether each of *channels* is significantly coherent with at least one other channel.

    Parameters
    ----------
    x : ndarray, shape (n_samples, n_channels)
        One block (NaN samples are set to 0 after a linear detrend).
    sampling_rate_hz : float
        [Hz]
    channels : sequence of int
        Columns to test.
    others : ndarray of bool, shape (n_channels,), optional
        Columns to compare with (default all); a column is never compared with itself.
    n_segments : int
        Non-overlapping Hann-windowed segments of the Welch estimate.
    alpha : float
        Significance level of the zero-coherence test of one frequency line.

    Returns
    -------
    ndarray of float, shape (len(channels),)
        1.0 (coherent with some other channel) or 0.0; NaN without another channel.

    Notes
    -----
    With n independent segments and no true coherence, the estimated magnitude-squared
    coherence of one frequency line exceeds :math:`c_\\alpha = 1 - \\alpha^{1/(n-1)}`
    with probability α [1]_. Counting the lines (up to 0.8 times Nyquist) where the
    coherence with channel k exceeds :math:`c_\\alpha`, a channel without coherence
    gives a binomial count B(m, α) over m lines; the channel is *coherent* when, for some
    k, the count exceeds the binomial's 0.999 quantile (Bonferroni-corrected for the
    channels compared). Structural modes seen by both channels give many lines of high
    coherence; a disconnected sensor recording its own noise gives none.

    References
    ----------
    .. [1] J. S. Bendat, A. G. Piersol, "Random Data: Analysis and Measurement
       Procedures", 4th ed., Wiley, 2010, section 9.2.3. doi:10.1002/9781118032428
    """
    from scipy import stats as scipy_stats

    array, _ = _as_2d(x)
    _positive(sampling_rate_hz, "sampling_rate_hz")
    n_samples, n_channels = array.shape
    channels = np.asarray(channels, dtype=int)
    others = np.ones(n_channels, dtype=bool) if others is None else np.asarray(others, bool)
    result = np.full(channels.size, np.nan)
    segment = n_samples // max(int(n_segments), 2)
    if segment < 16 or channels.size == 0:
        return result
    n = n_samples // segment
    columns = np.union1d(channels, np.flatnonzero(others))
    data = np.nan_to_num(detrend(array[: n * segment, columns]), nan=0.0)
    window = np.hanning(segment)
    spectra = np.fft.rfft(
        data.reshape(n, segment, columns.size) * window[None, :, None], axis=1
    )  # (segments, lines, channels)
    lines = int(0.8 * (segment // 2)) + 1
    spectra = spectra[:, 1:lines]
    auto = np.mean(np.abs(spectra) ** 2, axis=0)  # (lines, channels)
    critical = 1.0 - alpha ** (1.0 / (n - 1))
    position = {int(c): k for k, c in enumerate(columns)}
    for r, j in enumerate(channels):
        a = position[int(j)]
        partners = [position[int(k)] for k in np.flatnonzero(others) if k != j]
        if not partners:
            continue
        cross = np.mean(spectra[:, :, [a]].conj() * spectra[:, :, partners], axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            coherence = np.abs(cross) ** 2 / (auto[:, [a]] * auto[:, partners])
        count = np.sum(np.nan_to_num(coherence) > critical, axis=0)
        limit = scipy_stats.binom.ppf(1.0 - 0.001 / len(partners), coherence.shape[0], alpha)
        result[r] = float(np.any(count > limit))
    return result
