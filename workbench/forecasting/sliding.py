"""Sliding-window predictive model of modal frequencies with Kalman blending.

For every tracked mode a stepwise regression of the frequency on the block predictors is
trained (model ``"window"``: on the last ``train_blocks`` blocks; model ``"memory"``: on the
whole history with forgetting, :mod:`workbench.forecasting.memory`) and predicts ahead with
95 % prediction bounds;
a Kalman filter per mode (:mod:`workbench.forecasting.kalman`) blends the prediction with the
SSI estimate of each block.

* scheme ``"single_window"`` (method 1): one training window, one long forward prediction
  of ``horizon`` blocks;
* scheme ``"rolling"`` (method 2): predict ``horizon`` blocks, Kalman-filter them, slide the
  window forward by ``horizon`` blocks (model ``"window"``: taking the Kalman estimates as the
  new training targets), refit, repeat to the end of the data.

Measurement options: A, the block's tracked pole (modal table); B, a pole of the block's
stabilisation diagram chosen automatically: inside a gate around the a-priori estimate, with
a mode shape matching the mode's reference shape (MAC); a mode seen only outside the gate
is re-acquired there (window model) or measured there with a Huber weight, the row's
``warning`` saying so (memory model) (an automatic modal parameter selection).

Every setting is a field of :class:`~workbench.forecasting.options.ForecastOptions`.

Notes
-----
*No look-ahead*: each window's predictors are z-scored with that window's mean and
standard deviation only, and a window model sees only its own blocks.

*Kalman blending* per mode (see :mod:`workbench.forecasting.kalman`), model ``"window"``: state =
frequency;
a-priori x⁻_k = m_k + φ (x⁺_{k-1} - m_{k-1}) with m the current window model's
prediction (F = φ, B u = m_k - φ m_{k-1}); P⁻ = φ² P⁺ + Q; update with the SSI estimate
z_k (H = 1) in Joseph form. R is the scatter of the block measurements about the window
model: the variance of its white part, estimated robustly from successive differences,
σ² = (1.4826 MAD(Δr))² / 2 (differencing removes the slowly varying model error, the
MAD ignores the odd wrong pole; plain residual variance for fewer than 6 values); Q
from *trust* (:class:`~workbench.forecasting.options.ForecastOptions`). P starts at the
steady-state prior of the first window's Q and R. The filter runs through the first
training window (phase "train", with the in-sample model) and every forecast block.

*Method 2 targets*: the Kalman estimates of the blocks that had a measurement;
predict-only blocks are not training targets (they hold no new information, and
re-training on them would feed the model its own extrapolation), so a long stretch
without SSI estimates leads to the last good model rather than a self-fed drift.

*Fallbacks* (never an exception for data problems): a model prediction outside
half to twice the mode's level (median of its first training targets) is replaced by
the constant model, and a Kalman estimate outside that band restarts the mode's
filter at the model (track lost); a window with fewer than
*min_train_blocks* targets or a failing fit reuses the last good model, else a
constant model (window mean ± t s sqrt(1 + 1/n)); constant or mostly-NaN predictors are
dropped from the window's candidates; a block whose needed predictor is NaN is
predicted by the constant model of the window; a block without a measurement is a
predict-only step.

*Option B pole selection.* Reference shape φ_ref of mode j at block k: the latest
shape of the mode in the tracked modal table at or before block k (no look-ahead) that
is confirmed by the mode's tracked shape before it (MAC >= *mac_min*), so one
mis-tracked block does not become the reference; before the first confirmation, the
mode's first tracked shape. A pole p is admissible when

.. math:: \\mathrm{MAC}(φ_p, φ_{ref}) = \\frac{|φ_{ref}^H φ_p|^2}
          {(φ_{ref}^H φ_{ref})(φ_p^H φ_p)} \\ge \\mathrm{MAC}_{min},

computed on the channels both shapes have (NaN components, e.g. a dead sensor, are
left out; fewer than 3 shared channels: not admissible). Inside the gate
|f_p - x⁻| <= g, g = gate_sigma sqrt(P⁻ + R), stable admissible poles are preferred
to unstable ones, and among them the pole with the lowest score

.. math:: s_p = \\frac{|f_p - \\tilde f|}{g} + \\frac{1 - \\mathrm{MAC}_p}{1 - \\mathrm{MAC}_{min}}

is the measurement, with f̃ the median frequency of those poles (the centre of the
mode's column in the stabilisation diagram). Both terms lie in about [0, 1]: distance
from the column's centre and shape misfit count alike. Centring on the column rather
than on x⁻ keeps the measurement independent of the prior, so the Kalman update
still averages two estimates (nearest-to-x⁻ selection pulls z towards x⁻). The pole's
order, damping ratio and MAC are recorded.

*Re-acquisition of a lost track* (model ``"window"``). When the model cannot follow a regime change, the
prior and its gate stay on a stale frequency while the mode moves away; the gate then
holds no admissible pole (at most noise poles of other shapes), and the nearest-pole
rule would lock onto them. Rule: a block in which the gate holds no admissible pole but
the band |f_p - c| <= *reacquire_band* c around c = the last chosen pole's frequency or
c = x⁻ holds one counts as a miss (a block without any admissible pole in the band is
predict-only and neither counts nor resets; a pole chosen inside the gate resets the
count). At *reacquire_blocks* consecutive misses the admissible pole of the band with
the highest MAC (stable preferred) is the measurement, and the prior variance is
inflated to P⁻ ← max(P⁻, y²), y = z - x⁻, so that the gain is about 1 and the estimate
jumps to the re-acquired pole (the prior was wrong, not the measurement); P returns to
its steady state over the next blocks. Each re-acquisition is a row warning and is
counted in a :class:`ForecastWarning`.
"""

