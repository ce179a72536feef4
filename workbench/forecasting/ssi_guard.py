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

The test. Write the blend's error a = x̂ - x and SSI's e = z - x, so d = x̂ - z = a - e.
For a blend whose noise model is right, E[d²] = R - P ≤ R (P the blend's posterior
variance: the estimate lies within SSI's scatter of SSI). The guarded estimate is

.. math:: \\tilde x = z + λ (\\hat x - z), \\qquad λ = \\min(1, \\bar R / \\overline{d^2}),

with both means over the last :data:`GUARD_BLOCKS` blocks of the mode. λ is the
mean-squared-error optimum of both readings: where the blend is right
(E[e d] = -E[d²]), the MSE R - 2λE[d²] + λ²E[d²] is least at λ = 1; where its error does
not come from SSI's (a lagging or smoothing blend, E[a e] = 0), the MSE R - 2λR + λ²E[d²]
is least at λ = R / E[d²]. So the blend stands while its distance from SSI is within SSI's
own error, and is drawn toward SSI by as much as that distance exceeds it. The guarded
variance is (1 - λ)² R̄ + λ² P (the two errors taken as independent).

A mode moving inside the block adds its move to f₁ - f₂, so R̄ errs on the large side and
the guard on the side of leaving the blend alone. Blocks without both halves (LSCF, a half
that does not show the mode, tables from before the column) leave the means; with fewer
than :data:`MIN_PAIRS` blocks holding both d and R the blend stands.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GUARD_BLOCKS", "MIN_PAIRS", "SSIGuard"]

#: Blocks over which the distance from SSI and SSI's own error are averaged (40 minutes of
#: 5-minute steps: two 20-minute blocks that share no data). [-]
GUARD_BLOCKS = 8
#: Fewest blocks of the window holding both a distance and a half-block error. [-]
MIN_PAIRS = 3


class SSIGuard:
    """The running test of the module docstring, one per forecast, all modes at once.

    Parameters
    ----------
    n_modes : int
        Modes of the forecast.
    blocks : int
        Window of the means (:data:`GUARD_BLOCKS`).
    """

    def __init__(self, n_modes: int, blocks: int = GUARD_BLOCKS):
        self.blocks = int(blocks)
        self._d2 = np.full((self.blocks, n_modes), np.nan)
        self._r = np.full((self.blocks, n_modes), np.nan)
        self._next = 0
        #: λ of the last block (1: the blend as it is). [-]
        self.weight = np.ones(n_modes)

    def step(
        self,
        estimate: np.ndarray,
        variance: np.ndarray,
        measured: np.ndarray,
        half_difference_hz: np.ndarray,
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
        """
        d2 = (estimate - measured) ** 2
        r = (0.5 * half_difference_hz) ** 2
        both = np.isfinite(d2) & np.isfinite(r)
        slot = self._next % self.blocks
        self._d2[slot] = np.where(both, d2, np.nan)
        self._r[slot] = np.where(both, r, np.nan)
        self._next += 1
        pairs = np.isfinite(self._d2).sum(axis=0)
        count = np.maximum(pairs, 1)
        r_mean = np.nansum(self._r, axis=0) / count
        d2_mean = np.nansum(self._d2, axis=0) / count
        weight = np.ones_like(r_mean)
        pull = (pairs >= MIN_PAIRS) & (d2_mean > r_mean)
        weight[pull] = r_mean[pull] / d2_mean[pull]
        weight = np.where(np.isfinite(measured) & np.isfinite(weight), weight, 1.0)
        self.weight = weight
        guarded = np.where(weight < 1.0, measured + weight * (estimate - measured), estimate)
        guarded_variance = np.where(
            weight < 1.0, (1.0 - weight) ** 2 * r_mean + weight**2 * variance, variance
        )
        return guarded, guarded_variance
