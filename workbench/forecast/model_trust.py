"""Does the model still explain the mode? Two hypotheses weighed by their predictive likelihood.

The memory forecast's filter (:mod:`workbench.forecast.memory_kalman`) estimates
x = m + c with the model's prediction m; when something changes that no predictor
records (fuel burnt without soundings, ballast, ice on deck), its noise model, fitted on
residuals from before the change, can trust m more than the data allow, and the blend
ends up worse than the raw SSI estimate. Beside it, this module runs a filter that does
not use the model at all:

.. math::

    x_k = x_{k-1} + w_k, \\quad z_k = x_k + e_k + v_k, \\quad e_k = ρ e_{k-1} + u_k,

(the level x a random walk, the identification error e and v as in the blend's noise
model), and weighs the two hypotheses H₁ "the model explains the mode" (the blend) and
H₀ "it does not" (the model-free filter) by the likelihood of each block's measurement
under each filter's one-step prediction, with a small probability of switching between
blocks (a two-model multiple-model filter without state mixing, [1]_ §11.6). The
likelihood uses Huber-clipped normalised innovations (one mis-selected pole cannot decide
it). The estimate is the probability-weighted mean of the two filters' estimates:

.. math:: \\hat x = p \\hat x_1 + (1 - p) \\hat x_0, \\qquad
          P = p (P_1 + (\\hat x_1 - \\hat x)^2) + (1 - p) (P_0 + (\\hat x_0 - \\hat x)^2).

The one-step prediction of a block's measurement is out of sample for both filters, so p
measures which of them predicts the data better as the voyage goes on: a guard that
measures whether leaning on the model still helps, and falls back to the model-free
estimate (which follows SSI) when it does not.

References
----------
.. [1] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, "Estimation with Applications to Tracking
   and Navigation", Wiley, 2001, ch. 11.6 (multiple-model estimation).
   doi:10.1002/0471221279
"""

from __future__ import annotations

import numpy as np

__all__ = ["ModelTrust"]

#: Probability that the hypothesis changes from one block to the next (about one switch
#: in 2 days of 5-minute blocks would be 0.002; a larger value lets p come back within a
#: few hours after the model recovers). [-]
SWITCH_PROBABILITY = 0.02
#: Level random-walk variance of the model-free filter per block, in units of the
#: identification error's variance σ_e² + σ_v²: a level that moves by about the SSI
#: scatter in 10 blocks (50 minutes); faster moves are what the model is for, and the
#: likelihood then favours the blend. [-]
LEVEL_STEP_VARIANCE = 0.1
#: Probability that the model explains a mode before its first out-of-sample block. [-]
PRIOR_PROBABILITY = 0.9
#: Smallest and largest model probability (neither hypothesis is ever ruled out). [-]
P_MIN, P_MAX = 1e-4, 1.0 - 1e-4


