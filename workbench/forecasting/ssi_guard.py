"""Do no harm: the blended estimate may lie no farther from SSI than SSI's own error allows.

The blend (:mod:`workbench.forecasting.memory.forecast`) splits the residuals z - m into a
model error and an identification error by their correlation over blocks. A change that
no predictor records and that moves faster than one block step (an ice load, sea state)
looks white, as the identification error does, and the split books it as identification
error: the blend then smooths away a change SSI measured, and is worse than raw SSI
(``benchmarks/results/ice_voyage_blend_40.txt``). Nothing in the residuals can tell the two
apart; the block itself can. SSI on each half of the block
(:func:`~workbench.identification.engine.half_differences`, the modal table's
``half_difference_hz``) measures the block estimate's error variance,
R ≈ ((f₁ - f₂) / 2)², independently of any model of how the modes move.

*The test.* Write the blend's error a = x̂ - x and SSI's e = z - x, so d = x̂ - z = a - e.
Where blocks share no data (e independent from block to block) a blend whose noise model is
right has E[d²] = R - P ≤ R (P its posterior variance): it lies within SSI's scatter of SSI.
The guard compares the mean of d² over the last :data:`GUARD_BLOCKS` blocks of the mode
with R̄, the mean of R over the last :data:`R_BLOCKS` (one block's R is a one-degree-of-
freedom estimate; SSI's error changes with the excitation more slowly than an unlogged
change moves the mode); while mean d² ≤ R̄ the blend stands.

*The guarded estimate*, where the test fails. The blend's error is then not known, and its
correlation with e (the blend took part of z in) is not known either. Its *prediction* of
the block, x̂⁻ₖ = x̃ₖ₋₁ + (mₖ - mₖ₋₁) (the last guarded estimate, moved by what the model's
predictors record since), shares no data with block k, so its error a⁻ is independent of e
and the mean of d⁻² = (x̂⁻ - z)² over the window is E[a⁻²] + R: the prediction's error
variance A⁻ is measured. The best combination of the prediction and SSI is then

.. math:: \\tilde x = z + λ (\\hat x^- - z), \\qquad λ = \\bar R / \\overline{d^{-2}},
          \\qquad \\operatorname{var} \\tilde x = \\bar R (1 - λ),

(a Kalman update with a measured prior), whose error variance A⁻R / (A⁻ + R) is below R:
not worse than raw SSI. Where the prediction's mean is not above R̄ (or it has too few
blocks) the blend itself is drawn toward SSI, λ = R̄ / mean d² (the best weight when its
error is independent of SSI's), with variance (1 - λ)² R̄ + λ² P.

*A lone outlier.* The one block of the window whose d² is more than :data:`OUTLIER_SIGMA`²
times the mean of the others' is taken for an outlier of SSI (another column's pole): the
blend's own outlier weighting stands at that block (a single wild pole is not followed),
and the next prediction starts from x̂⁻ there. A fast unlogged change gives many large
distances, none alone.

*A change of the whole hull.* An unlogged change of mass or stiffness (ice on the hull,
ballast, cargo) moves every global mode at once, and the same way; another column's pole
is one mode's event, and a swap of two modes' labels moves them opposite ways. So where
:data:`HULL_MODES` or more modes have a lone outlier at the same block, all with SSI on the
same side of the blend, the distance is the hull's, not SSI's: the modes are not treated as
outliers, and the window - which holds only blocks from before the change - does not
describe the blend's error after it. That block's own distance does (one draw of
E[d²] = E[a²] + R), so its weight is at most R̄ / d²; the blocks after it have the large
distance in their window and are guarded as usual
(``benchmarks/results/ice_voyage_guard_48.txt``).

*Where it runs* (:class:`~workbench.forecasting.memory.forecast.MemoryRun`): on blocks that
share no data with their neighbours, and on blocks of varying length or an unknown grid.
Where blocks overlap n-fold (20-minute blocks every 5 minutes), consecutive SSI errors are
correlated. The bound itself still holds for the best filter (its x̂ - z is minus its
estimate of e given all the blocks, whose variance is at most R), but the blend is not that
filter there: the split of the residuals into a model error and the overlap's correlated
identification error is ill-determined (:mod:`~workbench.forecasting.innovation_consistency`),
and a blend that books part of one as the other lies farther than R from SSI while still
nearer the truth. On the overlapping block-level suite the test fired in regimes the model
explains and cost option A points of median (``ice_voyage_blend_40.txt``), so it is off
there (``guard_weight`` NaN). A test that needs no halves, the blend against SSI by how
well each predicts the block L on, was too weak where it was needed (the mode moves by
more in L blocks than either estimate errs; ``benchmarks/results/ice_voyage_blend_41.txt``).

A mode moving inside the block adds its move to f₁ - f₂, so R̄ errs on the large side and
the guard on the side of leaving the blend alone. Blocks without both halves (LSCF, a half
that does not show the mode, tables from before the column) leave the means; with fewer
than :data:`MIN_PAIRS` blocks holding both d and R the blend stands.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "GUARD_BLOCKS",
    "HULL_MODES",
    "MIN_PAIRS",
    "OUTLIER_SIGMA",
    "R_BLOCKS",
    "GuardWindow",
    "SSIGuard",
]

#: Blocks over which the distance from SSI is averaged (40 minutes of 5-minute steps). [-]
GUARD_BLOCKS = 8
#: Blocks over which SSI's error R̄ is averaged (module docstring; 2 hours of 5-minute
#: steps). [-]
R_BLOCKS = 24
#: Fewest blocks of the window holding both a distance and a half-block error. [-]
MIN_PAIRS = 3
#: The one block of the window whose d² is more than this squared times the mean of the
#: others' is an outlier of SSI (a mislabelled pole, 1-3 % off where SSI scatters by
#: 0.1-0.3 %): it leaves the means, and the blend's estimate of it stands. [-]
OUTLIER_SIGMA = 5.0
#: Fewest modes with a lone outlier at one block, all of one sign, that make a change of the
#: whole hull rather than SSI's outliers (two modes' chance outliers share a sign half the
#: time, three a quarter; the first forecast block of an ice voyage had two). [-]
HULL_MODES = 3


class GuardWindow:
    """The last *blocks* values of a quantity per mode (NaN: none), and their means."""

    def __init__(self, blocks: int, n_modes: int):
        self.values = np.full((blocks, n_modes), np.nan)

    def push(self, slot: int, value: np.ndarray) -> None:
        self.values[slot] = value

    def mean(self, exclude: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Mean and count per mode, without the slots *exclude* marks (n_modes,; -1: none)."""
        values = self.values
        if exclude is not None:
            values = values.copy()
            modes = np.flatnonzero(exclude >= 0)
            values[exclude[modes], modes] = np.nan
        count = np.isfinite(values).sum(axis=0)
        return np.nansum(values, axis=0) / np.maximum(count, 1), count

    def lone_outlier(self) -> np.ndarray:
        """Per mode, the slot of a value more than OUTLIER_SIGMA² times the mean of the
        others (one mislabelled pole among the window's blocks), else -1."""
        filled = np.where(np.isfinite(self.values), self.values, -np.inf)
        top = np.argmax(filled, axis=0)
        modes = np.arange(self.values.shape[1])
        largest = filled[top, modes]
        rest, count = self.mean(top)
        lone = (count >= MIN_PAIRS - 1) & np.isfinite(largest) & (largest > OUTLIER_SIGMA**2 * rest)
        return np.where(lone, top, -1)


