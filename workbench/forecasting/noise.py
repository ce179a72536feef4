"""Noise levels of the Kalman blend from the data: covariance matching of model residuals.

The residual of a block's SSI estimate about the model, r_k = z_k - m_k, is modelled as

.. math::

    r_k = c_k + e_k + v_k, \\qquad c_k = φ c_{k-1} + w_k, \\qquad e_k = ρ e_{k-1} + u_k,

with c the slowly varying part of the frequency the model does not explain (time constant
τ_c = -1/ln φ blocks), e the identification error, correlated between 75 %-overlapping
blocks (lag-1 correlation ρ), and v a white part. Their autocovariances add up,

.. math:: γ(h) = σ_c^2 φ^h + σ_e^2 ρ^h + σ_v^2 [h = 0],

(for overlapping blocks, φ^h is the autocorrelation of c's mean over a block instead,
:func:`correction_autocorrelation`: a block's true frequency is its time average; the
filter keeps c an AR(1) with the fitted τ_c and the blocks' variance σ_c²), so
(σ_c², σ_e², σ_v²) follow from the measured γ(0..L) by non-negative least squares for
each (τ_c, ρ) of a grid, and the pair with the smallest misfit wins (covariance matching,
[1]_). For blocks that share data with their L - 1 neighbours the identification error is
the mean of the L independent errors of the segments they share, and ρ^h is replaced by
its correlation (L - h) / L, zero from lag L (``error_segments``,
:func:`error_autocorrelation`): an AR(1) e with ρ = 0.7 still has 0.24 at lag 4 and can
take a model error of a few blocks' time constant; the overlap's shape cannot. Safeguards against self-training into drift: the residuals are of raw measurements
about a model that was fitted before they were seen (never of the filter's own output; the
first window's, to which the model was fitted, are the exception the floor below covers), they
are winsorised at 4 robust standard deviations (the odd mis-selected pole), the estimate
needs :data:`MIN_RESIDUALS` residuals and is otherwise a fixed prior, and every variance has
a floor relative to the frequency. The caller then raises σ_c² to what the out-of-sample
residuals show beyond the measurement variance (:func:`model_error_floor`): the fit's
split between model error and identification error is ill-determined early on, and this
makes the blend err toward the measurement.

References
----------
.. [1] R. K. Mehra, "On the identification of variances and adaptive Kalman filtering",
   IEEE Trans. Automatic Control 15(2), 175-184, 1970. doi:10.1109/TAC.1970.1099422
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

__all__ = [
    "MIN_OUT_OF_SAMPLE",
    "MIN_RESIDUALS",
    "NoiseModel",
    "correction_autocorrelation",
    "error_autocorrelation",
    "estimate_noise",
    "lagged_autocovariance",
    "identification_error_bound",
    "model_error_floor",
]

#: Fewest residuals for the covariance-matching estimate.
MIN_RESIDUALS = 30
#: Fewest out-of-sample residuals for the model-error floor (:func:`model_error_floor`).
MIN_OUT_OF_SAMPLE = 8
#: Residuals are winsorised at this many robust standard deviations.
WINSOR = 4.0
#: Lags matched. [blocks]
MAX_LAG = 12
#: Grid of time constants of the model error. [blocks]
CORRECTION_TIMES = (6.0, 12.0, 24.0, 48.0, 96.0, 192.0, 384.0)
#: Grid of lag-1 correlations of the identification error.
ERROR_CORRELATIONS = tuple(np.round(np.arange(0.0, 0.71, 0.05), 2))
#: Relative floors: model-error and measurement standard deviations, x frequency. [-]
MIN_CORRECTION_STD = 3e-5
MIN_MEASUREMENT_STD = 1e-4


@dataclass(frozen=True)
class NoiseModel:
    """Variances of the residual model (module docstring).

    Parameters
    ----------
    correction_variance : float
        σ_c², stationary variance of the model error c. [Hz²]
    correction_time_blocks : float
        τ_c, φ = exp(-1/τ_c). [blocks]
    error_variance : float
        σ_e², stationary variance of the correlated identification error e. [Hz²]
    error_correlation : float
        ρ, lag-1 correlation of e. [-]
    white_variance : float
        σ_v². [Hz²]
    n_residuals : int
        Residuals the estimate used (0: prior).
    error_segments : int
        0: e is AR(1) with lag-1 correlation ρ. L >= 2: e is the mean of the L independent
        errors of the segments a block shares with its neighbours (blocks of L steps, a
        new one every step), an MA(L - 1) with correlation (L - h) / L at lag h < L and
        zero from lag L (:func:`error_autocorrelation`); ρ is then (L - 1) / L.
    """

    correction_variance: float
    correction_time_blocks: float
    error_variance: float
    error_correlation: float
    white_variance: float
    n_residuals: int = 0
    error_segments: int = 0

    @property
    def transition(self) -> float:
        return math.exp(-1.0 / self.correction_time_blocks)


def error_autocorrelation(lags: np.ndarray, *, rho: float = 0.0, segments: int = 0) -> np.ndarray:
    """Autocorrelation of the identification error e at *lags* (>= 0). [-]

    AR(1) (``segments`` 0): ρ^h. Mean of L = ``segments`` independent segment errors,
    block k spanning segments k .. k + L - 1: blocks h apart share L - h of them, so the
    correlation is (L - h) / L for h < L and exactly 0 from h = L (blocks that share no
    data).
    """
    h = np.asarray(lags, dtype=float)
    if segments >= 2:
        return np.clip(1.0 - h / segments, 0.0, None)
    if rho > 0:
        return rho**h
    return (h == 0) * 1.0


def correction_autocorrelation(lags: np.ndarray, tau: float, *, segments: int = 0) -> np.ndarray:
    """Autocorrelation of the model error c at *lags* (>= 0), time constant *tau*. [-]

    Without overlap (``segments`` 0): φ^h, φ = exp(-1/τ_c). Blocks of L = ``segments``
    steps, a new one every step: a block's true frequency is the time average over its L
    steps, so what a block sees of a model error that varies continuously in time (an
    AR(1) of time constant τ_c steps: correlation e^{-|u|/τ_c} at time lag u) is its mean
    over the block, whose autocovariance is the double integral of that correlation over
    two blocks h steps apart [1]_,

    .. math::

        γ(h) ∝ ψ(h + L) + ψ(h - L) - 2 ψ(h), \\qquad
        ψ(u) = τ_c^2 (e^{-|u|/τ_c} + |u|/τ_c - 1)

    (ψ'' = e^{-|u|/τ_c}), here divided by γ(0). Below lag L it is flatter than φ^h
    (blocks that share data share that part of the wander: 0.97 against 0.88 at lag 1
    for τ_c = 8, L = 4); from lag L on it is φ^h times a constant. The overlap's
    identification error (:func:`error_autocorrelation`) differs from it over the same L
    lags, so fitted with φ^h the block mean's extra correlation there goes to the wrong
    term: on a long record of a 1-hour wander (``tests/forecast/test_overlap_error.py``)
    φ^h takes a quarter to a half of σ_e² for model error.

    References
    ----------
    .. [1] A. Papoulis, S. U. Pillai, "Probability, Random Variables and Stochastic
       Processes", 4th ed., McGraw-Hill, 2002 (the variance of the time average of a
       stationary process).
    """
    h = np.asarray(lags, dtype=float)
    tau = float(tau)
    if segments < 2:
        return math.exp(-1.0 / tau) ** h
    L = float(segments)

    def psi(u):
        a = np.abs(u) / tau
        return np.exp(-a) + a - 1.0

    return (psi(h + L) + psi(h - L) - 2.0 * psi(h)) / (2.0 * psi(L))


def lagged_autocovariance(values: np.ndarray, max_lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean products r_k r_{k+h}, h = 0..max_lag, over the pairs with both values finite.

    Not demeaned: a constant offset of the residuals is model error (part of c).
    Returns the products and the number of pairs per lag.
    """
    r = np.asarray(values, dtype=float)
    finite = np.isfinite(r)
    filled = np.where(finite, r, 0.0)
    gamma = np.full(max_lag + 1, np.nan)
    count = np.zeros(max_lag + 1, dtype=np.int64)
    for h in range(max_lag + 1):
        if h >= r.size:
            break
        both = finite[: r.size - h] & finite[h:]
        count[h] = int(both.sum())
        if count[h]:
            gamma[h] = float((filled[: r.size - h] * filled[h:])[both].sum() / count[h])
    return gamma, count


