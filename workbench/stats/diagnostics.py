"""Residual diagnostics of a regression: autocorrelation and normality.

:func:`residual_diagnostics` summarises residuals taken in time (block) order: the
Durbin-Watson statistic and lag-1 autocorrelation (serial correlation makes the
regression's p-values and intervals too optimistic), and the Shapiro-Wilk and Jarque-Bera
tests of normality (the t and F tests assume normal errors). The figure is drawn by
:func:`workbench.reporting.diagnostics_plot.plot_residual_diagnostics`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy import stats as _scipy_stats

__all__ = ["ResidualDiagnostics", "durbin_watson", "residual_diagnostics"]


def _finite_residuals(residuals, blocks) -> tuple[np.ndarray, np.ndarray | None]:
    """The finite residuals (flattened) and the block numbers that go with them."""
    e = np.asarray(residuals, dtype=float).ravel()
    finite = np.isfinite(e)
    if blocks is not None:
        blocks = np.asarray(blocks, dtype=float).ravel()
        if blocks.shape != e.shape:
            raise ValueError(f"blocks has shape {blocks.shape}; residuals have {e.shape}")
        blocks = blocks[finite]
    return e[finite], blocks


def _run_pairs(e: np.ndarray, blocks) -> np.ndarray:
    """Mask of the consecutive pairs (t-1, t) of *e* that lie in one contiguous run of
    blocks (block numbers differing by 1); all pairs when *blocks* is None."""
    if blocks is None:
        return np.ones(max(e.size - 1, 0), dtype=bool)
    return np.diff(np.asarray(blocks, dtype=float)) == 1


def durbin_watson(residuals, blocks=None) -> float:
    """Durbin-Watson statistic of residuals in time order (NaN left out).

    Parameters
    ----------
    residuals : array_like
        Residuals in block order.
    blocks : array_like of int, optional
        Block number of each residual. Differences are then taken only between residuals
        of consecutive blocks (within contiguous runs): across a gap (missing blocks,
        another operating case) neighbouring residuals are not neighbours in time.

    Notes
    -----
    d = Σ_{t≥2} (e_t - e_{t-1})² / Σ_t e_t², about 2 (1 - ρ₁) for lag-1 autocorrelation ρ₁:
    2 for independent residuals, towards 0 for positive and 4 for negative serial
    correlation [1]_. With *blocks* the numerator sums over pairs inside runs only and is
    scaled by (n - 1) / (number of pairs), so d keeps its meaning (2 for white residuals)
    when runs are short.
    One contiguous run gives the textbook statistic
    (:func:`statsmodels.stats.stattools.durbin_watson`).

    References
    ----------
    .. [1] J. Durbin, G. S. Watson, "Testing for serial correlation in least squares
       regression. I", Biometrika 37(3/4), 409-428, 1950. doi:10.2307/2332391
    """
    e, blocks = _finite_residuals(residuals, blocks)
    total = float(e @ e)
    pairs = _run_pairs(e, blocks)
    if e.size < 2 or total == 0.0 or not pairs.any():
        return math.nan
    if pairs.all():  # one contiguous run: the textbook statistic
        from statsmodels.stats.stattools import durbin_watson as _durbin_watson

        return float(_durbin_watson(e))
    difference = np.diff(e)[pairs]
    value = float(difference @ difference) / total
    if blocks is not None:
        value *= (e.size - 1) / int(pairs.sum())
    return value


@dataclass(frozen=True)
class ResidualDiagnostics:
    """Summary of regression residuals (see :func:`residual_diagnostics`).

    Parameters
    ----------
    n : int
        Finite residuals.
    mean, std : float
        Mean and standard deviation (ddof 1). [response unit]
    skewness, excess_kurtosis : float
        Sample skewness and excess kurtosis (0 for a normal distribution).
    durbin_watson : float
        Durbin-Watson statistic (2: no lag-1 autocorrelation).
    lag1_autocorrelation : float
        Correlation of consecutive residuals.
    shapiro_statistic, shapiro_p_value : float
        Shapiro-Wilk W and p-value (NaN for n < 3 or n > 5000).
    jarque_bera_statistic, jarque_bera_p_value : float
        Jarque-Bera statistic and asymptotic χ²₂ p-value.
    alpha : float
        Level used for :attr:`normal` and :attr:`independent`.
    """

    n: int
    mean: float
    std: float
    skewness: float
    excess_kurtosis: float
    durbin_watson: float
    lag1_autocorrelation: float
    shapiro_statistic: float
    shapiro_p_value: float
    jarque_bera_statistic: float
    jarque_bera_p_value: float
    alpha: float = 0.05

    @property
    def normality_p_value(self) -> float:
        """Shapiro-Wilk p-value where defined (n ≤ 5000), else Jarque-Bera's."""
        if math.isfinite(self.shapiro_p_value):
            return self.shapiro_p_value
        return self.jarque_bera_p_value

    @property
    def normal(self) -> bool:
        """Normality not rejected at :attr:`alpha`."""
        p = self.normality_p_value
        return bool(math.isfinite(p) and p >= self.alpha)

    @property
    def independent(self) -> bool:
        """Durbin-Watson within 1.5-2.5, the usual rule of thumb for no serious lag-1
        autocorrelation."""
        return bool(math.isfinite(self.durbin_watson) and 1.5 <= self.durbin_watson <= 2.5)

    def summary(self) -> str:
        """Three lines of text: autocorrelation, normality, moments."""
        test = "Shapiro-Wilk" if math.isfinite(self.shapiro_p_value) else "Jarque-Bera"
        statistic = (
            f"W = {self.shapiro_statistic:.4f}"
            if test == "Shapiro-Wilk"
            else f"JB = {self.jarque_bera_statistic:.3f}"
        )
        return "\n".join(
            [
                f"Durbin-Watson = {self.durbin_watson:.3f} (lag-1 autocorrelation "
                f"{self.lag1_autocorrelation:+.3f}; "
                f"{'no serious' if self.independent else 'SERIAL'} correlation)",
                f"Normality: {test} {statistic}, p = {self.normality_p_value:.4g} "
                f"({'not rejected' if self.normal else 'REJECTED'} at {self.alpha:g}); "
                f"Jarque-Bera p = {self.jarque_bera_p_value:.4g}",
                f"Residuals: n = {self.n}, mean = {self.mean:.3g}, sd = {self.std:.3g}, "
                f"skewness = {self.skewness:.3f}, excess kurtosis = {self.excess_kurtosis:.3f}",
            ]
        )

    def to_dict(self) -> dict:
        """JSON-serialisable values (non-finite numbers become ``None``)."""
        out = {}
        for key, value in asdict(self).items():
            if isinstance(value, float) and not math.isfinite(value):
                value = None
            out[key] = value
        out["normal"] = self.normal
        out["independent"] = self.independent
        return out


