"""The conditioning filter cascade seen from outside: the default analysis rate for a band,
how far the filters' transients reach into a record (the padding of a file conditioned on
its own), and the decimation of (n_channels, n_samples) arrays along the contiguous axis."""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import signal

from .conditioning import decimation_stages

__all__ = ["default_decimation_rate", "padding_samples"]

#: Relative size of a filter transient regarded as gone (impulse-response envelope). [-]
SETTLED = 1e-9
#: Highest analysis rate relative to the band's upper edge in the default rate rule. [-]
RATE_PER_BAND_EDGE = 4.0


# ----------------------------------------------------------------------------------------
# the default analysis rate
# ----------------------------------------------------------------------------------------
def default_decimation_rate(
    sampling_rate_hz: float, band_hz: tuple[float | None, float | None] | None
) -> float:
    """The analysis rate for files sampled at *sampling_rate_hz* and the band *band_hz*.

    Rule: halve the files' rate while the result stays at or above
    ``RATE_PER_BAND_EDGE`` (4) times the band's upper edge. The anti-alias filter of the
    last decimation stage then starts rolling off at 0.4 x the analysis rate, at least 1.6 x
    above the band, and the band lies below half the Nyquist frequency, where SSI with a
    few dozen block rows resolves it well. E.g. 2048 Hz and a 2-12 Hz band give 64 Hz,
    1000 Hz gives 62.5 Hz, 200 Hz gives 50 Hz, 64 Hz stays 64 Hz. Without an upper band
    edge the files' rate is kept.

    Parameters
    ----------
    sampling_rate_hz : float
        Rate of the acceleration files. [Hz]
    band_hz : (float or None, float or None) or None
        Analysis band. [Hz]

    Returns
    -------
    float
        The analysis rate, ``sampling_rate_hz / 2**k`` for some k >= 0. [Hz]
    """
    rate = float(sampling_rate_hz)
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"sampling_rate_hz={sampling_rate_hz!r} must be a positive number")
    if band_hz is None or band_hz[1] is None:
        return rate
    lowest = RATE_PER_BAND_EDGE * float(band_hz[1])
    while rate / 2 >= lowest:
        rate /= 2
    return rate


# ----------------------------------------------------------------------------------------
# filter transients
# ----------------------------------------------------------------------------------------
def _settle_samples(sos: np.ndarray, tolerance: float = SETTLED) -> int:
    """Samples after which the impulse response of *sos* stays below *tolerance* times its
    peak (one pass; the backward pass of a zero-phase filter decays alike)."""
    length = 256
    while True:
        impulse = np.zeros(length)
        impulse[0] = 1.0
        response = np.abs(signal.sosfilt(sos, impulse))
        above = np.flatnonzero(response > tolerance * response.max())
        if above[-1] < length // 2 or length >= 1 << 22:
            return int(above[-1]) + 1
        length *= 2


@functools.lru_cache(maxsize=32)
def padding_samples(
    sampling_rate_hz: float,
    target_rate_hz: float,
    band_hz: tuple[float | None, float | None] | None,
    *,
    order: int = 8,
    ripple_db: float = 0.05,
    band_order: int = 4,
) -> int:
    """Raw samples on each side of a file that carry the conditioning filters' transients.

    The sum over the cascade (each decimation stage, then the band-pass) of the length of
    its impulse response down to :data:`SETTLED` of its peak, in input samples, rounded up
    to a whole number of decimation factors. Filtering a file padded with this many samples
    of its neighbours and discarding the padding gives the file's part of the continuously
    filtered record; it is also how far into a block the per-block filters' start-up
    transients reach.

    Parameters
    ----------
    sampling_rate_hz, target_rate_hz : float
        Input and analysis rate. [Hz]
    band_hz : (float or None, float or None) or None
        Band-pass edges at the analysis rate. [Hz]
    order, ripple_db, band_order
        As for :func:`~workbench.signals.conditioning.decimate` and
        :func:`~workbench.signals.conditioning.bandpass`.
    """
    factor = int(round(sampling_rate_hz / target_rate_hz))
    total = 0
    step = 1  # input samples per sample at the current stage's rate
    for q in decimation_stages(factor):
        sos = signal.cheby1(int(order), ripple_db, 0.8 / q, output="sos")
        total += _settle_samples(sos) * step
        step *= q
    if band_hz is not None:
        low, high = band_hz
        if low is None:
            sos = signal.butter(band_order, high, "lowpass", fs=target_rate_hz, output="sos")
        elif high is None:
            sos = signal.butter(band_order, low, "highpass", fs=target_rate_hz, output="sos")
        else:
            sos = signal.butter(
                band_order, [low, high], "bandpass", fs=target_rate_hz, output="sos"
            )
        total += _settle_samples(sos) * step
    return int(math.ceil(total / factor) * factor)