def _winsorise(r: np.ndarray) -> np.ndarray:
    finite = r[np.isfinite(r)]
    centre = float(np.median(finite))
    spread = 1.4826 * float(np.median(np.abs(finite - centre)))
    if spread <= 0:
        return r
    return np.clip(r, centre - WINSOR * spread, centre + WINSOR * spread)


def prior_noise(
    level_hz: float,
    white_scatter_variance: float | None = None,
    mean_square: float | None = None,
) -> NoiseModel:
    """Noise model before enough residuals exist (conservative: the filter leans on SSI).

    The measurement variance is the white scatter (successive differences), all white;
    the model error gets the larger of four times that and the residuals' mean square, with
    a short time constant (6 blocks), because in-sample residuals of a model fitted on a
    few blocks flatter it and nothing yet says how it extrapolates: the blend follows the
    measurements until the model has earned trust out of sample.
    """
    floor = (MIN_MEASUREMENT_STD * level_hz) ** 2
    total = white_scatter_variance if white_scatter_variance else (3e-3 * level_hz) ** 2
    total = max(float(total), floor)
    return NoiseModel(
        correction_variance=max(4.0 * total, float(mean_square or 0.0)),
        correction_time_blocks=6.0,
        error_variance=0.0,
        error_correlation=0.0,
        white_variance=total,
        n_residuals=0,
    )


