"""Signal conditioning: NaN-run interpolation, linear detrend, decimation, band-pass.

All functions are pure: they take an array of shape (n_samples, n_channels) (a 1-D array
is one channel) and return a new array of the same layout; the input is never modified.

NaN policy
----------
Dropouts (NaN) are handled the same way everywhere:

* :func:`detrend` fits and removes the line through the finite samples only; NaN stay NaN.
* The filters (:func:`decimate`, :func:`bandpass`) need finite input. NaN runs up to
  ``max_nan_run_s`` (default :data:`MAX_INTERPOLATED_NAN_RUN_S`) are first replaced by
  straight lines between the neighbouring samples (:func:`interpolate_nan_runs`); the
  interpolated samples stay in the output as ordinary values. A channel that still holds
  NaN after that (a longer run) is faulty: it comes out all-NaN and a
  :class:`SignalWarning` names it. The block builder (:mod:`workbench.signals.block_builder`) drops
  such channels before filtering (see :func:`~workbench.signals.moments.faulty_channels`),
  so in a pipeline the warning does not occur.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy import signal

__all__ = [
    "MAX_INTERPOLATED_NAN_RUN_S",
    "SignalWarning",
    "bandpass",
    "decimate",
    "decimation_stages",
    "detrend",
    "interpolate_nan_runs",
    "line_from_sums",
    "nan_runs",
]

#: Longest NaN run that is bridged by linear interpolation before filtering. [s]
MAX_INTERPOLATED_NAN_RUN_S = 10.0
#: Largest decimation factor of one anti-alias stage (the SciPy documentation advises at
#: most 13 for an order-8 Chebyshev filter); larger factors are split into stages.
MAX_STAGE_FACTOR = 10


class SignalWarning(UserWarning):
    """A channel or block needed special treatment (faulty channel, NaN left, ...)."""


def _as_2d(x, name: str = "x") -> tuple[np.ndarray, bool]:
    try:
        array = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as error:
        raise TypeError(f"{name} must be a numeric array") from error
    if array.ndim == 1:
        return array[:, None], True
    if array.ndim != 2:
        raise ValueError(f"{name} must be 1-D or 2-D (n_samples x n_channels), got {array.ndim}-D")
    return array, False


def _restore(array: np.ndarray, was_1d: bool) -> np.ndarray:
    return array[:, 0] if was_1d else array


def _positive(value, name: str) -> float:
    number = float(value)
    if not math.isfinite(number) or number <= 0:
        raise ValueError(f"{name}={value!r} must be a positive number")
    return number


def nan_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start indices and lengths of the runs of True in a 1-D boolean *mask*.

    Returns
    -------
    starts, lengths : ndarray of int
    """
    mask = np.asarray(mask, dtype=bool).ravel()
    edges = np.diff(np.concatenate(([0], mask.view(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    return starts, ends - starts


def constant_runs(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per channel of *x* (n_samples, n_channels), the samples of the run of one repeated
    value that starts the record, of the one that ends it, and of the longest: a stuck or
    zero-filled sensor repeats one value, a live one hardly twice (NaN never equals).

    Returns
    -------
    leading, trailing, longest : ndarray of int, shape (n_channels,)
        Each at least 1 (0 without samples).
    """
    n, n_channels = x.shape
    leading = np.full(n_channels, min(n, 1), dtype=np.int64)
    trailing, longest = leading.copy(), leading.copy()
    if n < 2:
        return leading, trailing, longest
    equal = x[1:] == x[:-1]  # True where a sample repeats the one before it
    for j in np.flatnonzero(equal.any(axis=0)):
        starts, lengths = nan_runs(equal[:, j])
        longest[j] = lengths.max() + 1
        if starts[0] == 0:
            leading[j] = lengths[0] + 1
        if starts[-1] + lengths[-1] == n - 1:
            trailing[j] = lengths[-1] + 1
    return leading, trailing, longest


def interpolate_nan_runs(
    x: np.ndarray, sampling_rate_hz: float, *, max_run_s: float = MAX_INTERPOLATED_NAN_RUN_S
) -> np.ndarray:
    """Bridge NaN runs of at most *max_run_s* by straight lines.

    Parameters
    ----------
    x : ndarray, shape (n_samples, n_channels) or (n_samples,)
        Signal with NaN dropouts.
    sampling_rate_hz : float
        Sampling rate. [Hz]
    max_run_s : float
        Longest run that is bridged. [s] Longer runs, and all-NaN channels, are left NaN.

    Returns
    -------
    ndarray
        A copy; a run at the start or end of the record takes the nearest finite value.
    """
    array, was_1d = _as_2d(x)
    rate = _positive(sampling_rate_hz, "sampling_rate_hz")
    max_samples = int(math.floor(float(max_run_s) * rate + 1e-9))
    out = array.copy()
    for j in np.flatnonzero(np.isnan(array).any(axis=0)):
        column = array[:, j]
        missing = np.isnan(column)
        if missing.all():
            continue
        starts, lengths = nan_runs(missing)
        short = lengths <= max_samples
        if not short.any():
            continue
        fill = np.zeros(len(column), dtype=bool)
        for start, length in zip(starts[short], lengths[short], strict=True):
            fill[start : start + length] = True
        good = np.flatnonzero(~missing)
        out[fill, j] = np.interp(np.flatnonzero(fill), good, column[good])
    return _restore(out, was_1d)


def detrend(x: np.ndarray) -> np.ndarray:
    """Remove the least-squares straight line from each channel, ignoring NaN samples.

    Parameters
    ----------
    x : ndarray, shape (n_samples, n_channels) or (n_samples,)
        Signal; NaN marks missing samples.

    Returns
    -------
    ndarray
        Same shape; NaN where *x* is NaN. A channel with a single finite sample becomes 0
        there; an all-NaN channel stays all-NaN.

    Notes
    -----
    For channel :math:`j` with finite samples at indices :math:`t_i` (weights
    :math:`w_i = 1`, 0 for NaN), the line :math:`a + b t` minimises
    :math:`\\sum_i w_i (x_i - a - b t_i)^2`:
    :math:`b = \\sum w (t-\\bar t)(x-\\bar x) / \\sum w (t-\\bar t)^2`,
    :math:`a = \\bar x - b \\bar t` (weighted means). All channels are fitted at once.
    """
    array, was_1d = _as_2d(x)
    n = array.shape[0]
    t = np.arange(n, dtype=float) - (n - 1) / 2.0  # centred: sum(t) = 0 without NaN
    if not np.isnan(array).any():
        # closed form: mean(t) = 0, sum(t^2) = n (n^2 - 1) / 12
        sxx = n * (n * n - 1) / 12.0
        slope = (t @ array) / sxx if sxx > 0 else np.zeros(array.shape[1])
        out = array - array.mean(axis=0) if n else array.copy()
        out -= np.outer(t, slope)
        return _restore(out, was_1d)
    finite = np.isfinite(array)
    weight = finite.astype(float)
    values = np.where(finite, array, 0.0)
    # weighted sums by matrix-vector products (one pass over the data each)
    count = weight.sum(axis=0)
    sum_t = t @ weight
    sum_tt = (t * t) @ weight
    sum_x = values.sum(axis=0)
    sum_tx = t @ values
    slope, intercept = line_from_sums(count, sum_t, sum_tt, sum_x, sum_tx)
    trend = np.outer(t, slope)
    trend += intercept
    return _restore(np.where(finite, array - trend, np.nan), was_1d)


def line_from_sums(count, sum_t, sum_tt, sum_x, sum_tx) -> tuple[np.ndarray, np.ndarray]:
    """Slope b and intercept a of the least-squares line x = a + b t of each channel, from
    its sums over the samples: n, Σt, Σt², Σx, Σtx (:func:`detrend`'s Notes).

    b = 0 where the times do not spread (Σ(t - t̄)² = 0); NaN where n = 0.
    """
    with np.errstate(invalid="ignore", divide="ignore"):
        t_mean = sum_t / count
        x_mean = sum_x / count
        sxx = sum_tt - count * t_mean * t_mean
        sxy = sum_tx - count * t_mean * x_mean
        slope = np.where(sxx > 0, sxy / np.where(sxx > 0, sxx, 1.0), 0.0)
        intercept = x_mean - slope * t_mean
    return slope, intercept


def _finite_for_filtering(array: np.ndarray, rate: float, max_nan_run_s: float) -> np.ndarray:
    """Interpolate short runs; channels still holding NaN become all-NaN (warned)."""
    if not np.isnan(array).any():
        return array
    filled = interpolate_nan_runs(array, rate, max_run_s=max_nan_run_s)
    bad = np.isnan(filled).any(axis=0)
    if bad.any():
        warnings.warn(
            f"channel(s) {', '.join(str(j) for j in np.flatnonzero(bad))} have NaN runs longer "
            f"than {max_nan_run_s:g} s; they are returned all-NaN (drop faulty channels first)",
            SignalWarning,
            stacklevel=3,
        )
        filled[:, bad] = np.nan
    return filled


def _sosfiltfilt(sos: np.ndarray, array: np.ndarray) -> np.ndarray:
    """Zero-phase filtering of the finite channels; all-NaN channels pass through."""
    out = np.full_like(array, np.nan)
    good = ~np.isnan(array).any(axis=0)
    if good.any():
        out[:, good] = signal.sosfiltfilt(sos, array[:, good], axis=0)
    return out


def decimation_stages(factor: int, *, max_stage_factor: int = MAX_STAGE_FACTOR) -> list[int]:
    """Split a decimation *factor* into stages of at most *max_stage_factor* each.

    Largest stage first (the later, slower-rate stages are cheaper), e.g. 32 -> [8, 4],
    12 -> [6, 2], 100 -> [10, 10]. A prime factor above *max_stage_factor* stays one stage.
    """
    factor = int(factor)
    if factor < 1:
        raise ValueError(f"factor={factor} must be a positive integer")
    stages: list[int] = []
    remaining = factor
    while remaining > 1:
        divisor = next(
            (d for d in range(min(max_stage_factor, remaining), 1, -1) if remaining % d == 0),
            remaining,
        )
        stages.append(divisor)
        remaining //= divisor
    return stages


def decimate(
    x: np.ndarray,
    sampling_rate_hz: float,
    target_rate_hz: float,
    *,
    order: int = 8,
    ripple_db: float = 0.05,
    max_nan_run_s: float = MAX_INTERPOLATED_NAN_RUN_S,
) -> np.ndarray:
    """Lower the sampling rate by an integer factor behind a zero-phase anti-alias filter.

    Parameters
    ----------
    x : ndarray, shape (n_samples, n_channels) or (n_samples,)
        Signal sampled at *sampling_rate_hz*.
    sampling_rate_hz : float
        Input sampling rate. [Hz]
    target_rate_hz : float
        Output sampling rate; ``sampling_rate_hz / target_rate_hz`` must be a whole number.
        [Hz]
    order : int
        Order of each Chebyshev type I stage.
    ripple_db : float
        Passband ripple of each stage for one pass. [dB] Forward-backward filtering doubles
        it: each stage's gain lies between :math:`10^{-2 r / 20}` and 1 in its passband
        (0.9886-1 for the default 0.05 dB), and the stages multiply.
    max_nan_run_s : float
        NaN runs up to this length are interpolated first (see the module NaN policy). [s]

    Returns
    -------
    ndarray, shape (ceil(n_samples / factor), n_channels)
        Samples 0, factor, 2 factor, ... of the filtered signal.

    Notes
    -----
    Each stage with factor :math:`q` applies a Chebyshev type I low-pass of the given
    order and ripple with edge frequency :math:`0.8 f_s / (2 q)` forwards and backwards
    (``scipy.signal.sosfiltfilt``: zero phase, squared magnitude) and keeps every
    :math:`q`-th sample -- the filter of MATLAB's and SciPy's ``decimate``. A single-stage
    call equals ``scipy.signal.decimate(x, q, ftype="iir", zero_phase=True)``. Factors
    above :data:`MAX_STAGE_FACTOR` are split (:func:`decimation_stages`), e.g. 2048 Hz ->
    64 Hz as 8 x 4. Passband gain: each stage's zero-phase gain is
    :math:`|H(f)|^2 \\in [10^{-2r/20}, 1]` for ripple :math:`r` dB, so :math:`S` stages stay
    within :math:`2 S r` dB of 1 (0.2 dB for 2048 Hz -> 64 Hz with the defaults; a 3 Hz
    tone keeps 98.5 % of its amplitude). The phase is exactly zero, and the same gain applies
    to all channels, so mode shapes and frequencies are unaffected. For an amplitude error
    below 0.1 % at 2048 Hz -> 64 Hz use ``ripple_db=0.002``. A 40 Hz tone (which would
    alias to 24 Hz) is attenuated by about 100 dB with the defaults and 70 dB with
    ``ripple_db=0.002``.

    Raises
    ------
    ValueError
        When the rate ratio is not a whole number, or the target is above the input rate.
    """
    array, was_1d = _as_2d(x)
    rate = _positive(sampling_rate_hz, "sampling_rate_hz")
    target = _positive(target_rate_hz, "target_rate_hz")
    ratio = rate / target
    factor = int(round(ratio))
    if factor < 1 or abs(ratio - factor) > 1e-9 * ratio:
        raise ValueError(
            f"target_rate_hz={target:g} must divide sampling_rate_hz={rate:g} by a whole "
            f"number (ratio {ratio:g}); resample first or choose e.g. "
            f"{rate / max(1, math.floor(ratio)):g} Hz"
        )
    if int(order) < 1:
        raise ValueError(f"order={order} must be a positive integer")
    ripple = _positive(ripple_db, "ripple_db")
    out = _finite_for_filtering(array, rate, max_nan_run_s)
    for q in decimation_stages(factor):
        sos = signal.cheby1(int(order), ripple, 0.8 / q, output="sos")
        out = _sosfiltfilt(sos, out)[::q]
    return _restore(np.ascontiguousarray(out), was_1d)


def bandpass(
    x: np.ndarray,
    sampling_rate_hz: float,
    low_hz: float | None,
    high_hz: float | None,
    *,
    order: int = 4,
    max_nan_run_s: float = MAX_INTERPOLATED_NAN_RUN_S,
) -> np.ndarray:
    """Zero-phase Butterworth band-pass (or high-/low-pass when one edge is None).

    Parameters
    ----------
    x : ndarray, shape (n_samples, n_channels) or (n_samples,)
        Signal.
    sampling_rate_hz : float
        Sampling rate. [Hz]
    low_hz, high_hz : float or None
        Lower and upper -6 dB edges of the forward-backward filter (-3 dB per pass);
        ``None`` for a low-pass (no lower edge) or high-pass (no upper edge). [Hz]
    order : int
        Butterworth order of one pass (a band-pass has twice as many poles).
    max_nan_run_s : float
        NaN runs up to this length are interpolated first (see the module NaN policy). [s]

    Returns
    -------
    ndarray
        Same shape as *x*.

    Notes
    -----
    ``scipy.signal.butter(order, ..., output="sos")`` applied with ``sosfiltfilt``: the
    magnitude response is :math:`|H(f)|^2`, phase zero. A Butterworth pass has gain
    :math:`1/\\sqrt{2}` at its edges, so the zero-phase filter has gain 1/2 there.
    """
    array, was_1d = _as_2d(x)
    rate = _positive(sampling_rate_hz, "sampling_rate_hz")
    nyquist = rate / 2.0
    for name, value in (("low_hz", low_hz), ("high_hz", high_hz)):
        if value is not None and not 0 < float(value) < nyquist:
            raise ValueError(f"{name}={value} must lie between 0 and Nyquist {nyquist:g} Hz")
    if low_hz is None and high_hz is None:
        raise ValueError("give low_hz, high_hz or both")
    if low_hz is not None and high_hz is not None and not float(low_hz) < float(high_hz):
        raise ValueError(f"low_hz={low_hz} must be below high_hz={high_hz}")
    if int(order) < 1:
        raise ValueError(f"order={order} must be a positive integer")
    if low_hz is None:
        sos = signal.butter(int(order), float(high_hz), "lowpass", fs=rate, output="sos")
    elif high_hz is None:
        sos = signal.butter(int(order), float(low_hz), "highpass", fs=rate, output="sos")
    else:
        sos = signal.butter(
            int(order), [float(low_hz), float(high_hz)], "bandpass", fs=rate, output="sos"
        )
    out = _sosfiltfilt(sos, _finite_for_filtering(array, rate, max_nan_run_s))
    return _restore(out, was_1d)
