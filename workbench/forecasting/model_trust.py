"""Does the model still explain the mode? The blend against model-free filters, by likelihood.

The memory forecast's filter (:mod:`workbench.forecasting.memory.kalman`) estimates
x = m + c with the model's prediction m; when something changes that no predictor
records (fuel burnt without soundings, ballast, ice on deck), its noise model, fitted on
residuals from before the change, can trust m more than the data allow, and the blend
ends up worse than the raw SSI estimate. Beside it, this module runs filters that do not
use the model at all:

.. math::

    x_k = x_{k-1} + w_k, \\quad z_k = x_k + e_k + v_k,

(the level x a random walk, var w = q (σ_e² + σ_v²) with q from
:data:`LEVEL_STEP_VARIANCES`, a filter that stays close to the raw SSI estimate; the
identification error e, with the blend's states - one AR(1) state or the overlap's
segment terms, :mod:`workbench.forecasting.memory.kalman` - and v as in the blend's noise
model), and weighs the hypotheses H₁ "the model explains the mode" (the blend) and H₀
"it does not" (each model-free filter) by the likelihood of each block's measurement
under each filter's one-step prediction, with a small probability of switching between
blocks (a multiple-model filter without state mixing, [1]_ §11.6). The model-free filters
take the blend's persistence rule (a run of large innovations of one sign as long as the
blocks sharing data is a move of the level, which they then follow with a gain of about 1),
so that after a real jump they predict as well as the blend does. The likelihood uses
Huber-clipped normalised innovations (one mis-selected pole cannot decide it), each
block's evidence is capped at :data:`EVIDENCE_CAP`, and only out-of-sample blocks count (the model was fitted to the training blocks). The estimate is
the weighted mean of the filters' estimates,

.. math:: \\hat x = \\sum_i w_i \\hat x_i, \\qquad
          P = \\sum_i w_i (P_i + (\\hat x_i - \\hat x)^2),

with the blend's weight w₁ = min(1, p₁ / :data:`FULL_WEIGHT_PROBABILITY`) f_L and the rest
shared by the model-free filters in proportion to their probabilities; p₁ f_L, the
probability that the model explains the mode, is the forecast table's
``model_probability``.

*The follow test.* A level random walk lags a mode that keeps moving (by s (1 - K) / K
for a ramp of s per block, K its gain; 0.62 s at q = 1), and where SSI's own error is
smaller than that lag the fallback is worse than SSI. Such a lag shows in the filter's
innovations, which are then of one sign: over its newest persist_blocks innovations the
sign test of the blend's innovation consistency
(:mod:`workbench.forecasting.innovation_consistency`, ψ clipped at 1.5, level 5 % over
the persist_blocks tests each innovation takes part in) says whether the model-free
filter explains the measurements; where it does not, neither hypothesis does, and where
the blend takes every measurement without Huber weight (its noise levels the prior's,
method 1's single window throughout) that filter's share of the estimate is the block's
SSI estimate (:meth:`ModelTrust.combine`). The probabilities are not changed by the test.

The one-step prediction of a block's measurement is out of sample for every filter, so the
weights measure which of them predicts the data better as the voyage goes on: a guard that
measures whether leaning on the model still helps, and falls back to the model-free
estimate (which follows SSI) when it does not.

*The lead test* (factor f_L). The one-step prediction includes the identification error
the next block shares with this one, so a noise model that gives part of the model's
error to the identification error (the split of the residuals is ill-determined,
:mod:`workbench.forecasting.noise`) still predicts the next block well while its estimate
of x, which leaves that part out, is worse than SSI's. L blocks ahead (L = the blocks
that share data, 4 for 20-minute blocks every 5 minutes) the measured block shares no
data with any block either filter has seen: its identification error is independent of
both predictions, the blend's overlap states predict 0 for it, and the difference of the
two filters' mean squared errors of prediction is an unbiased estimate of the difference
of their errors about the true frequency L blocks ahead. Each filter holds its present
estimate of what the model does not explain: the blend predicts the model's value of that
block's measurement plus its present correction ĉ, the model-free filter its present
level. The two differ by the model's change over the L blocks (what the predictors
record) and by the split of the present residual; the blend's decay of c (φ^L) is left
out, because the test is about the split, and τ_c, ill-determined from a short record,
hardly matters to the estimate but would decide the test (a decayed correction measured
worse on the 12-h demo and on the 40-minute wander:
``benchmarks/results/forecast_accuracy_27c.txt``). Each block's evidence is the log-likelihood
ratio of the two errors under one variance (their mean square, averaged over
1 / :data:`LEAD_FORGET` blocks), capped at :data:`EVIDENCE_CAP` and divided by L
(predictions made at consecutive blocks overlap); it updates p_L, the probability that
the blend predicts better (prior :data:`LEAD_PRIOR`, switching as above), and
f_L = min(1, p_L / :data:`LEAD_PRIOR`): the blend keeps its whole weight until the
measured evidence is against it. The test is weak where the unexplained change has a time
constant of about L blocks (both predictions then nearly as poor as the mean).

*The lead test against SSI* (factor f_S). The same test with the block's SSI estimate as the
competitor: L blocks ahead SSI predicts the model's value of that block's measurement plus
its present residual z_k - m_k. Where the split of the residuals leaves the blend's
correction behind a move that no predictor records but that lasts (a slow change of the
hull between two firings of the change test), neither the one-step likelihood nor the
model-free level measures that SSI errs less than the blend; the difference of the two
mean squared errors of prediction does. The evidence, as the lead test's, is pooled over
the modes measured out of sample (each mode's capped and divided by L; a hull-wide move
shows in all of them), updates p_S, the probability that the blend (with its model-free
share) errs less than SSI (prior 1/2, switching :data:`SSI_SWITCH_PROBABILITY`: the
evidence is L blocks old, so the probability has to leave and come back within hours),
and the estimate is f_S x̂ + (1 - f_S) z_k with f_S = min(1, p_S /
:data:`SSI_FULL_WEIGHT_PROBABILITY`) (the worked example's last hour, measured in
``benchmarks/results/forecast_worst_seeds_54.txt``).

*The hull-wide change test.* An ice load (added mass and stiffness) moves every mode of
the hull at once, and the model explains none of the moves; each mode's evidence alone
needs several blocks to move its probability, while the modes together say it in a few.
Each block's normalised innovations of the blend, ψ-clipped as in the follow test, are
pooled over the n modes measured out of sample, T = Σ ψ(ν_j) / sqrt(n m_ψ) (N(0, 1)
while the model explains the modes and their SSI errors are independent), and a
two-sided CUSUM (drift :data:`CHANGE_DRIFT`, threshold :data:`CHANGE_THRESHOLD`) marks a
change of one sign that lasts; while it is on, the blend stands aside (weight 0) and the
model-free share of the estimate is the block's SSI estimate (a level random walk lags
such a move, and SSI errs less than the lag). Moves of single modes, or of modes in
opposite directions, cancel in T and leave it to each mode's probability. The CUSUM
forgets by the drift each block, so the blend comes back when its innovations have been
balanced for a while (the 20-minute ice voyages and the worked example, measured with
and without it: ``benchmarks/results/forecast_level_slope_53.txt``).

*After a hole.* After a hole in the record the model's probability is at most the
prior's again (:meth:`ModelTrust._after_hole`), so the estimate is mostly the model-free
level's, and a ship that changes speed right after the hole moves the modes
faster than the level's random walk follows. In the first blocks after it, while the
refits settle, the level may step by the structural prior on the predictors' move
(:attr:`BlendStep.level_step_variance`, the prior of the band inside the hole:
``benchmarks/results/forecast_after_hole_step_54.txt``).

References
----------
.. [1] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, "Estimation with Applications to Tracking
   and Navigation", Wiley, 2001, ch. 11.6 (multiple-model estimation).
   doi:10.1002/0471221279
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import norm

from .innovation_consistency import ALPHA, TEST_CLIP, clipped_square_moments
from .memory.kalman import kalman_predict, kalman_update
from .memory.noise import run_after_hole, update_run

__all__ = ["BlendStep", "ModelTrust"]

#: Probability that the hypothesis changes from one block to the next (one switch in about
#: 4 hours of 5-minute blocks): p follows the accumulated evidence, and stretches in which
#: both filters predict equally well (the ship holds one speed) leave it where it is. It
#: also bounds how sure either hypothesis gets: from its floor the blend's log-odds must
#: move ln(0.75 / 0.25) - ln(π / (1 - π)), 5 nats, before its weight starts to fall, at
#: most :data:`EVIDENCE_CAP` a block - after a long stretch the model explained, the blend
#: stands aside within about five blocks of a change it does not explain (one switch in 2
#: days, 0.002, took about eight: benchmarks/results/forecast_trust_switch_27j.txt and
#: forecast_soft_split_27m.txt). [-]
SWITCH_PROBABILITY = 0.02
#: Level random-walk variances of the model-free filters per block, in units of the
#: identification error's variance σ_e² + σ_v²: a level that moves by about the SSI
#: scatter every block, so the filter stays close to the raw SSI estimate (a slower
#: filter, 0.1, measured better on slow unrecorded wander but lagged real moves and
#: cost the 12-h demo 2-4 points; benchmarks/results/forecast_accuracy_27.txt). [-]
LEVEL_STEP_VARIANCES = (1.0,)
#: The hull-wide change test's drift and threshold (a two-sided CUSUM on the blend's
#: normalised innovations pooled over the measured modes, module docstring), in standard
#: deviations of the pooled statistic: a lower threshold set it off in the open water of
#: the 20-min ice voyages, a higher one later in the ice
#: (``benchmarks/results/forecast_level_slope_53.txt``); None switches the test off. [-]
CHANGE_DRIFT = 0.5
CHANGE_THRESHOLD: float | None = 8.0
#: Probability that the lead test against SSI's hypothesis ("the blend errs less than SSI")
#: changes from one block to the next, and the probability below which the estimate moves
#: to the block's SSI (module docstring): pulled from p_S = 0.5 on (switch 0.05) the
#: estimate left the blend where it gained (the 6-h demo), from 0.1 on it left the worked
#: example's seed 2 where it was (``benchmarks/results/forecast_worst_seeds_54.txt``). [-]
SSI_SWITCH_PROBABILITY = 0.1
SSI_FULL_WEIGHT_PROBABILITY = 0.25
#: Probability that the model explains a mode before its first out-of-sample block: the
#: model-free hypothesis is favoured (4 : 1) until the model has predicted blocks it had not
#: seen (the start-up blocks, and method 1's single window, whose model is fitted once on the
#: first window); with :data:`FULL_WEIGHT_PROBABILITY` the blend still starts with weight
#: 0.8, and evidence of up to :data:`EVIDENCE_CAP` per block moves it either way. [-]
PRIOR_PROBABILITY = 0.2
#: The blend's probability below which the estimate starts to move to the model-free
#: filters (a model-free filter three times as probable as the blend): while the
#: evidence is weaker, the blend, which measures best where the model explains the mode,
#: keeps its whole weight. [-]
FULL_WEIGHT_PROBABILITY = 0.25
#: Most evidence one block can give against the best-predicting hypothesis (log
#: likelihood ratio): a stretch of outliers as long as the blocks sharing data, or the
#: first blocks of a real move (which the blend takes once it persists), cannot decide
#: alone. [nats]
EVIDENCE_CAP = 1.0
#: Probability that the blend predicts the measurement lead_blocks ahead better than the
#: model-free filter, before any such prediction was scored (no evidence either way). [-]
LEAD_PRIOR = 0.5
#: Probability that the lead test's hypothesis changes from one block to the next (one
#: switch in about 2 days): its evidence comes at most EVIDENCE_CAP / L a block (predictions
#: made at consecutive blocks overlap), so a faster switch (:data:`SWITCH_PROBABILITY`)
#: would hold p_lead near its prior and the test could not leave a blend whose split
#: hides the model error (tests/forecast/test_model_trust.py). [-]
LEAD_SWITCH_PROBABILITY = 0.002
#: Forgetting of the scale of the lead test's squared errors (time constant 1/LEAD_FORGET
#: blocks). [-]
LEAD_FORGET = 1.0 / 96
#: Smallest and largest model probability (neither hypothesis is ever ruled out). [-]
P_MIN, P_MAX = 1e-4, 1.0 - 1e-4


@dataclass(frozen=True)
class BlendStep:
    """The blend's filter in one block, as :meth:`ModelTrust.step` weighs it.

    Parameters
    ----------
    normalised, variance : ndarray (n,)
        The blend's normalised innovation and innovation variance S in this block. [-], [Hz²]
    state : ndarray (n, s), optional
        The blend's a-posteriori state of this block, for the lead test (None: no test).
    measurement_model : ndarray (n,), optional
        The model's value of this block's measurement (the blend predicts z = this +
        H x). [Hz]
    unweighted : ndarray of bool (n,), optional
        Modes whose blend takes every measurement without Huber weight (its noise levels
        are the prior's, :func:`~workbench.forecasting.memory.noise.filter_matrices`):
        only there may :meth:`ModelTrust.combine` follow SSI in place of a lagging
        model-free level (None: nowhere).
    after_hole : bool
        The block ends a hole in the record (no mode measured for at least
        ``persist_blocks`` blocks): the model-free filters, too, take a large innovation
        as a move of the level (their state is as old as the hole), not as SSI's outlier.
    settling : bool
        The block is among the first after a hole, while the refits hand the model's
        error over from c (:mod:`~workbench.forecasting.memory.forecast`'s refit
        continuity): the hull-wide change test starts again after them.
    level_step_variance : ndarray (n,), optional
        Variance the model-free filters' level may step in this block beside its random
        walk (the predictors' move in the first blocks after a hole,
        :meth:`~workbench.forecasting.memory.forecast.MemoryRun._level_step_variance`;
        None: none). [Hz²]
    """

    normalised: np.ndarray
    variance: np.ndarray
    state: np.ndarray | None = None
    measurement_model: np.ndarray | None = None
    unweighted: np.ndarray | None = None
    after_hole: bool = False
    settling: bool = False
    level_step_variance: np.ndarray | None = None


class ModelTrust:
    """Model-free filters and the probability that the model explains each mode.

    Parameters
    ----------
    n_modes : int
    huber_sigma : float
        Normalised innovations are clipped at this many standard deviations in the
        likelihood. [-]
    prior_probability : float
        Probability of "the model explains the mode" before any measurement. [-]
    persist_blocks : int or None
        The blend's persistence rule, applied to the model-free filters too: a run of
        this many consecutive normalised innovations of one sign beyond *huber_sigma* is
        a move of the level, not an outlier (no Huber weight, P_xx raised to y², the gain
        about 1), so a model-free filter follows a real jump of the frequency as fast as
        the blend does. None: Huber weights only.
    """

    def __init__(
        self,
        n_modes: int,
        huber_sigma: float,
        prior_probability: float = PRIOR_PROBABILITY,
        level_steps: tuple[float, ...] = LEVEL_STEP_VARIANCES,
        persist_blocks: int | None = None,
        states: int = 2,
        lead_blocks: int = 0,
    ):
        self.huber_sigma = float(huber_sigma)
        self.prior_probability = float(prior_probability)
        self.persist_blocks = None if persist_blocks is None else int(persist_blocks)
        self.steps = np.asarray(level_steps, dtype=float)  # one model-free filter each
        n_free = self.steps.size
        self.level = np.full((n_free, n_modes), np.nan)  # model-free estimates x̂₀ [Hz]
        # their identification-error states (the blend's layout: one AR(1) state or the
        # overlap's segment terms) [Hz]
        self.error = np.zeros((n_free, n_modes, states - 1))
        self.P = np.zeros((n_free, n_modes, states, states))
        # signed runs of large innovations of each model-free filter (memory.noise.update_run)
        self.run = np.zeros((n_free, n_modes), dtype=np.int64)
        # hypothesis probabilities: row 0 the blend, then the model-free filters
        self.weights = np.empty((n_free + 1, n_modes))
        self.weights[0] = float(prior_probability)
        self.weights[1:] = (1.0 - float(prior_probability)) / n_free
        # the lead test: each filter's prediction of the measurement lead_blocks ahead (the
        # blend's without the model's value then), the test's probability that the blend
        # predicts better, and the scale of the squared prediction errors
        self.lead = int(lead_blocks)
        self.lead_blend = np.full((max(self.lead, 1), n_modes), np.nan)
        self.lead_free = np.full((max(self.lead, 1), n_modes), np.nan)
        self.lead_at = 0
        self.lead_probability = np.full(n_modes, LEAD_PRIOR)
        self.lead_scale = np.full(n_modes, np.nan)
        # the lead test against SSI: SSI's residual from the model at each of the newest
        # lead_blocks blocks, the scale of the squared errors and the hull-wide probability
        # that the blend errs less than SSI
        self.lead_ssi = np.full((max(self.lead, 1), n_modes), np.nan)
        self.ssi_scale = np.full(n_modes, np.nan)
        self.ssi_probability = 0.5
        # the follow test: each model-free filter's newest persist_blocks normalised
        # innovations (NaN: not yet measured), whether they put it off to one side of
        # the measurements, and this block's measurement with its variance
        self.recent = np.full((n_free, n_modes, self.persist_blocks or 0), np.nan)
        n_recent = self.recent.shape[2]
        self.follow_mean_square = clipped_square_moments(TEST_CLIP)[0]
        self.follow_critical = float(norm.isf(ALPHA / (2 * n_recent))) if n_recent else np.inf
        self.off_side = np.zeros((n_free, n_modes), dtype=bool)
        self.measurement = np.full(n_modes, np.nan)
        self.measurement_variance = np.full(n_modes, np.nan)
        # the hull-wide change test: the CUSUM's two sums (up, down), whether it is on,
        # and this block's measurement [Hz]
        self.change_sums = np.zeros(2)
        self.change = False
        self.measured = np.full(n_modes, np.nan)

    @property
    def lead_factor(self) -> np.ndarray:
        """The lead test's factor on the blend's weight, min(1, p_lead / LEAD_PRIOR)
        (1 without the test). [-]"""
        if not self.lead:
            return np.ones(self.weights.shape[1])
        return np.clip(self.lead_probability / LEAD_PRIOR, 0.0, 1.0)

    @property
    def ssi_factor(self) -> float:
        """The lead test against SSI's factor on the estimate, min(1, p_S /
        SSI_FULL_WEIGHT_PROBABILITY) (the rest is the block's SSI estimate). [-]"""
        return float(min(1.0, self.ssi_probability / SSI_FULL_WEIGHT_PROBABILITY))

    @property
    def probability(self) -> np.ndarray:
        """Probability that the model explains each mode: the one-step hypothesis
        probability times :attr:`lead_factor` (the forecast table's
        ``model_probability``). [-]"""
        return self.weights[0] * self.lead_factor

    def _log_likelihood(self, normalised: np.ndarray, variance: np.ndarray) -> np.ndarray:
        # log N(y; 0, S) with ν² Huber-clipped: -0.5 (log S + ρ_H(ν))
        a = np.abs(normalised)
        k = self.huber_sigma
        rho = np.where(a <= k, a * a, 2 * k * a - k * k)
        return -0.5 * (np.log(variance) + rho)

    def step(
        self,
        z: np.ndarray,
        transition: np.ndarray,
        error_step_variance: np.ndarray,
        error_variance: np.ndarray,
        white_variance: np.ndarray,
        blend: BlendStep,
        learn: np.ndarray,
    ) -> None:
        """One block: predict and update the model-free filters, then the probabilities.

        Parameters
        ----------
        z : ndarray (n,)
            The block's measurement (NaN: none). [Hz]
        transition : ndarray (n, s, s)
            The blend's F (:func:`~workbench.forecasting.memory.kalman.transition_matrices`);
            its identification-error part (rows and columns 1 ..) is used.
        error_step_variance : ndarray (n, s)
            The blend's Q of the identification error's states (this block's scale). [Hz²]
        error_variance, white_variance : ndarray (n,)
            σ_e² (stationary) and the block's white variance R of the blend's noise model
            (the same identification error under every hypothesis). [Hz²]
        blend : BlendStep
            The blend's filter in this block.
        learn : ndarray of bool (n,)
            Modes whose probabilities may change in this block (out of sample: the model
            had not seen the block).
        """
        blend_normalised, blend_variance = blend.normalised, blend.variance
        if blend.after_hole:
            self._after_hole(np.isfinite(z))
        blend_state, measurement_model = blend.state, blend.measurement_model
        sigma2 = np.maximum(error_variance + white_variance, 1e-300)
        # SSI's estimate where the blend takes it without Huber weight (NaN elsewhere: the
        # follow test's substitute; where the blend judges outliers, a run of them as
        # long as the blocks sharing data is the persistence rule's to accept)
        unweighted = np.zeros(z.shape, dtype=bool) if blend.unweighted is None else blend.unweighted
        self.measurement = np.where(unweighted, np.asarray(z, dtype=float), np.nan)
        self.measurement_variance = sigma2.copy()
        log_l = np.full(self.weights.shape, np.nan)
        log_l[0] = self._blend_log_likelihood(blend_normalised, blend_variance)
        if blend.after_hole or blend.settling:
            # the first innovations after a hole are the filter's stale state and the
            # refits' handover, not a move of the hull: the test starts again after them
            self.change_sums[:] = 0.0
            self.change = False
        else:
            self._change_step(blend_normalised, learn)
        self.measured = np.asarray(z, dtype=float).copy()
        for h, step in enumerate(self.steps):
            log_l[h + 1] = self._free_step(
                h,
                step,
                z,
                transition,
                error_step_variance,
                sigma2,
                white_variance,
                blend.after_hole,
                blend.level_step_variance,
            )
        use = learn & np.isfinite(log_l).all(axis=0)
        if use.any():
            # p̄_i = (1 - π) p_i + π (1 - p_i) / (H - 1) ; p_i ∝ p̄_i L_i
            n_h = self.weights.shape[0]
            w = self.weights[:, use]
            prior = (1 - SWITCH_PROBABILITY) * w + SWITCH_PROBABILITY * (1 - w) / (n_h - 1)
            # evidence per block at most EVIDENCE_CAP nats against the best hypothesis: a
            # stretch of outliers as long as the blocks sharing data cannot decide alone
            ll = log_l[:, use]
            ll = np.maximum(ll, ll.max(axis=0, keepdims=True) - EVIDENCE_CAP)
            log_post = np.log(prior) + ll
            log_post -= log_post.max(axis=0, keepdims=True)
            post = np.exp(log_post)
            post /= post.sum(axis=0, keepdims=True)
            post = np.clip(post, P_MIN, P_MAX)
            self.weights[:, use] = post / post.sum(axis=0, keepdims=True)
        if self.lead and blend_state is not None:
            self._lead_step(z, blend_state, measurement_model, learn)

    def _change_step(self, normalised: np.ndarray, learn: np.ndarray) -> None:
        """The hull-wide change test (module docstring) after the blend's innovations of
        one block: T = Σ ψ(ν_j) / sqrt(n m_ψ) over the n modes measured out of sample,
        ψ clipped at :data:`~workbench.forecasting.innovation_consistency.TEST_CLIP` and
        m_ψ its mean square (T ~ N(0, 1) while the model explains the modes and their
        errors are independent); the CUSUM sums g⁺ = max(0, g⁺ + T - d),
        g⁻ = max(0, g⁻ - T - d) and the change is on while either exceeds the threshold."""
        if CHANGE_THRESHOLD is None:
            return
        ok = learn & np.isfinite(normalised)
        if not ok.any():
            return
        psi = np.clip(normalised[ok], -TEST_CLIP, TEST_CLIP)
        t = psi.sum() / np.sqrt(ok.sum() * self.follow_mean_square)
        up, down = self.change_sums
        up = max(0.0, up + t - CHANGE_DRIFT)
        down = max(0.0, down - t - CHANGE_DRIFT)
        self.change_sums[:] = up, down
        self.change = bool(max(up, down) > CHANGE_THRESHOLD)

    def _after_hole(self, measured: np.ndarray) -> None:
        """After a hole in the record, the measured modes' probability that the model
        explains them at most the prior's (:data:`PRIOR_PROBABILITY`), the rest shared by
        the model-free filters.

        The probabilities are updated only on measured blocks, so across a hole they keep
        what the blocks before it said, while the model only extrapolated there (the ship
        may have left port, the model knows it at rest): its trust has to be earned again
        on the measurements after the hole, as at the start."""
        w0 = np.minimum(self.weights[0, measured], self.prior_probability)
        self.weights[0, measured] = w0
        self.weights[1:, measured] = (1.0 - w0) / self.steps.size

    def _lead_step(self, z, blend_state, measurement_model, learn) -> None:
        """The lead test (module docstring): score the predictions made lead_blocks ago,
        then store this block's."""
        slot = self.lead_at % self.lead
        blend = measurement_model + self.lead_blend[slot]
        free = self.lead_free[slot]
        e_b, e_f = z - blend, z - free
        ok = learn & np.isfinite(e_b) & np.isfinite(e_f)
        if ok.any():
            square = 0.5 * (e_b[ok] ** 2 + e_f[ok] ** 2)
            old = self.lead_scale[ok]
            scale = np.where(np.isfinite(old), old + LEAD_FORGET * (square - old), square)
            self.lead_scale[ok] = scale
            # log-likelihood ratio of the two point predictions under one error variance
            ratio = (e_f[ok] ** 2 - e_b[ok] ** 2) / (2.0 * np.maximum(scale, 1e-300))
            ratio = np.clip(ratio, -EVIDENCE_CAP, EVIDENCE_CAP) / self.lead
            p = self.lead_probability[ok]
            p = (1 - LEAD_SWITCH_PROBABILITY) * p + LEAD_SWITCH_PROBABILITY * (1 - p)
            odds = np.log(p) - np.log1p(-p) + ratio
            self.lead_probability[ok] = np.clip(1.0 / (1.0 + np.exp(-odds)), P_MIN, P_MAX)
        self._ssi_lead_step(z, e_b, measurement_model, learn, slot)
        # predictions of the measurement lead_blocks ahead, each filter holding its present
        # estimate of what the model does not explain: the blend's correction c (the
        # model's value of that block is added then), the model-free filter's level; the
        # identification error of that block is independent of both (predicted 0)
        self.lead_blend[slot] = blend_state[:, 0]
        self.lead_free[slot] = self.level[0]
        self.lead_at += 1

    def _ssi_lead_step(self, z, e_b, measurement_model, learn, slot) -> None:
        """The lead test against SSI (module docstring): the blend's error e_b of the
        prediction made lead_blocks ago against SSI's (the model's value of this block's
        measurement plus SSI's residual then), the evidence pooled over the modes; then
        this block's residual is stored."""
        e_s = z - (measurement_model + self.lead_ssi[slot])
        ok = learn & np.isfinite(e_b) & np.isfinite(e_s)
        if ok.any():
            square = 0.5 * (e_b[ok] ** 2 + e_s[ok] ** 2)
            old = self.ssi_scale[ok]
            scale = np.where(np.isfinite(old), old + LEAD_FORGET * (square - old), square)
            self.ssi_scale[ok] = scale
            ratio = (e_s[ok] ** 2 - e_b[ok] ** 2) / (2.0 * np.maximum(scale, 1e-300))
            ratio = np.clip(ratio, -EVIDENCE_CAP, EVIDENCE_CAP) / self.lead
            p = self.ssi_probability
            p = (1 - SSI_SWITCH_PROBABILITY) * p + SSI_SWITCH_PROBABILITY * (1 - p)
            odds = np.log(p) - np.log1p(-p) + ratio.sum()
            self.ssi_probability = float(np.clip(1.0 / (1.0 + np.exp(-odds)), P_MIN, P_MAX))
        self.lead_ssi[slot] = z - measurement_model

    def _blend_log_likelihood(self, normalised, variance):
        out = np.full(normalised.shape, np.nan)
        ok = np.isfinite(normalised) & np.isfinite(variance) & (variance > 0)
        out[ok] = self._log_likelihood(normalised[ok], variance[ok])
        return out

    def _free_step(
        self,
        h,
        step,
        z,
        transition,
        error_step_variance,
        sigma2,
        white_variance,
        after_hole,
        level_step_variance=None,
    ):
        """Predict and update model-free filter *h*; its log-likelihood of z (NaN: none).

        States [x, identification error's states]: F = the blend's with 1 for the level,
        Q = the blend's identification part and q (σ_e² + σ_v²) for the level, plus
        *level_step_variance* (:class:`BlendStep`) where given; the step is
        the blend's (:func:`~workbench.forecasting.memory.kalman.kalman_update`: Huber
        weights, the persistence rule, Joseph form).
        """
        out = np.full(z.shape, np.nan)
        level, error, P_all = self.level[h], self.error[h], self.P[h]
        fresh = np.isfinite(z) & ~np.isfinite(level)
        if fresh.any():  # start at the first measurement, with the measurement's variance
            level[fresh] = z[fresh]
            error[fresh] = 0.0
            P_all[fresh] = _stationary(transition[fresh], error_step_variance[fresh])
            P_all[fresh, 0, 0] = sigma2[fresh]
        on = np.isfinite(level) & ~fresh
        if not on.any():
            return out
        idx = np.flatnonzero(on)
        F = transition[idx].copy()
        F[:, 0, :] = 0.0
        F[:, :, 0] = 0.0
        F[:, 0, 0] = 1.0
        Q = error_step_variance[idx].copy()
        Q[:, 0] = step * sigma2[idx]
        if level_step_variance is not None:
            Q[:, 0] += level_step_variance[idx]
        state = np.concatenate([level[idx, None], error[idx]], axis=1)
        run = self.run[h, idx]
        state, P_prior = kalman_predict(state, P_all[idx], F, Q)
        judged = run
        if after_hole and self.persist_blocks is not None:
            # as the blend after a hole (MemoryRun._run_after_hole): a large innovation
            # moves the level at once
            judged = run_after_hole(run, z[idx] - state.sum(axis=1), self.persist_blocks)
        state, P, _, nu, S, _ = kalman_update(
            state,
            P_prior,
            z[idx],
            white_variance[idx],
            self.huber_sigma,
            previous_run=judged if self.persist_blocks is not None else None,
            persist_blocks=self.persist_blocks or 0,
        )
        have = np.isfinite(nu)
        out[idx[have]] = self._log_likelihood(nu[have], S[have])
        self._follow_test(h, idx[have], nu[have])
        self.run[h, idx] = update_run(run, nu, np.full(idx.size, self.huber_sigma))
        level[idx], error[idx], P_all[idx] = state[:, 0], state[:, 1:], P
        return out

    def _follow_test(self, h: int, modes: np.ndarray, normalised: np.ndarray) -> None:
        """The follow test of model-free filter *h* after a block that measured *modes*.

        A level random walk lags a mode that keeps moving (a ramp of s per block: by
        s (1 - K) / K, K its gain) and its innovations are then of one sign. Over its
        newest n = persist_blocks innovations (a run as long as that is not one corrupted
        stretch of data) the sign test of
        :class:`~workbench.forecasting.innovation_consistency.InnovationConsistency`:
        mean ψ(ν), ψ clipped at :data:`~workbench.forecasting.innovation_consistency.TEST_CLIP`
        (one outlier cannot decide it), has standard deviation √(m_k / n) while the filter
        explains the measurements; beyond z_{1-α/(2n)} of them it does not, and
        :meth:`combine` takes the block's SSI estimate in its place. The test runs every
        block on a window that moves by one, so each innovation takes part in n of them:
        at α/n a test (Bonferroni), an innovation sets it off by chance with probability at
        most α, the consistency test's level (at α a test the method-1 rows of the suite
        lost up to 1.9 of median and 6.8 of worst seed:
        ``benchmarks/results/forecast_method1_demo_27s.txt``).
        """
        n = self.recent.shape[2]
        if not n or modes.size == 0:
            return
        recent = self.recent[h]
        recent[modes] = np.roll(recent[modes], -1, axis=1)
        recent[modes, -1] = normalised
        psi = np.clip(recent[modes], -TEST_CLIP, TEST_CLIP)
        with np.errstate(invalid="ignore"):
            statistic = np.abs(psi.mean(axis=1)) * np.sqrt(n / self.follow_mean_square)
        self.off_side[h, modes] = np.isfinite(statistic) & (statistic > self.follow_critical)

    def combine(
        self, blend_estimate: np.ndarray, blend_variance: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Probability-weighted estimate [Hz] and its variance [Hz²] (module docstring).

        A model-free filter whose newest innovations put it off to one side of the
        measurements (:meth:`_follow_test`) explains them no better than the model does:
        where the blend takes every measurement without Huber weight (the prior's noise
        levels: method 1's single window, the first windows of method 2) its share of the
        estimate is the block's SSI estimate, with the identification error's variance.
        Where the blend has a Huber weight, a stretch of outliers as long as the blocks
        sharing data would set the test off too, and following SSI there would undo the
        persistence rule (``benchmarks/results/forecast_method1_demo_27s.txt``).
        While the hull-wide change test is on (:meth:`_change_step`) the blend's weight is
        0 and every model-free filter's share is the block's SSI estimate; otherwise the
        lead test against SSI moves 1 - :attr:`ssi_factor` of the estimate to the block's
        SSI estimate.
        """
        started = np.isfinite(self.level)
        level = np.where(started, self.level, blend_estimate)
        level_variance = np.where(started, self.P[:, :, 0, 0], blend_variance)
        follow = self.off_side & np.isfinite(self.measurement)
        level = np.where(follow, self.measurement, level)
        level_variance = np.where(follow, self.measurement_variance, level_variance)
        if self.change:  # the hull moves: the model-free share is the block's SSI
            have = np.isfinite(self.measured)
            level = np.where(have, self.measured, level)
            level_variance = np.where(have, self.measurement_variance, level_variance)
        xs = np.concatenate([blend_estimate[None], level])
        Ps = np.concatenate([blend_variance[None], level_variance])
        # the blend keeps its whole weight until its probability falls below
        # FULL_WEIGHT_PROBABILITY; below, its weight is p / FULL_WEIGHT_PROBABILITY and the
        # rest goes to the model-free filters in proportion to their probabilities
        w = self.weights.copy()
        w[0] = np.clip(self.weights[0] / FULL_WEIGHT_PROBABILITY, 0.0, 1.0)
        w[0] *= self.lead_factor
        if self.change:  # ... and the blend stands aside
            w[0] = 0.0
        rest = self.weights[1:].sum(axis=0)
        w[1:] = self.weights[1:] / np.where(rest > 0, rest, 1.0) * (1.0 - w[0])
        x = (w * xs).sum(axis=0)
        P = (w * (Ps + (xs - x) ** 2)).sum(axis=0)
        f = self.ssi_factor
        if not self.change and f < 1.0:  # the lead test against SSI
            have = np.isfinite(self.measured)
            z = np.where(have, self.measured, x)
            g = np.where(have, f, 1.0)
            mixed = g * x + (1 - g) * z
            P = g * (P + (x - mixed) ** 2) + (1 - g) * (
                self.measurement_variance + (z - mixed) ** 2
            )
            x = mixed
        return x, P


def _stationary(transition: np.ndarray, step_variance: np.ndarray) -> np.ndarray:
    """Stationary covariance Σ_i F^i Q F'^i of the identification error's states (rows
    and columns 1 ..; F's spectral radius below 1 there), by doubling. [Hz²]"""
    n, s = step_variance.shape
    A = transition.copy()
    A[:, 0, :] = 0.0
    A[:, :, 0] = 0.0
    P = np.zeros((n, s, s))
    P[:, np.arange(s), np.arange(s)] = step_variance
    P[:, 0, 0] = 0.0
    for _ in range(7):  # P ← P + A P A', A ← A²: 2^7 terms of the sum
        P = P + A @ P @ np.transpose(A, (0, 2, 1))
        A = A @ A
    return P