_SUBSETS = tuple(tuple(c for c in range(3) if mask >> c & 1) for mask in range(1, 8))


def _grid_fits(lags: np.ndarray, target: np.ndarray, weight: np.ndarray, segments: int = 0):
    """Non-negative least squares of γ(h) on [φ^h, ρ^h, [h=0]] for every (τ_c, ρ) of the grid
    (φ^h the block mean's correlation for overlapping blocks, :func:`correction_autocorrelation`).

    Exact NNLS for three unknowns: the optimum is the least-squares solution on its set of
    positive coefficients, so the best of the least-squares solutions on the 7 column
    subsets that come out non-negative is the NNLS solution (batched over the grid).
    With *segments* L >= 2 the identification error's column is the overlap's
    (L - h) / L (:func:`error_autocorrelation`) instead of a grid of ρ^h.
    Returns τ_c, ρ, the misfit |A c - b| and the coefficients (σ_c², σ_e², σ_v²) of every
    grid point.
    """
    phis = np.exp(-1.0 / np.asarray(CORRECTION_TIMES))
    if segments >= 2:
        rhos = np.array([(segments - 1) / segments])
    else:
        rhos = np.asarray(ERROR_CORRELATIONS, dtype=float)
    tau_g, rho_g = np.meshgrid(np.arange(phis.size), np.arange(rhos.size), indexing="ij")
    tau_g, rho_g = tau_g.ravel(), rho_g.ravel()
    h = lags[None, :].astype(float)
    # the model error's column: the block mean of an AR(1) for overlapping blocks
    if segments >= 2:
        columns = np.stack(
            [correction_autocorrelation(lags, t, segments=segments) for t in CORRECTION_TIMES]
        )
    else:
        columns = phis[:, None] ** h
    zero = (lags == 0)[None, :] * 1.0
    if segments >= 2:
        rho_col = np.broadcast_to(
            error_autocorrelation(lags, segments=segments), (rho_g.size, lags.size)
        )
    else:
        rho_col = np.where(rhos[rho_g][:, None] > 0, rhos[rho_g][:, None] ** h, zero)
    design = (
        np.stack([columns[tau_g], rho_col, np.broadcast_to(zero, rho_col.shape)], axis=2)
        * weight[None, :, None]
    )
    b = target * weight
    best_misfit = np.full(tau_g.size, np.inf)
    best_coef = np.zeros((tau_g.size, 3))
    gram = np.einsum("gmi,gmj->gij", design, design)  # AᵀA per grid point
    rhs = np.einsum("gmi,m->gi", design, b)  # Aᵀb
    bb = float(b @ b)
    for subset in _SUBSETS:
        idx = np.asarray(subset)
        G = gram[:, idx[:, None], idx[None, :]]
        # ridge 1e-12 trace: columns that coincide (e.g. ρ^h at small ρ and [h=0])
        ridge = 1e-12 * np.trace(G, axis1=1, axis2=2)[:, None, None] * np.eye(idx.size)
        coef = np.linalg.solve(G + ridge + 1e-300, rhs[:, idx][:, :, None])[:, :, 0]
        feasible = (coef >= 0).all(axis=1)
        # |Ac - b|² = cᵀGc - 2cᵀAᵀb + bᵀb
        misfit = np.sqrt(
            np.maximum(
                np.einsum("gi,gij,gj->g", coef, G, coef)
                - 2 * np.einsum("gi,gi->g", coef, rhs[:, idx])
                + bb,
                0.0,
            )
        )
        better = feasible & (misfit < best_misfit - 1e-30)
        best_misfit[better] = misfit[better]
        full = np.zeros((tau_g.size, 3))
        full[:, subset] = coef
        best_coef[better] = full[better]
    return np.asarray(CORRECTION_TIMES, dtype=float)[tau_g], rhos[rho_g], best_misfit, best_coef


