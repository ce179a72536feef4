"""Significance of correlations between autocorrelated block series.

Blocks overlap (a 20-min block every 5 min shares 75 % of its data with the next), so a
mode's frequency and the ship's speed are both autocorrelated along the voyage and the
naive t-test of Pearson's r, which takes every block as independent, is far too
optimistic. :func:`effective_sample_size` estimates the number of independent pairs from
the two series' autocorrelations (Bartlett's formula, as used for climate series by
Bretherton et al. 1999), :func:`effective_p_value` tests r with it, and
:func:`effective_significance` adds both to a table of
:func:`~workbench.stats.correlation.correlation_table`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from scipy import special as _special

__all__ = ["effective_p_value", "effective_sample_size", "effective_significance"]


def _autocorrelation(values: np.ndarray, valid: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation at lags 0..max_lag of a series on a regular grid with gaps
    (``valid`` False): the lagged products of the deviations from the mean are averaged
    over the pairs present at each lag, then divided by the variance."""
    deviation = np.where(valid, values - values[valid].mean(), 0.0)
    size = 1 << int(np.ceil(np.log2(2 * len(deviation) - 1)))

    def lagged_sums(series):
        spectrum = np.fft.rfft(series, size)
        return np.fft.irfft(spectrum * np.conj(spectrum), size)[: max_lag + 1]

    covariance = lagged_sums(deviation)
    pairs = np.rint(lagged_sums(valid.astype(float)))
    if covariance[0] <= 0.0:
        return np.full(max_lag + 1, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_products = np.where(pairs > 0, covariance / pairs, 0.0)
    return mean_products / mean_products[0]


def effective_sample_size(
    x: np.ndarray,
    y: np.ndarray,
    *,
    positions: np.ndarray | None = None,
    max_lag: int | None = None,
) -> float:
    """Effective number of independent pairs behind the correlation of two autocorrelated
    series.

    Parameters
    ----------
    x, y : ndarray, shape (n,)
        The two series, NaN where missing; pairs where both are finite are used.
    positions : ndarray of int, shape (n,), optional
        Position of each value on a regular grid (e.g. the block number); default
        ``0 .. n-1``. Gaps in the grid count as missing values, so lags stay lags in time.
    max_lag : int, optional
        Largest lag summed; default ``N // 5`` (Pyper and Peterman [3]_), N the number of
        pairs.

    Returns
    -------
    float
        N_eff in [2, N] (NaN for fewer than 3 pairs or a constant series).

    Notes
    -----
    Bartlett's large-sample variance of r between two series with autocorrelations
    ρ_x(k) and ρ_y(k), both uncorrelated with each other, gives the effective sample size
    [1]_ [2]_ [3]_

    .. math:: \\frac{1}{N_{eff}} = \\frac{1}{N}
              + \\frac{2}{N} \\sum_{k=1}^{M} \\frac{N - k}{N} ρ_x(k) ρ_y(k)

    Overlapping blocks (20 min, a new one every 5 min) share 75 % of their data, so block
    averages and modal estimates of neighbouring blocks are strongly correlated and
    N_eff is a fraction of N. The t-test of r then uses N_eff - 2 degrees of freedom
    (:func:`effective_p_value`). For two AR(1) series the sum gives Bretherton et al.'s
    N_eff / N = (1 - ρ_x ρ_y) / (1 + ρ_x ρ_y) [2]_ (eq. 31).

    References
    ----------
    .. [1] M. S. Bartlett, "Some aspects of the time-correlation problem in regard to
       tests of significance", J. R. Stat. Soc. 98(3), 536-543, 1935. doi:10.2307/2342284
    .. [2] C. S. Bretherton, M. Widmann, V. P. Dymnikov, J. M. Wallace, I. Bladé, "The
       effective number of spatial degrees of freedom of a time-varying field", J. Climate
       12(7), 1990-2009, 1999. doi:10.1175/1520-0442(1999)012<1990:TENOSD>2.0.CO;2
    .. [3] B. J. Pyper, R. M. Peterman, "Comparison of methods to account for
       autocorrelation in correlation analyses of fish data", Can. J. Fish. Aquat. Sci.
       55(9), 2127-2140, 1998. doi:10.1139/f98-104
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"x and y must be 1-D of equal length, got {x.shape} and {y.shape}")
    if positions is None:
        positions = np.arange(len(x))
    positions = np.asarray(positions, dtype=np.int64)
    if positions.shape != x.shape:
        raise ValueError(f"positions has shape {positions.shape}, x has {x.shape}")
    both = np.isfinite(x) & np.isfinite(y)
    n = int(both.sum())
    if n < 3:
        return float("nan")
    grid = positions[both] - positions[both].min()
    if len(np.unique(grid)) != n:
        raise ValueError("positions must be unique")
    length = int(grid.max()) + 1
    gx = np.zeros(length)
    gy = np.zeros(length)
    valid = np.zeros(length, dtype=bool)
    gx[grid], gy[grid], valid[grid] = x[both], y[both], True
    if max_lag is None:
        max_lag = n // 5
    max_lag = int(min(max(max_lag, 0), length - 1))
    if max_lag < 0 or np.ptp(x[both]) == 0.0 or np.ptp(y[both]) == 0.0:
        return float("nan")
    rho_x = _autocorrelation(gx, valid, max_lag)
    rho_y = _autocorrelation(gy, valid, max_lag)
    lags = np.arange(1, max_lag + 1)
    total = np.sum((n - lags) / n * rho_x[1:] * rho_y[1:])
    inverse = 1.0 / n + 2.0 / n * total
    return float(np.clip(1.0 / inverse, 2.0, n)) if inverse > 0 else float(n)


def effective_p_value(r: np.ndarray, n_effective: np.ndarray) -> np.ndarray:
    """Two-sided p-value of H0: ρ = 0 from r with N_eff - 2 degrees of freedom (t-test as in
    :func:`~workbench.stats.correlation.pairwise_pearson`, N replaced by the effective sample size)."""
    r = np.asarray(r, dtype=float)
    dof = np.asarray(n_effective, dtype=float) - 2.0
    with np.errstate(invalid="ignore", divide="ignore"):
        t = r * np.sqrt(dof / ((1.0 - r) * (1.0 + r)))
        p = 2.0 * _special.stdtr(dof, -np.abs(t))
    p = np.where(np.abs(r) == 1.0, 0.0, p)
    return np.where(np.isfinite(r) & (dof > 0), p, np.nan)


def effective_significance(
    table: pd.DataFrame,
    joined: pd.DataFrame,
    case_blocks: Mapping[str, np.ndarray],
    *,
    alpha: float = 0.05,
    min_blocks: int = 10,
) -> pd.DataFrame:
    """*table* (of :func:`~workbench.stats.correlation.correlation_table`) with significance that respects
    autocorrelated blocks, as a new table.

    Adds ``n_effective`` (:func:`effective_sample_size` on the block grid, per pair and
    case), ``p_effective`` (:func:`effective_p_value`), ``significant_effective``
    (``p_effective < alpha``) and ``small`` (fewer than *min_blocks* blocks or N_eff < 5:
    too little to judge). The naive ``p_value`` (blocks taken as independent) is kept
    beside.

    Parameters
    ----------
    table : DataFrame
        Pairs (x, y, case, r, n, ...) computed on *joined*.
    joined : DataFrame
        The block table correlated (:func:`~workbench.stats.correlation.joined_blocks`), indexed by block number.
    case_blocks : mapping of str to ndarray of bool
        Rows of *joined* in each case of *table* (:func:`~workbench.stats.correlation.case_masks`).
    """
    table = table.copy()
    positions = joined.index.to_numpy(dtype=np.int64)
    n_effective = np.full(len(table), np.nan)
    for case, rows in table.groupby("case", sort=False).groups.items():
        mask = case_blocks[case]
        for row in rows:
            x = joined[table.at[row, "x"]].to_numpy(dtype=float)[mask]
            y = joined[table.at[row, "y"]].to_numpy(dtype=float)[mask]
            n_effective[row] = effective_sample_size(x, y, positions=positions[mask])
    table["n_effective"] = n_effective
    table["p_effective"] = effective_p_value(table["r"].to_numpy(float), n_effective)
    table["significant_effective"] = np.nan_to_num(table["p_effective"], nan=1.0) < alpha
    table["small"] = (table["n"] < min_blocks) | ~(np.nan_to_num(n_effective) >= 5.0)
    return table
