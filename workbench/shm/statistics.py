"""The control-chart statistics behind :func:`~workbench.shm.chart.health_chart` and
:class:`~workbench.shm.monitor.HealthMonitor`, as plain array functions: EWMA and
one-sided CUSUM recursions (Page 1954), Hotelling's T² of the EWMA vector (Lowry et al.
1992), CUSUM decision intervals for a false-alarm rate, long-run standard deviations of
autocorrelated residuals, and the empirical limit for a target up-crossing rate.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

#: Standardised residuals at least this far out are wrong poles, not the Gaussian core of
#: the identification error (P(|N(0, 1)| >= 3.5) = 0.05 %). [-]
OUTLIER_SIGMA = 3.5

__all__ = [
    "ewma_hold",
    "ewma_step",
    "cusum_step",
    "cusum_hold",
    "long_run_std",
    "InControlResiduals",
    "cusum_limits",
    "hotelling",
    "upcrossings_per_day",
    "trimmed_location_scale",
]


def ewma_hold(
    values: np.ndarray, ewma_lambda: float, *, ceiling: float | None = None
) -> np.ndarray:
    """Column-wise EWMA that holds its value where an input is missing.

    z_k = z_{k-1} + λ (x_k - z_{k-1}) where x_k is finite, z_k = z_{k-1} otherwise;
    z_{-1} = 0 (the in-control mean of standardised residuals). With *ceiling*, z_k is
    reflected at it, z_k = min(z_k, ceiling) (a one-sided EWMA for decreases).
    """
    x = np.asarray(values, dtype=float)
    out = np.empty_like(x)
    z = np.zeros(x.shape[1:])
    for k in range(x.shape[0]):
        z = ewma_step(z, x[k], ewma_lambda, ceiling=ceiling)
        out[k] = z
    return out


def ewma_step(
    z: np.ndarray, x: np.ndarray, ewma_lambda: float, *, ceiling: float | None = None
) -> np.ndarray:
    """One step of :func:`ewma_hold` (the batch and the incremental chart share it)."""
    z = z + ewma_lambda * np.nan_to_num(x - z, nan=0.0)  # missing: no update
    return z if ceiling is None else np.minimum(z, ceiling)


def cusum_step(cusum: np.ndarray, x: np.ndarray, allowance: np.ndarray) -> np.ndarray:
    """One step of a lower one-sided CUSUM per column (Page 1954):
    S_k = max(0, S_{k-1} - x_k - K); S_k = S_{k-1} where x_k is missing.

    *x* are standardised residuals (in-control mean 0); *allowance* K is the reference
    value, half of the decrease to detect in the same units.
    """
    increment = np.nan_to_num(-np.asarray(x, dtype=float) - allowance, nan=0.0)
    return np.maximum(cusum + increment, 0.0)


def cusum_hold(values: np.ndarray, allowance: np.ndarray) -> np.ndarray:
    """:func:`cusum_step` along axis 0 of *values* from S_{-1} = 0 (columns independent)."""
    x = np.asarray(values, dtype=float)
    out = np.empty_like(x)
    s = np.zeros(x.shape[1:])
    for k in range(x.shape[0]):
        s = cusum_step(s, x[k], allowance)
        out[k] = s
    return out


def long_run_std(values: np.ndarray, lags: int) -> np.ndarray:
    """Long-run standard deviation of each column, Bartlett-weighted autocovariances up to
    *lags* (Newey and West 1987), NaN-aware: √(γ₀ + 2 Σ_l (1 - l/(L+1)) γ_l).

    For residuals of 20-min blocks every 5 min (errors are means of four 5-min segments,
    correlated 0.75, 0.5, 0.25 at lags 1-3) it is about twice the standard deviation.
    """
    x = np.asarray(values, dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        centred = x - np.nanmean(x, axis=0)
    valid = np.isfinite(centred)
    filled = np.where(valid, centred, 0.0)
    n_valid = valid.sum(axis=0)
    gamma0 = (filled**2).sum(axis=0) / np.maximum(n_valid, 1)
    variance = gamma0.copy()
    for lag in range(1, min(lags, x.shape[0] - 1) + 1):
        pairs = (valid[lag:] & valid[:-lag]).sum(axis=0)
        gamma = (filled[lag:] * filled[:-lag]).sum(axis=0) / np.maximum(pairs, 1)
        variance += 2.0 * (1.0 - lag / (lags + 1.0)) * gamma
    return np.sqrt(np.maximum(variance, gamma0 * 0.25))  # floor: no negative estimates


@dataclass(frozen=True)
class InControlResiduals:
    """How :func:`cusum_limits` simulates the in-control residuals of a chart.

    Attributes
    ----------
    segments : int
        Independent segment errors averaged into a block's error (overlapping blocks: the
        block length over the step), so neighbouring blocks correlate 1 - l/segments at
        lag l.
    variance : float
        Variance the Gaussian core is scaled to after standardisation.
    outlier_rate : float
        Share of wrong poles, far off either way (clipped like the chart's).
    missing_rate : float
        Share of missing estimates (the CUSUM holds).
    offset_std : ndarray, optional
        Standard deviation of each mode's persistent offset over a simulated day (the
        model's own error); default none.
    trimmed : bool
        Standardise with the chart's :func:`trimmed_location_scale` (else the median
        and 1.4826 MAD).
    """

    segments: int
    variance: float = 1.0
    outlier_rate: float = 0.0
    missing_rate: float = 0.0
    offset_std: np.ndarray | None = None
    trimmed: bool = True


def cusum_limits(
    allowance: np.ndarray,
    residuals: InControlResiduals,
    *,
    reference_blocks: int,
    blocks_per_day: float,
    false_alarms_per_day: float,
    replicates: int,
    clip_sigma: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Decision intervals H_j of the per-mode CUSUMs for a target false-alarm rate.

    The in-control residuals of overlapping blocks are simulated as they arise (the
    italic names are fields of *residuals*, :class:`InControlResiduals`): each
    block's error is the mean of *segments* independent segment errors (so neighbouring
    blocks correlate 1 - l/segments at lag l and the long-run variance is *segments*
    times the variance). A share *outlier_rate* of them are wrong poles, far off either
    way and clipped to ±*clip_sigma* like the chart's, and a share *missing_rate* are
    missing (the CUSUM holds). Each replicate is a reference period of
    *reference_blocks*, whose location and scale standardise it (the chart's own:
    :func:`trimmed_location_scale`, or the median and 1.4826 MAD with ``trimmed=False``,
    with their estimation error, Jones-Farmer et al. 2014), the Gaussian core then
    scaled to *variance*, followed by one day to which mode j adds a persistent offset
    N(0, *offset_std*_j²) (the model's own error, one draw per day); the CUSUM runs
    through both. H_j is the exp(-rate/p) quantile of the daily maximum of mode j's
    CUSUM over all p x *replicates* simulated series, so that the p modes together pass
    a day without false alarm with probability exp(-rate) (Šidák's split; the modes'
    charts are about independent, their residuals being errors of different poles).
    """
    allowance = np.asarray(allowance, dtype=float)
    segments, variance = residuals.segments, residuals.variance
    outlier_rate, missing_rate = residuals.outlier_rate, residuals.missing_rate
    offset_std, trimmed = residuals.offset_std, residuals.trimmed
    p = allowance.size
    day = int(round(blocks_per_day))
    n = reference_blocks + day
    window = np.lib.stride_tricks.sliding_window_view
    u = rng.standard_normal((n + segments - 1, replicates * p))
    x = window(u, segments, axis=0).mean(-1)  # (n, series), variance 1/segments
    if outlier_rate > 0:  # wrong poles: far off either way, clipped like the chart's
        wrong = rng.random(x.shape) < outlier_rate
        x = np.where(wrong, rng.choice([-1.0, 1.0], x.shape) * 1e3 * clip_sigma, x)
    if missing_rate > 0:  # no estimate: the CUSUM holds
        x = np.where(rng.random(x.shape) < missing_rate, np.nan, x)
    estimate = trimmed_location_scale if trimmed else _robust_location_scale
    location, scale = estimate(x[:reference_blocks])
    x = (x - location) / scale * math.sqrt(variance)
    offset_std = np.zeros(p) if offset_std is None else np.asarray(offset_std, dtype=float)
    offset = rng.standard_normal(x.shape[1])  # one persistent model error per day
    level = math.exp(-false_alarms_per_day / p)
    limits = np.empty(p)
    for j in range(p):
        day_x = x[reference_blocks:] + offset_std[j] * offset
        day_x = np.clip(np.concatenate([x[:reference_blocks], day_x]), -clip_sigma, clip_sigma)
        daily_max = cusum_hold(day_x, np.full(x.shape[1], allowance[j]))[reference_blocks:].max(0)
        limits[j] = float(np.quantile(daily_max, level))
    return limits