def _soft_choice(taus, rhos, misfit, coefs, n_pairs: int, segments: int = 0):
    """(τ_c, ρ, coefficients) averaged over the grid by how well each point fits.

    The measured autocovariances scatter about the true ones, so grid points whose misfits
    differ by less than that scatter fit the data equally well; on the wander of a few
    blocks' time constant the smallest misfit alternates between splits as far apart as
    (τ_c 6, σ_e 0) and (τ_c 12, σ_e ≈ 1.6 σ) from one refit to the next. Each point gets the
    weight exp(-(misfit² - min misfit²) / 2 s²), with s² = Σ_h γ(h)² / n (h over all
    integers, γ the best point's model autocovariance, n the residual pairs at lag 0):
    Bartlett's large-sample variance of a measured autocovariance at a lag beyond the
    correlation [1]_, one lag's sampling scatter taken as the scale of the whole misfit (a
    pseudo-likelihood). The variances and φ = exp(-1/τ_c) are averaged with these weights
    (ρ too for the AR(1) error; the overlap's shape has none), so the split moves smoothly
    as residuals arrive. ``benchmarks/results/forecast_accuracy_27g.txt`` and
    ``forecast_soft_split_27m.txt`` measure it against the smallest misfit alone.

    References
    ----------
    .. [1] M. S. Bartlett, "On the theoretical specification and sampling properties of
       autocorrelated time-series", J. R. Stat. Soc. Suppl. 8(1), 27-41, 1946.
       doi:10.2307/2983611
    """
    g = int(np.argmin(misfit))
    sc, se, sv = coefs[g]
    h = np.arange(8 * int(max(taus[g], 12.0)))
    gamma = sc * correction_autocorrelation(
        h, float(taus[g]), segments=segments
    ) + se * error_autocorrelation(h, rho=float(rhos[g]), segments=segments)
    gamma[0] += sv
    s2 = (gamma[0] ** 2 + 2.0 * float(np.sum(gamma[1:] ** 2))) / max(int(n_pairs), 1)
    if not np.isfinite(s2) or s2 <= 0:
        return float(taus[g]), float(rhos[g]), coefs[g]
    w = np.exp(-(misfit**2 - misfit[g] ** 2) / (2.0 * s2))
    w /= w.sum()
    tau = -1.0 / math.log(float(w @ np.exp(-1.0 / taus)))
    rho = float(rhos[g]) if segments >= 2 else float(w @ rhos)
    return tau, rho, w @ coefs


def identification_error_bound(residuals: np.ndarray, correlated_lags: int) -> float | None:
    """Upper bound of the identification error's variance that does not depend on the model.

    Blocks *correlated_lags* apart share no data, so their identification errors are
    independent. The residual's second difference across them,
    d_k = r_k - (r_{k-L} + r_{k+L}) / 2, holds the identification error of three blocks,
    1.5 σ_ε², plus the model error's curvature over 2L blocks, which is >= 0; so
    mean(d²) / 1.5 bounds σ_ε² = σ_e² + σ_v² from above whatever the model error is (an
    offset or a linear drift of the model cancels in d). None with fewer than
    :data:`MIN_RESIDUALS` triples.
    """
    r = np.asarray(residuals, dtype=float)
    L = int(correlated_lags)
    if r.size <= 2 * L:
        return None
    d = r[L:-L] - 0.5 * (r[: -2 * L] + r[2 * L :])
    d = d[np.isfinite(d)]
    if d.size < MIN_RESIDUALS:
        return None
    return float(np.mean(d * d) / 1.5)