def _hull_change(lone: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """The modes of *lone* (this block's lone outliers) that moved with the whole hull: all
    of them when there are at least :data:`HULL_MODES` and *distance* (SSI less the blend)
    has one sign across them, else none."""
    signs = np.sign(distance[lone])
    if signs.size >= HULL_MODES and np.all(signs == signs[0]) and signs[0] != 0:
        return lone
    return np.zeros_like(lone)


class SSIGuard:
    """The running test and estimate of the module docstring, all modes at once.

    Parameters
    ----------
    n_modes : int
        Modes of the forecast.
    blocks : int
        Window of the means (:data:`GUARD_BLOCKS`).
    """

    def __init__(self, n_modes: int, blocks: int = GUARD_BLOCKS):
        self.blocks = int(blocks)
        self._d2 = GuardWindow(self.blocks, n_modes)
        self._d2_prior = GuardWindow(self.blocks, n_modes)
        self._r = GuardWindow(R_BLOCKS, n_modes)
        # the last guarded estimate and model value of each mode (the next prediction)
        self._estimate = np.full(n_modes, np.nan)
        self._model = np.full(n_modes, np.nan)
        self._next = 0
        #: λ of the last block (1: the blend as it is). [-]
        self.weight = np.ones(n_modes)

    def step(
        self,
        estimate: np.ndarray,
        variance: np.ndarray,
        measured: np.ndarray,
        half_difference_hz: np.ndarray,
        model: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The guarded estimate and variance of one block.

        Parameters
        ----------
        estimate, variance : ndarray, shape (n_modes,)
            The blend's estimate [Hz] and its variance [Hz²].
        measured : ndarray, shape (n_modes,)
            SSI's estimate of the block (NaN: none). [Hz]
        half_difference_hz : ndarray, shape (n_modes,)
            f₁ - f₂ of the block's halves (NaN: not known). [Hz]
        model : ndarray, shape (n_modes,)
            The model's prediction of the block (NaN: none). [Hz]
        """
        prior = self._estimate + (model - self._model)
        r = (0.5 * half_difference_hz) ** 2
        slot = self._next % self.blocks
        r_slot = self._next % R_BLOCKS
        for window, value in (
            (self._d2, (estimate - measured) ** 2),
            (self._d2_prior, (prior - measured) ** 2),
        ):
            window.push(slot, np.where(np.isfinite(value) & np.isfinite(r), value, np.nan))
        self._r.push(r_slot, np.where(np.isfinite(measured), r, np.nan))
        r_mean, _ = self._r.mean()
        # a lone outlier of SSI (another column's pole) is the blend's to weigh: the
        # blend's estimate of its block stands
        lone = self._d2.lone_outlier()
        have = np.isfinite(measured)
        hull = _hull_change((lone == slot) & have & np.isfinite(estimate), measured - estimate)
        outlier = (lone == slot) & ~hull
        d2, pairs = self._d2.mean()
        d2_prior, prior_pairs = self._d2_prior.mean()
        fail = have & ~outlier & (pairs >= MIN_PAIRS) & (d2 > r_mean)
        from_prior = fail & np.isfinite(prior) & (prior_pairs >= MIN_PAIRS) & (d2_prior > r_mean)
        weight = np.ones_like(r_mean)
        guarded, guarded_variance = estimate.copy(), variance.copy()
        blend = fail & ~from_prior
        weight[blend] = r_mean[blend] / d2[blend]
        weight[from_prior] = r_mean[from_prior] / d2_prior[from_prior]
        # a change of the whole hull: the block's own distance, not the window's
        d2_now = np.where(hull, (estimate - measured) ** 2, np.inf)
        now = hull & (r_mean < weight * d2_now)
        weight[now] = r_mean[now] / d2_now[now]
        b = blend | now  # the blend drawn toward SSI
        guarded[b] = measured[b] + weight[b] * (estimate[b] - measured[b])
        guarded_variance[b] = (1 - weight[b]) ** 2 * r_mean[b] + weight[b] ** 2 * variance[b]
        p = from_prior & ~now  # the prediction drawn toward SSI
        guarded[p] = measured[p] + weight[p] * (prior[p] - measured[p])
        guarded_variance[p] = r_mean[p] * (1 - weight[p])
        self.weight = weight
        # the predictions go on from the guarded estimates; at a lone outlier from the
        # prediction itself (the blend's estimate there is the one the guard could not judge)
        keep = np.where(outlier & np.isfinite(prior), prior, guarded)
        self._estimate = np.where(np.isfinite(keep), keep, self._estimate)
        self._model = np.where(np.isfinite(keep), model, self._model)
        self._next += 1
        return guarded, guarded_variance