def hotelling(ewma: np.ndarray, covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T² = zᵀ Σ⁻¹ z per row and each component's share z_j (Σ⁻¹ z)_j (they sum to T²)."""
    precision = np.linalg.pinv(covariance)
    weighted = ewma @ precision
    parts = ewma * weighted
    return parts.sum(axis=1), parts


def upcrossings_per_day(statistic: np.ndarray, limit: float, blocks_per_day: float) -> float:
    """Times *statistic* goes from <= *limit* to above it (or starts above it), per day.

    A 2-D *statistic* holds independent series in its columns (time along axis 0).
    """
    above = np.asarray(statistic) > limit
    if above.ndim == 1:
        above = above[:, None]
    n_up = np.count_nonzero(above[1:] & ~above[:-1]) + np.count_nonzero(above[0])
    return float(n_up) / (above.size / blocks_per_day)


def _robust_location_scale(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Median and 1.4826 MAD along axis 0, ignoring NaN (per mode, per replicate)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns give NaN
        location = np.nanmedian(values, axis=0)
        scale = 1.4826 * np.nanmedian(np.abs(values - location), axis=0)
    return location, scale


def trimmed_location_scale(
    values: np.ndarray, cut: float = OUTLIER_SIGMA
) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation along axis 0 of the values within *cut* robust standard
    deviations (1.4826 MAD) of the median, NaN-aware; the standard deviation is divided by
    that of N(0, 1) truncated at ±*cut* so a Gaussian core is estimated without bias.

    One step of a trimmed (Huber-type "skipped") estimator: the wrong poles beyond *cut*
    are dropped as the median and MAD would ignore them, while the Gaussian core is
    estimated with nearly the full efficiency of the mean and standard deviation (the MAD
    has 37 %; on residuals of overlapping blocks its error alone raised the simulated
    CUSUM limits, ``benchmarks/results/health.txt``, "CALIBRATED CUSUM LIMITS").
    """
    median, mad = _robust_location_scale(values)
    with np.errstate(invalid="ignore"):
        inside = np.abs(values - median) <= cut * mad
    core = np.where(inside, values, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        location = np.nanmean(core, axis=0)
        scale = np.nanstd(core, axis=0, ddof=1) / math.sqrt(truncated_normal_variance(cut))
    return location, scale


def truncated_normal_variance(cut: float) -> float:
    """Variance of N(0, 1) truncated to ±*cut*: 1 - 2 c φ(c) / (2 Φ(c) - 1)."""
    density = math.exp(-0.5 * cut * cut) / math.sqrt(2.0 * math.pi)
    inside = math.erf(cut / math.sqrt(2.0))
    return 1.0 - 2.0 * cut * density / inside


def _moving_block_bootstrap(
    rows: np.ndarray, n_out: int, length: int, rng: np.random.Generator
) -> np.ndarray:
    """Concatenated random runs of *length* consecutive rows of *rows* (Künsch 1989)."""
    n = rows.shape[0]
    length = min(length, n)
    n_runs = -(-n_out // length)
    starts = rng.integers(0, n - length + 1, n_runs)
    index = (starts[:, None] + np.arange(length)[None, :]).ravel()[:n_out]
    return rows[index]


def _limit_for_rate(statistic: np.ndarray, rate: float, blocks_per_day: float) -> float:
    """Smallest limit whose upcrossing rate in *statistic* is at most *rate* per day."""
    candidates = np.quantile(np.ravel(statistic), np.linspace(0.5, 1.0, 2001))
    for h in candidates:
        if upcrossings_per_day(statistic, h, blocks_per_day) <= rate:
            return float(h)
    return float(candidates[-1])
