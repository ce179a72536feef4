"""Condition each acquisition file once and cut the blocks from the conditioned files.

With 20-minute blocks every 5 minutes, each 5-minute file lies in four blocks. The block
builder of :mod:`workbench.signals.block_builder` reads, checks and decimates every block from its
raw files, so every raw sample is read, checked and filtered four times. At a recorder's
rate (2048 Hz, about 20 channels) that repetition dominates the cost of identification.

:class:`FileConditioner` does the expensive work once per file:

* the file is read once (its neighbours' edges with a partial read),
* short NaN runs are bridged, the Chebyshev type I decimation
  (:func:`~workbench.signals.conditioning.decimate`) and the zero-phase band-pass
  (:func:`~workbench.signals.conditioning.bandpass`) run over the file **padded with the
  raw edges of the contiguous neighbouring files** (overlap and discard), and the padding is
  cut off again: the conditioned files join into the record that filtering the whole
  continuous record would give, to within the decay of the filters' transients over the
  padding (:func:`padding_samples`). A gap between files (or the end of the data) breaks
  the chain: there the filters start as ``scipy.signal.sosfiltfilt`` starts at the ends of a
  record;
* the sums the faulty-channel check needs (NaN count and runs, power sums of the
  samples against time) are taken per grid step (:class:`_StepSums`), so the check of a block
  (:func:`~workbench.signals.moments.faulty_channels`: NaN fraction and runs, flatness,
  kurtosis and variance of the linearly detrended block) is assembled from them exactly,
  without the raw samples.

A block is then cut from the conditioned files (a few MB at the analysis rate) and its
faulty channels dropped. Blocks the conditioned files cannot give exactly as the per-block
builder would (a NaN-padded gap inside the block, a kept channel whose NaN run could not be
bridged elsewhere in its file, a block start off the decimated sample lattice) are built by
:func:`~workbench.signals.block_builder.load_block` instead, so the result never silently differs.

Equality with the per-block builder
-----------------------------------
The per-block builder filters each block on its own, so its first and last samples carry
the filters' start-up transients; the conditioned files carry none (inside a chain). The
two agree in the block's interior: samples farther than :func:`padding_samples` from both
block ends differ only by the transients' remainder (below ``1e-6`` of the signal RMS for
the default filters; ``tests/signals/test_file_conditioning.py`` checks it). The
faulty-channel statistics are equal up to rounding.

Memory: a :class:`FileConditioner` keeps the conditioned files of the blocks under way (at
the analysis rate) and one raw file; it does not grow with the voyage.

In parallel runs each file is conditioned once by :func:`condition_file` (a
:class:`~workbench.parallel.SharedInput` of the blocks holding it, on any worker) and the
blocks take the conditioned files with :meth:`FileConditioner.reuse`: only the small
conditioned files (a few MB at the analysis rate) travel between processes, never the raw
samples.
"""

from __future__ import annotations

import collections
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import signal

from data_contracts import read_accelerations
from data_contracts.npz import read_sample_rows

from ..blocks import BlockGrid
from .block_builder import AccelerationBlock, load_block
from .block_plan import FileInfo, PlannedBlock
from .conditioning import (
    MAX_INTERPOLATED_NAN_RUN_S,
    bandpass,
    decimation_stages,
    interpolate_nan_runs,
)
from .conditioning import detrend as linear_detrend
from .moments import CoherenceNeeded, channel_verdicts

__all__ = [
    "FileConditioner",
    "FileConditioning",
    "condition_file",
    "default_decimation_rate",
    "padding_samples",
]

_NS = 1_000_000_000
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