class ModelTrust:
    """Model-free filter and the probability that the model explains each mode.

    Parameters
    ----------
    n_modes : int
    huber_sigma : float
        Normalised innovations are clipped at this many standard deviations in the
        likelihood. [-]
    prior_probability : float
        Probability of "the model explains the mode" before any measurement. [-]
    """

    def __init__(self, n_modes: int, huber_sigma: float, prior_probability: float = PRIOR_PROBABILITY):
        self.huber_sigma = float(huber_sigma)
        self.level = np.full(n_modes, np.nan)  # model-free estimate x̂₀ [Hz]
        self.error = np.zeros(n_modes)  # its identification-error state ê [Hz]
        self.P = np.zeros((n_modes, 2, 2))
        self.probability = np.full(n_modes, float(prior_probability))

    def _log_likelihood(self, normalised: np.ndarray, variance: np.ndarray) -> np.ndarray:
        # log N(y; 0, S) with ν² Huber-clipped: -0.5 (log S + ρ_H(ν))
        a = np.abs(normalised)
        k = self.huber_sigma
        rho = np.where(a <= k, a * a, 2 * k * a - k * k)
        return -0.5 * (np.log(variance) + rho)

    def step(
        self,
        z: np.ndarray,
        error_correlation: np.ndarray,
        error_variance: np.ndarray,
        white_variance: np.ndarray,
        blend_normalised: np.ndarray,
        blend_variance: np.ndarray,
        learn: np.ndarray,
    ) -> None:
        """One block: predict and update the model-free filter, then the probability.

        Parameters
        ----------
        z : ndarray (n,)
            The block's measurement (NaN: none). [Hz]
        error_correlation, error_variance, white_variance : ndarray (n,)
            ρ, σ_e² (stationary) and the block's white variance R of the blend's noise
            model (the same identification error under both hypotheses). [-], [Hz²], [Hz²]
        blend_normalised, blend_variance : ndarray (n,)
            The blend's normalised innovation and innovation variance S in this block.
        learn : ndarray of bool (n,)
            Modes whose probability may change in this block (out of sample: the model
            had not seen the block).
        """
        rho = np.clip(error_correlation, 0.0, 0.99)
        sigma2 = np.maximum(error_variance + white_variance, 1e-300)
        fresh = np.isfinite(z) & ~np.isfinite(self.level)
        if fresh.any():  # start at the first measurement, with the measurement's variance
            self.level[fresh] = z[fresh]
            self.error[fresh] = 0.0
            self.P[fresh] = 0.0
            self.P[fresh, 0, 0] = sigma2[fresh]
            self.P[fresh, 1, 1] = error_variance[fresh]
        on = np.isfinite(self.level) & ~fresh
        if not on.any():
            return
        idx = np.flatnonzero(on)
        # x = Fx ; P = FPF' + Q with F = diag(1, ρ), Q = diag(q, σ_e²(1 - ρ²))
        F = np.stack([np.ones(idx.size), rho[idx]], axis=1)
        P = self.P[idx] * (F[:, :, None] * F[:, None, :])
        P[:, 0, 0] += LEVEL_STEP_VARIANCE * sigma2[idx]
        P[:, 1, 1] += error_variance[idx] * (1 - rho[idx] ** 2)
        level = self.level[idx]
        error = self.error[idx] * rho[idx]
        have = np.isfinite(z[idx])
        if have.any():
            h = np.flatnonzero(have)
            # y = z - Hx ; S = HPH' + R  (H = [1 1])
            y = z[idx][h] - level[h] - error[h]
            S = P[h, 0, 0] + P[h, 1, 1] + 2 * P[h, 0, 1] + white_variance[idx][h]
            nu = y / np.sqrt(S)
            # Huber weight as in the blend: beyond k the measurement counts as if k out
            a = np.abs(nu)
            extra = np.where(a > self.huber_sigma, S * (a / self.huber_sigma - 1.0), 0.0)
            S_eff = S + extra
            # K = PH'S⁻¹ ; x = x + Ky ; P = (I - KH) P (I - KH)' + K R K' (Joseph form)
            PH = np.stack([P[h, 0, 0] + P[h, 0, 1], P[h, 1, 0] + P[h, 1, 1]], axis=1)
            K = PH / S_eff[:, None]
            level[h] += K[:, 0] * y
            error[h] += K[:, 1] * y
            A = np.eye(2)[None, :, :] - K[:, :, None] * np.ones((1, 1, 2))
            R_eff = white_variance[idx][h] + extra
            P[h] = A @ P[h] @ np.transpose(A, (0, 2, 1)) + R_eff[:, None, None] * (
                K[:, :, None] * K[:, None, :]
            )
            # probability: p̄ = (1 - π) p + π (1 - p) ; p ∝ p̄ L₁, 1 - p ∝ (1 - p̄) L₀
            j = idx[h]
            use = learn[j] & np.isfinite(blend_normalised[j]) & np.isfinite(blend_variance[j])
            if use.any():
                jj = j[use]
                l1 = self._log_likelihood(blend_normalised[jj], blend_variance[jj])
                l0 = self._log_likelihood(nu[use], S[use])
                p = self.probability[jj]
                prior = (1 - SWITCH_PROBABILITY) * p + SWITCH_PROBABILITY * (1 - p)
                log_odds = np.log(prior) - np.log1p(-prior) + l1 - l0
                self.probability[jj] = np.clip(1.0 / (1.0 + np.exp(-log_odds)), P_MIN, P_MAX)
        self.level[idx], self.error[idx], self.P[idx] = level, error, P

    def combine(
        self, blend_estimate: np.ndarray, blend_variance: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Probability-weighted estimate [Hz] and its variance [Hz²] (module docstring)."""
        p = self.probability
        x0 = np.where(np.isfinite(self.level), self.level, blend_estimate)
        P0 = np.where(np.isfinite(self.level), self.P[:, 0, 0], blend_variance)
        x = p * blend_estimate + (1 - p) * x0
        P = p * (blend_variance + (blend_estimate - x) ** 2) + (1 - p) * (P0 + (x0 - x) ** 2)
        return x, P

    def reset(self, j: int) -> None:
        """Forget mode *j*'s model-free filter (it restarts at the next measurement)."""
        self.level[j] = np.nan
        self.error[j] = 0.0
        self.P[j] = 0.0