class _RowDecimator:
    """:func:`~workbench.signals.conditioning.decimate` of one channel at a time, in buffers
    reused from channel to channel and file to file.

    Each stage is ``scipy.signal.sosfiltfilt`` (odd extension of ``3 (2 n_sections + 1)``
    samples, forward pass from the steady state scaled by the first sample, backward pass
    likewise) followed by keeping every q-th sample, computed with scipy's own second-order
    section kernel on the same numbers in the same order: equal to ``decimate`` to the last
    bit (tested). What it saves is memory traffic: ``sosfiltfilt`` makes a padded copy and
    each of its two passes another copy of the channel; here the caller writes the samples
    straight into the first stage's buffer (:meth:`buffer`) and both passes run in place.
    """

    def __init__(
        self, factor: int, order: int = 8, ripple_db: float = 0.05, *, rows: int = 1
    ) -> None:
        self.rows = int(rows)  # channels the first stage's buffer holds at once
        self.stages = []
        for q in decimation_stages(factor):
            sos = signal.cheby1(int(order), ripple_db, 0.8 / q, output="sos")
            n_sections = sos.shape[0]
            taps = 2 * n_sections + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum())
            self.stages.append((q, sos, signal.sosfilt_zi(sos), 3 * int(taps)))
        self._forward: dict[int, np.ndarray] = {}
        self._backward: dict[int, np.ndarray] = {}

    @property
    def edge(self) -> int:
        """Samples of odd extension in front of the first stage's input in :meth:`buffer`."""
        return self.stages[0][3]

    def _buffers(self, stage: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        size = n + 2 * self.stages[stage][3]
        forward = self._forward.get(stage)
        if forward is None or forward.shape[1] != size:
            forward = self._forward[stage] = np.empty((self.rows if stage == 0 else 1, size))
            self._backward[stage] = np.empty((1, size))
        return forward, self._backward[stage]

    def buffers(self, n: int) -> np.ndarray:
        """The first stage's input buffers for *n* samples of :attr:`rows` channels, shape
        (rows, n + 2 edge): write channel j to ``buffers[j, edge : edge + n]``, then call
        :meth:`decimate` with *n* and ``row=j``."""
        return self._buffers(0, n)[0]

    def buffer(self, n: int) -> np.ndarray:
        """The first row of :meth:`buffers`."""
        return self.buffers(n)[0]

    def decimate(self, n: int, row: int = 0) -> np.ndarray:
        """The *n* samples written to row *row* of :meth:`buffers`, decimated (a new
        array; the row is overwritten)."""
        from scipy.signal._sosfilt import _sosfilt  # the kernel of scipy.signal.sosfilt

        first = row
        row = None
        for stage, (q, sos, zi, edge) in enumerate(self.stages):
            forward, backward = self._buffers(stage, n)
            if stage == 0:
                forward = forward[first : first + 1]
            ext = forward[0]
            if row is not None:
                ext[edge : edge + n] = row
            if n <= edge:
                raise ValueError(f"{n} samples are too few to filter (need more than {edge})")
            # odd extension: 2 x[0] - x[edge:0:-1] before, 2 x[-1] - x[-2:-edge-2:-1] after
            ext[:edge] = 2 * ext[edge : edge + 1] - ext[2 * edge : edge : -1]
            ext[edge + n :] = 2 * ext[edge + n - 1 : edge + n] - ext[edge + n - 2 : n - 2 : -1]
            _sosfilt(sos, forward, np.ascontiguousarray((zi * ext[0])[None]))
            back = backward[0]
            back[:] = ext[::-1]
            _sosfilt(sos, backward, np.ascontiguousarray((zi * back[0])[None]))
            row = back[::-1][edge : edge + n][::q]
            n = row.shape[0]
        return np.array(row)


def _decimate_channels_last(x: np.ndarray, factor: int, order: int = 8, ripple_db: float = 0.05):
    """:func:`~workbench.signals.conditioning.decimate` of finite samples laid out as
    (n_channels, n_samples), one channel at a time (:class:`_RowDecimator`): equal to the
    last bit (tested)."""
    if not decimation_stages(factor):
        return x
    decimator = _RowDecimator(factor, order, ripple_db)
    out = None
    n = x.shape[1]
    edge = decimator.edge
    for channel in range(x.shape[0]):
        decimator.buffer(n)[edge : edge + n] = x[channel]
        row = decimator.decimate(n)
        if out is None:
            out = np.empty((x.shape[0], row.shape[0]), dtype=row.dtype)
        out[channel] = row
    return out