def _decimate_channels_last(x: np.ndarray, factor: int, order: int = 8, ripple_db: float = 0.05):
    """:func:`~workbench.signals.conditioning.decimate` of finite samples laid out as
    (n_channels, n_samples): the same Chebyshev type I stages and zero-phase filtering
    (equal to the last bit, tested), filtering along the contiguous axis, which is twice as
    fast as along the rows of an (n_samples, n_channels) array."""
    for q in decimation_stages(factor):
        sos = signal.cheby1(int(order), ripple_db, 0.8 / q, output="sos")
        x = signal.sosfiltfilt(sos, x, axis=-1)[:, ::q]
    return x


# ----------------------------------------------------------------------------------------
# partial reads
# ----------------------------------------------------------------------------------------
#: Files read whole (formats without partial reads: CSV, MATLAB, HDF5, UFF, compressed
#: ``.npz``) kept per process. Conditioning a file also needs its neighbours' edges, and
#: the next file conditioned is usually a neighbour: with the last three files kept, a
#: voyage conditioned in order parses each file once instead of three times. [files]
WHOLE_READS_KEPT = 3
_whole_reads: collections.OrderedDict = collections.OrderedDict()


def _read_whole(path: Path, read_options=None):
    """:func:`data_contracts.read_accelerations` of *path*, from the per-process cache of
    the last :data:`WHOLE_READS_KEPT` files when neither the file (size, modification
    time) nor the reading options changed."""
    stat = path.stat()
    key = (str(path), stat.st_size, stat.st_mtime_ns, repr(sorted((read_options or {}).items())))
    record = _whole_reads.get(key)
    if record is None:
        record = read_accelerations(path, **(read_options or {}))
        _whole_reads[key] = record
        while len(_whole_reads) > WHOLE_READS_KEPT:
            _whole_reads.popitem(last=False)
    else:
        _whole_reads.move_to_end(key)
    return record


def _read_rows(
    info: FileInfo, channels: Sequence[str], first: int, stop: int, read_options=None
) -> np.ndarray:
    """Rows [first, stop) of a file's samples, channels in *channels* order.

    Uncompressed ``.npz`` files are read in place (only the wanted rows); other files are
    read whole (kept for the next few reads, :data:`WHOLE_READS_KEPT`).
    """
    first, stop = max(0, int(first)), min(info.n_samples, int(stop))
    if stop <= first:
        return np.zeros((0, len(channels)))
    rows = None
    if info.path.suffix.lower() == ".npz":
        rows = read_sample_rows(info.path, first, stop)
    if rows is None:
        record = _read_whole(info.path, read_options)
        rows, names = record.acceleration[first:stop], record.channels
    else:
        names = info.channels
    if tuple(names) != tuple(channels):
        rows = rows[:, [list(names).index(c) for c in channels]]
    return np.asarray(rows, dtype=float)


def _edge_rows(info: FileInfo, channels, first: int, stop: int | None = None, read_options=None):
    """Rows of a neighbouring file for padding, or None when it cannot be read (then the
    chain of contiguous files breaks there; the blocks holding that file report it)."""
    try:
        return _read_rows(
            info, channels, first, info.n_samples if stop is None else stop, read_options
        )
    except (OSError, ValueError):
        return None


# ----------------------------------------------------------------------------------------
# faulty-channel sums per grid step
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _StepSums:
    """Sums over the samples of one file inside one grid step, per channel.

    ``sums[i, j]`` is the sum over the finite samples of ``u**i * tau**j`` (``i + j <= 4``)
    with ``u = x - offset`` and ``tau`` the time from the piece's centre in units of its
    half-length ``half_s``; ``centre_ns`` is the centre's time.
    """

    first_ns: int
    n_samples: int
    centre_ns: int
    half_s: float
    offset: np.ndarray
    sums: np.ndarray  # (5, 5, n_channels)
    leading_nan: np.ndarray
    trailing_nan: np.ndarray
    longest_nan: np.ndarray


