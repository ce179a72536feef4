"""Innovation consistency of the memory forecast's Kalman filter: a safeguard toward SSI.

The noise model (:mod:`workbench.forecasting.noise`) splits the residuals r = z - m into a
model error c and an identification error e from their autocovariances. With a few dozen
residuals that split is ill-determined: a model error with a time constant of 6 blocks
(φ = 0.85) and an identification error correlated between 75 %-overlapping blocks
(ρ = 0.65-0.7) have nearly the same autocovariance, and when the split puts the model's
error into e the filter trusts a bad model and ends up worse than the raw SSI estimate.
The filter's own innovations tell. When its noise model is right, the normalised
innovations ν_k = y_k / √S_k are independent N(0, 1), whatever the correlation of the
residuals (the innovation sequence of the optimal filter is white, [1]_ §5.4). Over the
newest W out-of-sample blocks with a measurement, two tests at level α:

* size: T̄ = mean ψ(ν_k)², ψ(ν) = max(-k, min(ν, k)) with k = :data:`TEST_CLIP`, has mean
  m_k and standard deviation s_k / √W under the model (closed form,
  :func:`clipped_square_moments`); T̄ > m_k + z_{1-α} s_k / √W says the innovation
  variance is too small by the factor λ that solves λ m(k/√λ) = T̄ (the clipped mean
  square of N(0, λ), :func:`variance_factor`), i.e. by (λ - 1) S̄ with S̄ the window's mean
  S. The clip is tighter than the filter's Huber threshold because the test measures the
  spread of the bulk of the innovations: gross errors (a mislabelled pole, an ice impact)
  are the Huber weight's business, and at the rate ice brings them (a few per cent) a clip
  at 2.5 reads them as an innovation variance 20 % too small and adds model variance,
  which moves the blend toward the very measurements that are in error. At k = 1.5 such an
  error counts 2.25 instead of 6.25, and the test is no less sensitive to a real excess
  (s_k / m_k = 1.02 against 1.33 at 2.5);
* sign: mean ψ(ν_k) has standard deviation √(m_k / W); beyond z_{1-α/2} of them the
  filter's prediction is off to one side, by b = mean ψ(ν_k) √S_k, i.e. by b² in variance
  (a drifting model whose error the filter put into e passes the size test: e follows it).

The larger excess is added to the model's own variance s_m² (the white model error δ in
x = m + δ + c, :func:`~workbench.forecasting.memory.kalman.kalman_update`), on top of
what was in force while the window's innovations were normalised: an innovation-based
adaptive estimate of the noise ([2]_), whose fixed point is a consistent filter. A window
whose T̄ is below m_k takes the same share back, so the addition goes when the model
recovers. A consistent window (between m_k and the critical value) keeps what is in force.

Why the white model variance, and not R or the process noise of c: more model variance
moves each block's estimate toward its own measurement, whose error does not depend on
the filter, and in the limit the blend *is* the SSI estimate; the evidence is not stored
in the state, so an identification-error burst (ice) is not carried on for the hours a
long time constant of c would keep it. The adaptation cannot self-train into drift (it
never makes the filter trust its own past more) and it is bounded: at most the mean
square of the window's out-of-sample residuals, where the blend already follows the
measurement. Only out-of-sample innovations count (in the first window the model was
fitted to the blocks it filters, so those innovations flatter it).

References
----------
.. [1] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, "Estimation with Applications to Tracking
   and Navigation", Wiley, 2001, ch. 5.4 (filter consistency, NIS). doi:10.1002/0471221279
.. [2] A. H. Mohamed, K. P. Schwarz, "Adaptive Kalman filtering for INS/GPS", Journal of
   Geodesy 73(4), 193-203, 1999. doi:10.1007/s001900050236
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm

__all__ = ["InnovationConsistency", "clipped_square_moments", "variance_factor"]

#: Newest measured out-of-sample blocks of the test (2 h of 5-minute blocks: six times the
#: four blocks that share data, so one corrupted stretch cannot decide it). [blocks]
WINDOW_BLOCKS = 24
#: Fewest innovations for a test. [blocks]
MIN_BLOCKS = 12
#: Level of the one-sided test.
ALPHA = 0.05
#: Clip k of the normalised innovations in the tests (module docstring). [-]
TEST_CLIP = 1.5


def clipped_square_moments(k: float) -> tuple[float, float]:
    """Mean and standard deviation of ψ(ν)² = min(ν², k²) for ν ~ N(0, 1).

    .. math::

        E[ψ^2] = 2Φ(k) - 1 - 2kφ(k) + 2k^2 (1 - Φ(k)),

        E[ψ^4] = 3(2Φ(k) - 1) - 2φ(k)(k^3 + 3k) + 2k^4 (1 - Φ(k)).

    k = ∞ gives (1, √2), the moments of χ²₁.
    """
    if not math.isfinite(k):
        return 1.0, math.sqrt(2.0)
    Phi, phi, tail = float(norm.cdf(k)), float(norm.pdf(k)), float(norm.sf(k))
    m2 = 2 * Phi - 1 - 2 * k * phi + 2 * k * k * tail
    m4 = 3 * (2 * Phi - 1) - 2 * phi * (k**3 + 3 * k) + 2 * k**4 * tail
    return m2, math.sqrt(max(m4 - m2 * m2, 0.0))


def variance_factor(mean_clipped_square: float, k: float) -> float:
    """λ with E[min(λν², k²)] = *mean_clipped_square* for ν ~ N(0, 1). [-]

    E[min(λν², k²)] = λ m(k/√λ), m the mean of :func:`clipped_square_moments`, grows with λ
    from 0 to k²; solved by bisection on log λ in [1e-3, 1e3] (60 halvings: relative
    precision 1e-15). A value at or beyond k² gives 1e3.
    """
    if not math.isfinite(k):
        return max(float(mean_clipped_square), 1e-3)

    def clipped(lam: float) -> float:
        # λ m(c), c = k/√λ: m(c) = erf(c/√2) - 2cφ(c) + c² erfc(c/√2)
        c = k / math.sqrt(lam)
        density = math.exp(-0.5 * c * c) / math.sqrt(2 * math.pi)
        return lam * (
            math.erf(c / math.sqrt(2)) - 2 * c * density + c * c * math.erfc(c / math.sqrt(2))
        )

    low, high = math.log(1e-3), math.log(1e3)
    if clipped(math.exp(high)) <= mean_clipped_square:
        return math.exp(high)
    for _ in range(60):
        mid = 0.5 * (low + high)
        if clipped(math.exp(mid)) < mean_clipped_square:
            low = mid
        else:
            high = mid
    return math.exp(0.5 * (low + high))


@dataclass
class InnovationConsistency:
    """Per-mode record of normalised innovations and the model variance they add.

    Parameters
    ----------
    n_blocks, n_modes : int
        Size of the forecast's grid.
    huber_sigma : float
        Huber threshold of the filter; the tests clip ψ at the smaller of it and
        *test_clip*. [-]
    window_blocks : int
        W, measured blocks of the test. [blocks]
    alpha : float
        Level of the tests (size: one-sided, sign: two-sided).
    test_clip : float
        k of ψ in the tests (module docstring). [-]

    Attributes
    ----------
    added_variance : ndarray (n_modes,)
        Model variance the tests add, as of the last :meth:`update`. [Hz²]
    """

    n_blocks: int
    n_modes: int
    huber_sigma: float
    window_blocks: int = WINDOW_BLOCKS
    alpha: float = ALPHA
    test_clip: float = TEST_CLIP
    added_variance: np.ndarray = field(init=False)
    _nu: np.ndarray = field(init=False, repr=False)
    _used: np.ndarray = field(init=False, repr=False)
    _measured: list[list[int]] = field(init=False, repr=False)
    _constants: tuple[float, float, float, float] = field(init=False, repr=False)
    _variance: np.ndarray = field(init=False, repr=False)
    _residual2: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        shape = (self.n_blocks, self.n_modes)
        self._nu = np.full(shape, np.nan)
        self._used = np.zeros(shape)
        self._measured = [[] for _ in range(self.n_modes)]
        self._variance = np.full(shape, np.nan)
        self._residual2 = np.full(shape, np.nan)
        self.added_variance = np.zeros(self.n_modes)
        mean_k, sd_k = clipped_square_moments(self._clip)
        # moments of ψ² under the model; one- and two-sided normal quantiles at alpha
        self._constants = (
            mean_k,
            sd_k,
            float(norm.isf(self.alpha)),
            float(norm.isf(self.alpha / 2)),
        )

    @property
    def _clip(self) -> float:
        return min(float(self.huber_sigma), float(self.test_clip))

    def record(self, row: int, normalised, variance, residual) -> None:
        """Store block *row*'s normalised innovations ν, their variances S and residuals.

        Rows are recorded in increasing order, each once; NaN ν: no measurement.
        """
        nu = np.asarray(normalised, dtype=float)
        self._nu[row] = nu
        self._variance[row] = np.where(np.isfinite(nu), variance, np.nan)
        self._residual2[row] = np.where(np.isfinite(nu), np.asarray(residual) ** 2, np.nan)
        self._used[row] = self.added_variance
        for j in np.flatnonzero(np.isfinite(nu)):
            if not self._measured[j] or self._measured[j][-1] != row:
                self._measured[j].append(row)

    def update(self, row: int) -> np.ndarray:
        """Test the newest innovations before grid row *row*; return the added variance. [Hz²]"""
        k = self._clip
        mean_k, sd_k, z_one, z_two = self._constants
        for j in range(self.n_modes):
            # the newest W measured rows before *row*
            rows = self._measured[j]
            stop = len(rows)
            while stop and rows[stop - 1] >= row:
                stop -= 1
            have = np.asarray(rows[max(0, stop - self.window_blocks) : stop], dtype=np.int64)
            nu = self._nu[:row, j]
            if have.size < MIN_BLOCKS:
                continue
            n = have.size
            psi = np.clip(nu[have], -k, k)
            variance = self._variance[have, j]
            t_bar = float(np.mean(psi * psi))
            s_bar = float(np.mean(variance))
            # the addition in force while these innovations were normalised
            used = float(np.mean(self._used[have, j]))
            excess = 0.0
            if t_bar > mean_k + z_one * sd_k / math.sqrt(n):  # too large
                excess = (variance_factor(t_bar, k) - 1.0) * s_bar
            if abs(float(np.mean(psi))) * math.sqrt(n / mean_k) > z_two:  # off to one side
                bias = float(np.mean(psi * np.sqrt(variance)))
                excess = max(excess, bias * bias)
            if excess > 0.0:
                level = used + excess
            elif t_bar < mean_k:  # smaller than expected: take back
                level = used + (variance_factor(t_bar, k) - 1.0) * s_bar
            else:
                continue  # consistent: keep the addition
            cap = float(np.mean(self._residual2[have, j]))
            self.added_variance[j] = min(max(level, 0.0), cap)
        return self.added_variance
