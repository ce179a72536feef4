"""The faulty-channel statistics of a block (NaN fraction and runs, variance and kurtosis of
the linearly detrended samples, as :func:`~workbench.signals.moments.faulty_channels`
computes them) assembled exactly from power sums taken once per file and grid step."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .conditioning import constant_runs, line_from_sums

_NS = 1_000_000_000


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
    # runs of one repeated value (:func:`~workbench.signals.conditioning.constant_runs`)
    # and the values at the piece's ends, which join them to the neighbouring pieces'
    first_value: np.ndarray
    last_value: np.ndarray
    leading_flat: np.ndarray
    trailing_flat: np.ndarray
    longest_flat: np.ndarray


#: Rows of a file piece summed at a time by :func:`_step_sums` (its five power arrays of
#: 19 channels, 3 MB, stay in the CPU cache). [-]
_SUM_ROWS = 4096
#: Rows of the subsample whose mean is a piece's offset (see :func:`_offsets`). [-]
_OFFSET_ROWS = 4096


def _offsets(x: np.ndarray) -> np.ndarray:
    """Per channel, the mean of the finite samples of an evenly spaced subsample of about
    :data:`_OFFSET_ROWS` rows of *x* (of all its finite samples where the subsample has
    none; 0 without any finite sample).

    The offset only keeps the power sums about it well conditioned (the statistics are
    assembled about the block's own detrended mean, whatever the offset), so a mean
    within a few hundredths of a standard deviation of the channel's does; it costs a
    fraction of a pass over the piece.
    """
    sample = x[:: max(1, x.shape[0] // _OFFSET_ROWS)]
    finite = ~np.isnan(sample)
    count = finite.sum(axis=0)
    total = np.where(finite, sample, 0.0).sum(axis=0)
    offset = np.where(count > 0, total / np.maximum(count, 1), 0.0)
    for c in np.flatnonzero(count == 0):  # finite samples only between the subsample's
        column = x[:, c]
        column = column[~np.isnan(column)]
        if column.size:
            offset[c] = column.mean()
    return offset


def _step_sums(x: np.ndarray, first_ns: int, rate: float, chunk: int = _SUM_ROWS) -> _StepSums:
    """The sums of one piece *x* (n, n_channels) of a file inside one grid step.

    Row chunks that stay in the CPU cache: per chunk, ``u = x - offset`` and its powers
    are written once (contiguous, one array per power) and summed against the chunk's
    time powers with one stacked matrix product. A channel with missing samples in a
    chunk is summed again for that chunk over its finite samples alone (NaN read as
    absent: ``u`` and the weight set to 0 there); the time sums of the weight of a chunk
    without missing samples are the chunk's time sums.
    """
    n, n_channels = x.shape
    half = (n - 1) / 2.0
    scale = half if half > 0 else 1.0
    offset = _offsets(x) if n else np.zeros(n_channels)
    sums = np.zeros((5, 5, n_channels))  # [i, j]: sum of u**i tau**j
    rows = max(1, min(chunk, n))
    powers = np.empty((5, rows, n_channels))  # u**0 .. u**4 (the first row left unused)
    basis = np.empty((5, rows))  # tau**0 .. tau**4
    gaps = np.zeros(n_channels, dtype=bool)  # channels with a missing sample
    with np.errstate(invalid="ignore", over="ignore"):
        for lo in range(0, n, rows):
            hi = min(n, lo + rows)
            m = hi - lo
            u = powers[1, :m]
            np.subtract(x[lo:hi], offset, out=u)
            np.multiply(u, u, out=powers[2, :m])
            np.multiply(powers[2, :m], u, out=powers[3, :m])
            np.multiply(powers[3, :m], u, out=powers[4, :m])
            tau = basis[:, :m]
            tau[0] = 1.0
            np.subtract(np.arange(lo, hi, dtype=float), half, out=tau[1])
            tau[1] /= scale
            for j in range(2, 5):
                np.multiply(tau[j - 1], tau[1], out=tau[j])
            part = np.matmul(tau, powers[1:, :m])  # (4, 5, n_channels): [i - 1, j]
            missing = np.isnan(part[0, 0])
            np.add(sums[0], tau.sum(axis=1)[:, None], out=sums[0], where=~missing)
            for c in np.flatnonzero(missing):  # this chunk again over the finite samples
                column = x[lo:hi, c] - offset[c]
                absent = np.isnan(column)
                column[absent] = 0.0
                power = (~absent).astype(float)
                for i in range(5):
                    if i:
                        power = power * column
                    total = tau @ power
                    if i:
                        part[i - 1, :, c] = total
                    else:
                        sums[0, :, c] += total
            gaps |= missing
            sums[1:] += part
    for i in range(5):  # only i + j <= 4 are sums of the piece's statistics
        sums[i, 5 - i :] = 0.0
    leading = np.zeros(n_channels, dtype=np.int64)
    trailing = np.zeros(n_channels, dtype=np.int64)
    longest = np.zeros(n_channels, dtype=np.int64)
    for j in np.flatnonzero(gaps):
        column = np.isnan(x[:, j])
        if column.all():
            leading[j] = trailing[j] = longest[j] = n
            continue
        leading[j] = int(np.argmin(column))
        trailing[j] = int(np.argmin(column[::-1]))
        edges = np.diff(np.concatenate(([0], column.view(np.int8), [0])))
        longest[j] = int((np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)).max())
    half_s = half / rate if half > 0 else 1.0 / rate
    centre_ns = first_ns + int(round(half / rate * _NS))
    flat = constant_runs(x)
    ends = (x[0].copy(), x[-1].copy()) if n else (np.full(n_channels, np.nan),) * 2
    return _StepSums(
        first_ns, n, centre_ns, half_s, offset, sums, leading, trailing, longest, *ends, *flat
    )


def _block_flat_runs(pieces: Sequence[_StepSums], rate: float) -> np.ndarray:
    """Longest run of one repeated value [s] of the block made of *pieces* (contiguous, in
    time order), as :func:`~workbench.signals.conditioning.constant_runs` finds it on the
    whole block."""
    n_channels = pieces[0].offset.size
    longest = np.zeros(n_channels, dtype=np.int64)
    run = np.zeros(n_channels, dtype=np.int64)
    last = np.full(n_channels, np.nan)
    for p in pieces:
        joined = np.where(p.first_value == last, run + p.leading_flat, p.leading_flat)
        longest = np.maximum(longest, np.maximum(joined, p.longest_flat))
        run = np.where(p.leading_flat >= p.n_samples, joined, p.trailing_flat)
        last = p.last_value
    return np.maximum(longest, run) / rate


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
    slope, intercept = line_from_sums(count, sum_t, sum_tt, sum_x, sum_xt)
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