def _step_sums(x: np.ndarray, first_ns: int, rate: float, chunk: int = 2048) -> _StepSums:
    n, n_channels = x.shape
    missing = np.isnan(x)
    any_missing = bool(missing.any())
    half = (n - 1) / 2.0
    scale = half if half > 0 else 1.0
    if any_missing:
        count = n - missing.sum(axis=0)
        with np.errstate(invalid="ignore"):
            offset = np.where(count > 0, np.nansum(x, axis=0) / np.maximum(count, 1), 0.0)
    else:
        offset = x.mean(axis=0) if n else np.zeros(n_channels)
    sums = np.zeros((5, 5, n_channels))
    # row chunks that stay in cache: sums[i, j] = sum_t u_t**i tau_t**j (finite samples)
    for lo in range(0, n, chunk):
        hi = min(n, lo + chunk)
        tau = (np.arange(lo, hi) - half) / scale
        basis = np.vander(tau, 5, increasing=True)  # (m, 5): 1, tau, ..., tau**4
        u = x[lo:hi] - offset
        if any_missing:
            weight = ~missing[lo:hi]
            u = np.where(weight, u, 0.0)
            power = weight.astype(float)
        else:
            power = np.ones_like(u)
        for i in range(5):
            sums[i, : 5 - i] += (power.T @ basis[:, : 5 - i]).T
            if i < 4:
                power = power * u
    leading = np.zeros(n_channels, dtype=np.int64)
    trailing = np.zeros(n_channels, dtype=np.int64)
    longest = np.zeros(n_channels, dtype=np.int64)
    for j in np.flatnonzero(missing.any(axis=0)) if any_missing else ():
        column = missing[:, j]
        if column.all():
            leading[j] = trailing[j] = longest[j] = n
            continue
        leading[j] = int(np.argmin(column))
        trailing[j] = int(np.argmin(column[::-1]))
        edges = np.diff(np.concatenate(([0], column.view(np.int8), [0])))
        longest[j] = int((np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)).max())
    half_s = half / rate if half > 0 else 1.0 / rate
    centre_ns = first_ns + int(round(half / rate * _NS))
    return _StepSums(first_ns, n, centre_ns, half_s, offset, sums, leading, trailing, longest)