def residual_diagnostics(residuals, *, alpha: float = 0.05, blocks=None) -> ResidualDiagnostics:
    """Durbin-Watson, lag-1 autocorrelation and normality tests of residuals.

    Parameters
    ----------
    residuals : array_like
        Residuals in time (block) order; NaN entries are left out.
    alpha : float
        Level for the :attr:`~ResidualDiagnostics.normal` flag.
    blocks : array_like of int, optional
        Block number of each residual: the Durbin-Watson statistic and the lag-1
        autocorrelation then use only pairs of consecutive blocks (see
        :func:`durbin_watson`).

    Returns
    -------
    ResidualDiagnostics

    Notes
    -----
    Jarque-Bera: JB = n/6 (S² + K²/4) with skewness S and excess kurtosis K, χ²₂ under
    normality [1]_ (computed by :func:`statsmodels.stats.stattools.jarque_bera`).
    Shapiro-Wilk from :func:`scipy.stats.shapiro` [2]_.

    References
    ----------
    .. [1] C. M. Jarque, A. K. Bera, "A test for normality of observations and regression
       residuals", International Statistical Review 55(2), 163-172, 1987.
       doi:10.2307/1403192
    .. [2] S. S. Shapiro, M. B. Wilk, "An analysis of variance test for normality (complete
       samples)", Biometrika 52(3/4), 591-611, 1965. doi:10.1093/biomet/52.3-4.591
    """
    e, blocks = _finite_residuals(residuals, blocks)
    n = int(e.size)
    nan = math.nan
    if n == 0:
        return ResidualDiagnostics(0, nan, nan, nan, nan, nan, nan, nan, nan, nan, nan, alpha)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = float(e.mean())
        std = float(e.std(ddof=1)) if n > 1 else nan
        centred = e - mean
        m2 = float(centred @ centred) / n
        skewness = float(np.mean(centred**3)) / m2**1.5 if m2 > 0 else nan
        kurtosis = float(np.mean(centred**4)) / m2**2 - 3.0 if m2 > 0 else nan
        pairs = _run_pairs(e, blocks)
        if pairs.sum() > 2 and np.ptp(e) > 0:
            lag1 = float(np.corrcoef(e[:-1][pairs], e[1:][pairs])[0, 1])
        else:
            lag1 = nan
    if n >= 3 and n <= 5000 and np.ptp(e) > 0:
        shapiro = _scipy_stats.shapiro(e)
        shapiro_w, shapiro_p = float(shapiro.statistic), float(shapiro.pvalue)
    else:
        shapiro_w = shapiro_p = nan
    if n >= 2 and m2 > 0:
        from statsmodels.stats.stattools import jarque_bera as _jarque_bera

        jarque_bera, jarque_bera_p, _, _ = (float(v) for v in _jarque_bera(e))
    else:
        jarque_bera = jarque_bera_p = nan
    return ResidualDiagnostics(
        n=n,
        mean=mean,
        std=std,
        skewness=skewness,
        excess_kurtosis=kurtosis,
        durbin_watson=durbin_watson(e, blocks),
        lag1_autocorrelation=lag1,
        shapiro_statistic=shapiro_w,
        shapiro_p_value=shapiro_p,
        jarque_bera_statistic=float(jarque_bera),
        jarque_bera_p_value=jarque_bera_p,
        alpha=alpha,
    )