def estimate_noise(
    residuals: np.ndarray,
    level_hz: float,
    *,
    correlated_lags: int | None = None,
    error_segments: int = 0,
) -> NoiseModel:
    """Covariance-matching estimate of the residual model (module docstring).

    Parameters
    ----------
    residuals : ndarray
        r_k = z_k - m_k on consecutive blocks (NaN: no measurement), oldest first. [Hz]
    level_hz : float
        Typical frequency of the mode, for the floors. [Hz]
    correlated_lags : int, optional
        Blocks that share data with a block (4 for 20-minute blocks every 5 minutes):
        identification errors this many blocks apart are independent, and σ_e² + σ_v² is
        capped at :func:`identification_error_bound` (the excess goes to the model error
        σ_c²). None: no cap.
    error_segments : int
        0: the identification error e is AR(1), ρ from a grid. L >= 2: e is the mean of
        the L segment errors a block shares with its neighbours, with the overlap's
        correlation (L - h) / L, zero from lag L (:func:`error_autocorrelation`): with that
        shape known, a correlation that outlasts the overlap can only be model error, so
        the fit cannot give the model's error to e.
    """
    r = np.asarray(residuals, dtype=float)
    n = int(np.isfinite(r).sum())
    if n < MIN_RESIDUALS:
        finite = r[np.isfinite(r)]
        scatter = float(np.var(np.diff(finite)) / 2.0) if finite.size >= 3 else None
        spread = float(np.mean(finite**2)) if finite.size >= 3 else None
        return prior_noise(level_hz, scatter, spread)
    r = _winsorise(r)
    gamma, count = lagged_autocovariance(r, MAX_LAG)
    use = np.isfinite(gamma) & (count >= 10)
    lags = np.flatnonzero(use)
    target = gamma[use]
    weight = np.sqrt(count[use] / count[0])
    segments = int(error_segments) if error_segments and error_segments >= 2 else 0
    tau, rho, coef = _soft_choice(*_grid_fits(lags, target, weight, segments), count[0], segments)
    sc, se, sv = (float(c) for c in coef)
    if rho == 0.0:  # e and v coincide: all white
        sv, se = sv + se, 0.0
    if correlated_lags is not None:
        # the fit cannot tell a model error of a few blocks' time constant from the
        # identification error; the second difference across non-overlapping blocks bounds
        # the latter whatever the model does: what the fit put into e and v beyond the
        # bound is model error
        bound = identification_error_bound(r, int(correlated_lags))
        if bound is not None and se + sv > bound:
            excess = se + sv - bound
            shrink = bound / (se + sv)
            se, sv, sc = se * shrink, sv * shrink, sc + excess
    floor_c = (MIN_CORRECTION_STD * level_hz) ** 2
    floor_m = (MIN_MEASUREMENT_STD * level_hz) ** 2
    if se + sv < floor_m:
        sv = floor_m - se
    return NoiseModel(
        correction_variance=max(sc, floor_c),
        correction_time_blocks=float(tau),
        error_variance=se,
        error_correlation=float(rho),
        white_variance=max(sv, 0.05 * floor_m),
        n_residuals=n,
        error_segments=segments,
    )


def model_error_floor(noise: NoiseModel, out_of_sample: np.ndarray) -> NoiseModel:
    """Raise σ_c² to what the out-of-sample residuals show beyond the measurement noise.

    A residual r_k = z_k - m_k of a block the model had not seen when it was fitted has

    .. math:: E[r_k^2] = σ_c^2 + σ_e^2 + σ_v^2 \\;(+ s_m^2),

    so the mean square of such residuals in excess of the measurement variance,
    σ̂_c² = mean(r²) - σ_e² - σ_v², is a method-of-moments estimate of the model error that
    uses only out-of-sample evidence (s_m², the model's own variance, is left in: the
    estimate errs toward the measurement). :func:`estimate_noise` fits every residual of
    the noise window, and until the forecast has run for a while most of them are the
    first window's in-sample residuals, to which the model was fitted: they flatter it
    (with 75 %-overlapping blocks a 20-block window holds about five independent SSI
    estimates, and the fit absorbs part of their error). The fit can then put the model's
    error into the correlated identification error e, whose autocovariance over a few
    dozen residuals is hard to tell from that of a model error with a short time constant
    (ρ = 0.7 against φ = e^{-1/6} = 0.85), and the blend trusts a model that is off.

    The floor only ever raises σ_c², so the blend leans toward the raw measurement, whose
    error does not depend on the filter: it cannot self-train into drift. The residuals
    are winsorised like those of the fit (one mis-selected pole cannot raise it), and with
    fewer than :data:`MIN_OUT_OF_SAMPLE` of them *noise* is returned unchanged.

    Parameters
    ----------
    noise : NoiseModel
        The covariance-matching estimate.
    out_of_sample : ndarray
        Residuals of blocks the model was not fitted to (NaN: none). [Hz]
    """
    r = np.asarray(out_of_sample, dtype=float)
    r = r[np.isfinite(r)]
    if r.size < MIN_OUT_OF_SAMPLE:
        return noise
    excess = float(np.mean(_winsorise(r) ** 2)) - noise.error_variance - noise.white_variance
    if excess <= noise.correction_variance:
        return noise
    return replace(noise, correction_variance=excess)