def _block_statistics(pieces: Sequence[_StepSums], n_block: int, rate: float):
    """NaN fraction, longest NaN run [s], variance and kurtosis of the linearly detrended
    block made of *pieces* (in time order), as :func:`faulty_channels` computes them."""
    n_channels = pieces[0].offset.size
    centre_ns = (pieces[0].first_ns + pieces[-1].centre_ns * 2 - pieces[-1].first_ns) // 2
    # time sums about the block centre: t = d + h tau for each piece
    count = np.zeros(n_channels)
    sum_t = np.zeros(n_channels)
    sum_tt = np.zeros(n_channels)
    sum_x = np.zeros(n_channels)
    sum_xt = np.zeros(n_channels)
    for p in pieces:
        d = (p.centre_ns - centre_ns) / _NS
        h = p.half_s
        s = p.sums
        count += s[0, 0]
        sum_t += d * s[0, 0] + h * s[0, 1]
        sum_tt += d * d * s[0, 0] + 2 * d * h * s[0, 1] + h * h * s[0, 2]
        sum_x += s[1, 0] + p.offset * s[0, 0]
        sum_xt += d * s[1, 0] + h * s[1, 1] + p.offset * (d * s[0, 0] + h * s[0, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        t_mean = sum_t / count
        x_mean = sum_x / count
        sxx = sum_tt - count * t_mean * t_mean
        sxy = sum_xt - count * t_mean * x_mean
        slope = np.where(sxx > 0, sxy / np.where(sxx > 0, sxx, 1.0), 0.0)
        intercept = x_mean - slope * t_mean
    # power sums of the residual r = u - alpha - beta tau on each piece
    power = np.zeros((5, n_channels))
    binomial = [[math.comb(k, m) for m in range(k + 1)] for k in range(5)]
    for p in pieces:
        d = (p.centre_ns - centre_ns) / _NS
        alpha = intercept + slope * d - p.offset
        beta = slope * p.half_s
        for k in range(1, 5):
            for m in range(k + 1):
                line = np.zeros(n_channels)  # sum of u^(k-m) (alpha + beta tau)^m
                for ell in range(m + 1):
                    line += binomial[m][ell] * alpha ** (m - ell) * beta**ell * p.sums[k - m, ell]
                power[k] += binomial[k][m] * (-1) ** m * line
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = power[1] / count
        m2 = power[2] / count - mean**2
        m4 = (
            power[4] / count
            - 4 * mean * power[3] / count
            + 6 * mean**2 * power[2] / count
            - 3 * mean**4
        )
        m2 = np.maximum(m2, 0.0)
        kurtosis = np.where(m2 > 0, m4 / np.where(m2 > 0, m2, 1.0) ** 2, np.nan)
        variance = np.where(count > 0, m2, np.nan)
    kurtosis = np.where(count > 0, kurtosis, np.nan)
    # NaN runs across pieces
    longest = np.zeros(n_channels, dtype=np.int64)
    run = np.zeros(n_channels, dtype=np.int64)
    for p in pieces:
        whole = p.leading_nan >= p.n_samples
        longest = np.maximum(
            longest, np.where(whole, 0, np.maximum(run + p.leading_nan, p.longest_nan))
        )
        run = np.where(whole, run + p.n_samples, p.trailing_nan)
    longest = np.maximum(longest, run)
    nan_fraction = 1.0 - count / n_block if n_block else np.ones(n_channels)
    return nan_fraction, longest / rate, variance, kurtosis


# ----------------------------------------------------------------------------------------
# the conditioner
# ----------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class _ConditionedFile:
    first_out: int  # index of the first output sample on the analysis lattice
    samples: np.ndarray  # (n_out, n_channels), NaN columns where not bridgeable
    steps: dict  # grid step number -> list of _StepSums


class FileConditioner:
    """Conditioned blocks of a voyage, each file conditioned once (see the module notes).

    Parameters
    ----------
    files : sequence of FileInfo
        The voyage's files (``BlockPlan.files``, time order) or a stretch of them that
        covers the blocks asked for and, where they exist, one file on either side.
    grid : BlockGrid
    channels : tuple of str
        Channel order of the blocks.
    target_rate_hz : float
        Analysis rate; must divide the files' rate by a whole number > 1. [Hz]
    band_hz : (float or None, float or None) or None
        Band-pass edges. [Hz]
    max_gap_s : float
        As for :func:`~workbench.signals.block_builder.load_block` (blocks with a NaN-padded gap
        are built by it). [s]
    fault_options : mapping, optional
        Keyword arguments of :func:`~workbench.signals.moments.faulty_channels`.
    detrend : bool
        Without a lower band edge, remove a straight line from each block (with one, the
        band-pass has already removed it).
    read_options : mapping, optional
        Keyword arguments of :func:`data_contracts.read_accelerations` (file layout).
    """

    def __init__(
        self,
        files: Sequence[FileInfo],
        grid: BlockGrid,
        channels: Sequence[str],
        *,
        target_rate_hz: float,
        band_hz: tuple[float | None, float | None] | None,
        max_gap_s: float = 0.0,
        fault_options: Mapping | None = None,
        detrend: bool = True,
        read_options: Mapping | None = None,
    ) -> None:
        self.files = tuple(sorted(files, key=lambda i: i.start_time))
        self.grid = grid
        self.channels = tuple(channels)
        self.rate = float(self.files[0].sampling_rate_hz)
        self.target_rate_hz = float(target_rate_hz)
        self.factor = int(round(self.rate / self.target_rate_hz))
        if self.factor < 2 or abs(self.rate / self.target_rate_hz - self.factor) > 1e-9:
            raise ValueError(
                f"target_rate_hz={target_rate_hz:g} must divide {self.rate:g} Hz by a whole "
                "number above 1"
            )
        self.band_hz = None if band_hz is None else tuple(band_hz)
        self.max_gap_s = float(max_gap_s)
        self.fault_options = dict(fault_options or {})
        self.read_options = dict(read_options or {})
        self.detrend = bool(detrend)
        self.max_nan_run_s = float(
            self.fault_options.get("max_nan_run_s", MAX_INTERPOLATED_NAN_RUN_S)
        )
        self.padding = padding_samples(self.rate, self.target_rate_hz, self.band_hz)
        self._t0_ns = pd.Timestamp(grid.t0).as_unit("ns").value
        self._starts_ns = np.array([_start_ns(i) for i in self.files], dtype=np.int64)
        self._cache: dict[int, _ConditionedFile] = {}
        self.fallbacks = 0  # blocks built by load_block

    def reuse(self, conditioned: Mapping[str | Path, _ConditionedFile | None]) -> None:
        """Take files conditioned elsewhere (by :func:`condition_file`, e.g. in another
        worker) for the files of this conditioner with those paths; ``None`` values and
        paths not among its files are ignored (those files are conditioned here)."""
        index = {str(info.path): i for i, info in enumerate(self.files)}
        for path, value in conditioned.items():
            if value is not None and str(path) in index:
                self._cache[index[str(path)]] = value

    def conditioned_file(self, index: int) -> _ConditionedFile:
        """File *index* of :attr:`files` conditioned (padded with its contiguous
        neighbours' edges), with its faulty-channel step sums; cached."""
        return self._conditioned(index)

    # -- lattice helpers ------------------------------------------------------------------
    def _offset(self, index: int) -> float:
        """Raw samples from the grid origin to the file's first sample (may be fractional)."""
        return (self._starts_ns[index] - self._t0_ns) / _NS * self.rate

    def _contiguous(self, a: int, b: int) -> bool:
        """Files *a* and *b* (b = a + 1) abut on one sample lattice."""
        if a < 0 or b >= len(self.files):
            return False
        gap = self._offset(b) - (self._offset(a) + self.files[a].n_samples)
        return abs(gap) <= 1e-6 * self.rate or abs(gap) < 1e-3

    def _on_lattice(self, index: int) -> bool:
        offset = self._offset(index)
        return abs(offset - round(offset)) < 1e-3

    # -- conditioning of one file -----------------------------------------------------------
    def _raw_file(self, index: int) -> np.ndarray:
        info = self.files[index]
        if info.path.suffix.lower() == ".npz":
            record = read_accelerations(info.path, **self.read_options)
        else:  # parsed whole: the neighbours' conditioning reads it again
            record = _read_whole(info.path, self.read_options)
        if record.sampling_rate_hz != info.sampling_rate_hz or record.n_samples != info.n_samples:
            raise ValueError(f"{info.path}: file changed since it was planned")
        x = record.acceleration
        if record.channels != self.channels:
            x = x[:, [record.channels.index(c) for c in self.channels]]
        return x

    def _conditioned(self, index: int) -> _ConditionedFile:
        cached = self._cache.get(index)
        if cached is not None:
            return cached
        info = self.files[index]
        raw = self._raw_file(index)
        n = info.n_samples
        start = int(round(self._offset(index)))  # raw lattice index of the first sample
        f = self.factor
        parts = []
        before = 0
        if self._contiguous(index - 1, index):
            previous = self.files[index - 1]
            want = self.padding + start % f  # padded record starts on the analysis lattice
            tail = _edge_rows(
                previous, self.channels, previous.n_samples - want, None, self.read_options
            )
            if tail is not None:
                parts.append(tail)
                before = tail.shape[0]
        parts.append(raw)
        if self._contiguous(index, index + 1):
            head = _edge_rows(
                self.files[index + 1], self.channels, 0, self.padding + f, self.read_options
            )
            if head is not None:
                parts.append(head)
        steps = self._step_sums(index, raw, start)
        origin = start - before  # raw lattice index of the first padded sample
        lead = (-origin) % f  # samples before the first one on the analysis lattice
        parts[0] = parts[0][lead:]
        # one copy: the padded record as (n_channels, n_samples), filtered along its rows
        x = np.concatenate([p.T for p in parts], axis=1)
        bad = np.zeros(x.shape[0], dtype=bool)
        holes = np.flatnonzero(np.isnan(x).any(axis=1))
        if holes.size:
            bridged = interpolate_nan_runs(x[holes].T, self.rate, max_run_s=self.max_nan_run_s).T
            bad[holes] = np.isnan(bridged).any(axis=1)
            x[holes] = np.where(np.isnan(bridged), 0.0, bridged)  # unbridged: faulty there
        y = _decimate_channels_last(x, self.factor).T
        del x
        if self.band_hz is not None:
            y = bandpass(y, self.target_rate_hz, *self.band_hz)
        # analysis samples m * f with start <= m * f < start + n belong to this file
        first_out = -(-start // f)
        skip = first_out - (origin + lead) // f
        n_out = -(-(start + n) // f) - first_out
        samples = np.ascontiguousarray(y[skip : skip + n_out])
        samples[:, bad] = np.nan
        conditioned = _ConditionedFile(first_out, samples, steps)
        self._cache[index] = conditioned
        return conditioned

    def _step_sums(self, index: int, raw: np.ndarray, start: int) -> dict:
        """Faulty-channel sums of the file's pieces, one per grid step it touches."""
        step_samples = self.grid.step_s * self.rate
        n = raw.shape[0]
        steps: dict[int, list] = {}
        position = 0
        while position < n:
            number = math.floor((start + position) / step_samples + 1e-9)
            end = min(n, math.ceil((number + 1) * step_samples - 1e-9) - start)
            end = max(end, position + 1)
            first_ns = self._t0_ns + int(round((start + position) / self.rate * _NS))
            steps.setdefault(number, []).append(_step_sums(raw[position:end], first_ns, self.rate))
            position = end
        return steps

    def release_before(self, index: int) -> None:
        """Forget conditioned files before file *index* (blocks are taken in time order)."""
        for key in [k for k in self._cache if k < index]:
            del self._cache[key]

    # -- blocks -------------------------------------------------------------------------------
    def block(self, planned: PlannedBlock) -> AccelerationBlock:
        """The conditioned block *planned* (a block of this conditioner's voyage plan)."""
        built = None if planned.skipped_reason else self._from_files(planned)
        if built is None:
            self.fallbacks += 1
            return load_block(
                self.files,
                planned.block,
                self.grid,
                target_rate_hz=self.target_rate_hz,
                band_hz=self.band_hz,
                detrend=self.detrend,
                fault_options=self.fault_options,
                max_gap_s=self.max_gap_s,
                read_options=self.read_options,
            )
        return built

    def _from_files(self, planned: PlannedBlock) -> AccelerationBlock | None:
        index = {info.path: i for i, info in enumerate(self.files)}
        try:
            needed = [index[Path(p)] for p in planned.files]
        except KeyError:
            return None
        if not needed or not all(self._on_lattice(i) for i in needed):
            return None
        if any(not self._contiguous(a, a + 1) for a in needed[:-1]):
            return None
        block_start = (pd.Timestamp(planned.block_start).as_unit("ns").value - self._t0_ns) / _NS
        start_raw = block_start * self.rate
        n_raw = int(round(self.grid.length_s * self.rate))
        if abs(start_raw - round(start_raw)) > 1e-3 or round(start_raw) % self.factor:
            return None
        if n_raw % self.factor:
            return None
        start_raw = int(round(start_raw))
        first_index = needed[0]
        if self._offset(first_index) > start_raw + 0.5 or (
            self._offset(needed[-1]) + self.files[needed[-1]].n_samples < start_raw + n_raw - 0.5
        ):
            return None
        self.release_before(first_index)
        files = [self._conditioned(i) for i in needed]
        # faulty-channel check from the step sums
        step_samples = self.grid.step_s * self.rate
        if (
            abs(start_raw / step_samples - round(start_raw / step_samples)) > 1e-9
            or abs(n_raw / step_samples - round(n_raw / step_samples)) > 1e-9
        ):
            return None
        first_step = int(round(start_raw / step_samples))
        n_steps = int(round(n_raw / step_samples))
        pieces = []
        for number in range(first_step, first_step + n_steps):
            found = [p for f in files for p in f.steps.get(number, [])]
            if not found:
                return None
            pieces += sorted(found, key=lambda p: p.first_ns)
        if sum(p.n_samples for p in pieces) != n_raw:
            return None
        nan_fraction, longest, variance, kurtosis = _block_statistics(pieces, n_raw, self.rate)
        try:
            report = channel_verdicts(
                self.channels, nan_fraction, longest, variance, kurtosis, **self.fault_options
            )
        except CoherenceNeeded:
            return None  # a variance outlier's coherence needs the raw block: load_block

        faulty = report["faulty"].to_numpy()
        dropped = tuple(
            (str(c), str(r))
            for c, r in zip(report["channel"][faulty], report["reason"][faulty], strict=True)
        )
        notes = tuple(f"{c} dropped: {r}" for c, r in dropped)
        names = tuple(c for c, bad in zip(self.channels, faulty, strict=True) if not bad)
        file_names = tuple(Path(f).name for f in planned.files)
        if not names:
            return AccelerationBlock(
                planned.block,
                planned.block_start,
                planned.block_end,
                None,
                self.rate,
                (),
                dropped,
                file_names,
                "all channels faulty",
                notes,
                report,
            )
        kept = np.flatnonzero(~faulty)
        first_out = start_raw // self.factor
        n_out = n_raw // self.factor
        out = np.empty((n_out, kept.size))
        filled = 0
        for f in files:
            lo = max(first_out, f.first_out)
            hi = min(first_out + n_out, f.first_out + f.samples.shape[0])
            if hi <= lo:
                continue
            if lo - first_out != filled:
                return None
            out[lo - first_out : hi - first_out] = f.samples[lo - f.first_out : hi - f.first_out][
                :, kept
            ]
            filled = hi - first_out
        if filled != n_out or np.isnan(out).any():
            return None
        if self.detrend and (self.band_hz is None or self.band_hz[0] is None):
            out = linear_detrend(out)
        return AccelerationBlock(
            planned.block,
            planned.block_start,
            planned.block_end,
            out,
            self.target_rate_hz,
            names,
            dropped,
            file_names,
            "",
            notes,
            report,
        )


@dataclass(frozen=True)
class FileConditioning:
    """What :func:`condition_file` needs to condition one file on its own (picklable).

    Parameters
    ----------
    files : tuple of FileInfo
        The file and its neighbours in the voyage plan (one on either side where they
        exist): their edges pad the filters.
    index : int
        Position of the file in *files*.
    grid : BlockGrid
    channels : tuple of str
    settings : mapping
        Keyword arguments of :class:`FileConditioner` (``target_rate_hz``, ``band_hz``,
        ...).
    """

    files: tuple
    index: int
    grid: BlockGrid
    channels: tuple
    settings: Mapping


def condition_file(job: FileConditioning) -> _ConditionedFile:
    """One file conditioned once, for every block holding it: the value a
    :class:`FileConditioner` of those blocks takes with :meth:`FileConditioner.reuse`."""
    conditioner = FileConditioner(job.files, job.grid, job.channels, **dict(job.settings))
    return conditioner.conditioned_file(conditioner.files.index(job.files[job.index]))


def _start_ns(info: FileInfo) -> int:
    return pd.Timestamp(info.start_time).as_unit("ns").value