from __future__ import annotations

from dataclasses import replace

import pandas as pd

from ..errors import PredictorError
from .assembly import log_coverage_of, with_log_coverage
from .measurement import measurable_poles
from .memory.forecast import memory_forecast
from .options import ForecastOptions
from .results import ForecastResult, combined
from .window.forecast import window_forecast

__all__ = ["sliding_forecast"]


def sliding_forecast(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    options: ForecastOptions | None = None,
    *,
    poles: pd.DataFrame | None = None,
    modes=None,
    start_block: int | None = None,
    end_block: int | None = None,
    cases=None,
) -> ForecastResult:
    """Sliding stepwise-regression forecast of each mode's frequency, Kalman-blended with SSI.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract): block, mode, frequency_hz. Training targets
        of the first window, and the measurements of option A.
    predictors : DataFrame
        Block predictors (PREDICTORS contract; extra numeric columns allowed): block,
        block_start and predictor columns. Its blocks are the forecast's block grid
        (consecutive rows are consecutive Kalman steps).
    options : ForecastOptions, optional
        Every setting (model, scheme, measurement options, windows, gates); default
        ``ForecastOptions()``, the forecast stage's and the command line's. Each option of
        ``options.options`` is run, their tables one after the other.
    poles : DataFrame, optional
        Stabilisation diagrams (POLES contract: block, model_order, frequency_hz,
        damping_ratio, stable, and mode shapes ``shape_re_<ch>``/``shape_im_<ch>``);
        required for option B. Poles marked as a shaft or blade-pass harmonic (column
        ``harmonic``) are left out, but for option B's in the column of a tracked pole of
        *modal* in their block (:func:`~workbench.forecasting.measurement.measurable_poles`).
    modes : sequence of int, optional
        Modes to forecast; default every mode of *modal*.
    start_block : int, optional
        First block of the first training window; default the first block of *predictors*.
    end_block : int, optional
        Last block forecast (rolling scheme); default the last block of *predictors*.
    cases : None, "derive", CaseRule, column name, path or DataFrame, optional
        Operating cases (:func:`workbench.stats.cases.case_labels`). Each window then
        trains on its blocks of the case the first forecast block is in, so the forecast
        uses the model of the current case (the whole window when the case has fewer than
        *min_train_blocks* of them; :func:`workbench.stats.case_training_mask`). Model
        ``"memory"``: each refit uses the history's blocks of that case (all of the history
        when it holds fewer than *min_train_blocks*), and the terms are selected again when
        the case changes.

    Returns
    -------
    ForecastResult

    Warns
    -----
    ForecastWarning
        Once per kind of fallback, with counts (also in the ``warning`` column and
        :attr:`ForecastResult.warnings`).

    Notes
    -----
    The method: this module's docstring.
    """
    options = ForecastOptions() if options is None else options
    if not isinstance(options, ForecastOptions):
        raise TypeError(f"options must be a ForecastOptions, got {type(options).__name__}")
    missing = [c for c in ("block", "mode", "frequency_hz") if c not in modal.columns]
    if missing:
        raise ValueError(f"modal lacks column(s) {missing}")
    missing = [c for c in ("block", "block_start") if c not in predictors.columns]
    if missing:
        raise PredictorError(f"the predictor table has no column {', '.join(map(repr, missing))}")
    if "B" in options.options and poles is None:
        raise ValueError("option='B' needs poles (the stabilisation diagrams)")
    run = memory_forecast if options.model == "memory" else window_forecast
    results = []
    for option in options.options:  # a loop, not a comprehension: warnings point at the caller
        one = replace(options, options=(option,))
        results.append(
            run(
                modal,
                predictors,
                one,
                poles=None if poles is None else measurable_poles(poles, modal, option),
                modes=modes,
                start_block=start_block,
                end_block=end_block,
                cases=cases,
            )
        )
    result = combined(results, options)
    return replace(result, table=with_log_coverage(result.table, log_coverage_of(predictors)))
