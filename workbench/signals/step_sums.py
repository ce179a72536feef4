"""The faulty-channel statistics of a block (NaN fraction and runs, variance and kurtosis of
the linearly detrended samples, as :func:`~workbench.signals.moments.faulty_channels`
computes them) assembled exactly from power sums taken once per file and grid step."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .conditioning import line_from_sums

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


def _step_sums(x: np.ndarray, first_ns: int, rate: float, chunk: int = 2048) -> _StepSums:
    n, n_channels = x.shape
    missing = np.isnan(x)
    any_missing = bool(missing.any())
    half = (n - 1) / 2.0
    scale = half if half > 0 else 1.0
    if any_missing:
        count = n - missing.sum(axis=0)
        with np.errstate(invalid="ignore"):
            # the sum of the finite samples: np.nansum's value (NaN read as 0, same order),
            # without its copy of the whole file
            total = np.sum(x, axis=0, where=~missing)
            offset = np.where(count > 0, total / np.maximum(count, 1), 0.0)
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
