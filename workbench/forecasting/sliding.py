"""Sliding-window predictive model of modal frequencies with Kalman blending.

For every tracked mode a stepwise regression of the frequency on the block predictors is
trained on the last ``train_blocks`` blocks and predicts ahead with 95 % prediction bounds;
a Kalman filter per mode (:mod:`workbench.forecasting.kalman`) blends the prediction with the
SSI estimate of each block.

* method 1: one training window, one long forward prediction of ``horizon`` blocks;
* method 2: predict ``horizon`` blocks, Kalman-filter them, slide the window forward by
  ``horizon`` blocks taking the Kalman estimates as the new training targets, refit, repeat
  to the end of the data.

Measurement options: A, the block's tracked pole (modal table); B, a pole of the block's
stabilisation diagram chosen automatically: inside a gate around the a-priori estimate, with
a mode shape matching the mode's reference shape (MAC); a mode seen only outside the gate
is re-acquired there (window model) or measured there with a Huber weight, the row's
``warning`` saying so (memory model) (an automatic modal parameter selection).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Literal

import pandas as pd

from .._deprecation import DEPRECATED, renamed_argument

# Fitted window models, option B's pole selection and the output assembly have their own
# modules (fitted_model, pole_selection, assembly); both the window and the memory path use
# them from there.
from .kalman import relaxation_factor
from .memory.forecast import memory_forecast
from .options import (
    MeasurementOptions,
    ModelOptions,
    NoiseOptions,
    check_train_blocks,
    check_trust,
    default_min_train_blocks,
    method_label,
    option_label,
)
from .results import ForecastResult
from .window.forecast import window_forecast

__all__ = ["sliding_forecast"]

#: Default forecast horizon per method. [blocks]
DEFAULT_HORIZON = {1: 34, 2: 4}


# --------------------------------------------------------------------------- main function
def sliding_forecast(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    *,
    poles: pd.DataFrame | None = None,
    option: Literal["A", "B", "tracked_pole", "pole_cluster"] = "A",
    scheme: Literal[1, 2, "single_window", "rolling"] = 1,
    train_blocks: int = 20,
    horizon: int | None = None,
    start_block: int | None = None,
    end_block: int | None = None,
    trust: float | None | Literal["auto"] = "auto",
    correction_time_blocks: float = 36.0,
    gate_sigma: float = 3.0,
    mac_min: float = 0.9,
    reacquire_blocks: int | None = None,
    reacquire_band: float = 0.05,
    predictor_columns: Sequence[str] | None = None,
    stepwise_options: Mapping[str, Any] | None = None,
    min_train_blocks: int | None = None,
    gap_warning_blocks: int = 12,
    modes: Sequence[int] | None = None,
    alpha: float = 0.05,
    extrapolation_limit: float = 4.0,
    cases=None,
    model: Literal["memory", "window"] = "window",
    model_options: ModelOptions | None = None,
    noise_options: NoiseOptions | None = None,
    method=DEPRECATED,
    shape_mac_min=DEPRECATED,
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
    poles : DataFrame, optional
        Stabilisation diagrams (POLES contract: block, model_order, frequency_hz,
        damping_ratio, stable, and mode shapes ``shape_re_<ch>``/``shape_im_<ch>``);
        required for option B.
    option : {"A", "B", "tracked_pole", "pole_cluster"}
        Measurement: A (``"tracked_pole"``), the tracked pole of the block; B, an automatic pole selection from
        the block's stabilisation diagram (B, ``"pole_cluster"``): among the poles inside the gate
        ``gate_sigma * sqrt(P⁻ + R)`` around the a-priori estimate whose shape matches the
        mode's reference shape (MAC >= *mac_min*), the best by a score; a mode seen
        only outside the gate for *reacquire_blocks* blocks is re-acquired (Notes).
        Without shape columns in *poles* and *modal*: the nearest pole inside the gate,
        stable poles preferred, no MAC check (with a warning); with ``model="memory"`` a
        pick nearer to another mode's tracked pole of the block (else its a-priori
        estimate) than to the mode's own is refused and the mode's tracked pole measured
        (:func:`~workbench.forecasting.measurement.nearer_to_another_mode`).
    scheme : {1, 2, "single_window", "rolling"}
        How the forecast slides (the reference work's methods 1 and 2).
        ``"single_window"`` (1): one training window, one forward prediction of *horizon*
        blocks. ``"rolling"`` (2): predict
        *horizon* blocks, Kalman-filter them, slide the window by *horizon* blocks with the
        Kalman estimates as new training targets, refit, repeat to *end_block*.
    train_blocks : int
        Training window length N. [blocks]
    horizon : int, optional
        Blocks predicted per window; default 34 (method 1) or 4 (method 2). [blocks]
    start_block : int, optional
        First block of the first training window; default the first block of *predictors*.
    end_block : int, optional
        Last block forecast (method 2); default the last block of *predictors*.
    trust : float or None
        Steady-state Kalman gain, the weight on the SSI estimate (0.65: 65 % SSI, 35 %
        model). Q follows from R (:func:`~workbench.forecasting.kalman.process_variance_for_gain`).
        ``None``: data-driven, Q = s_m² (1 - φ²) with s_m² the model's mean-prediction
        variance over the window's forecast blocks, i.e. the correction's stationary
        variance equals the model's own uncertainty.
    correction_time_blocks : float
        Time constant τ of the Kalman correction, φ = exp(-1/τ); ``inf`` gives the random
        walk x⁻_k = x⁺_{k-1} + (m_k - m_{k-1}). Default 36 blocks (3 h of 5-min steps).
        [blocks]
    gate_sigma : float
        Option B gate in innovation standard deviations.
    mac_min : float
        Option B: a pole is admissible for a mode only when the MAC of its shape with the
        mode's reference shape is at least this, compared on the channels both shapes
        have. Default 0.9: on the 12-h demo voyage the poles of a mode's column in the
        stabilisation diagram reach MAC > 0.99 with its reference shape, the other modes
        stay below 0.25, and of the spurious poles near the stale 7.10-Hz prediction of the
        6.9-Hz mode (blocks 25-56) 83 of 84 stay below 0.9 (largest 0.94). [-]
    reacquire_blocks : int
        Option B: consecutive blocks (k) with no admissible pole inside the gate but one
        near the mode (within *reacquire_band*) after which the track is re-acquired
        outside the gate. Default 1: the MAC check already vouches for the pole, and on
        the demo voyage k = 2 left about 5 % of the blocks predict-only, exactly those in
        which the ship changed speed (cumulative Kalman error over all blocks 8.6 Hz
        against 7.7 Hz with k = 1). With ``model="memory"`` (default 1) the column seen
        outside the gate is measured there, Huber-weighted, without resetting the prior
        (:class:`~workbench.forecasting.measurement.ClusterChooser`). [blocks]
    reacquire_band : float
        Option B: relative half-width of the band searched for the mode outside the gate,
        around the last chosen pole's frequency and around the a-priori estimate
        (0.05: ±5 %). [-]
    predictor_columns : sequence of str, optional
        Candidate predictors; default every numeric column of *predictors* except
        ``block``.
    stepwise_options : mapping, optional
        Keyword arguments for :func:`workbench.stats.stepwise` (``upper``, ``p_enter``...).
    min_train_blocks : int, optional
        Fewest valid targets for a stepwise fit (else fallback); default
        ``max(5, train_blocks // 2)``. A predictor with fewer valid values in the window is
        left out of that window's candidates.
    gap_warning_blocks : int
        Consecutive blocks without a measurement after which rows carry a warning.
    modes : sequence of int, optional
        Modes to forecast; default every mode of *modal*.
    alpha : float
        1 - confidence of the prediction interval (0.05: 95 %).
    extrapolation_limit : float
        Normalised predictors are clipped to ±this many window standard deviations before
        prediction, so a long forecast cannot extrapolate a 20-block fit without bound
        (e.g. a time trend); clipped blocks carry a warning.
    model : {"window", "memory"}
        ``"window"`` (this function's default, so that its reference results stay where
        they were): the reference configuration, a stepwise model fitted on the last
        *train_blocks* blocks, Kalman trust *trust*. ``"memory"`` (the default of the
        forecast stage, the command line and the demo): stepwise terms with
        coefficients over the whole history with exponential forgetting, noise levels from
        the data, an AR(1) measurement-error state (:func:`workbench.forecasting.memory.forecast.
        memory_forecast`; *model_options*, *noise_options*), and a measurement equation for
        SSI's excitation weighting (:mod:`workbench.forecasting.excitation`). With method 2
        ``"memory"`` beats raw SSI by 30 % or more (median of 3 seeds, never worse in any)
        on every block-level regime of ``benchmarks/bench_forecast_accuracy.py`` and by
        15 % or more on the demo voyage at 3 h and 12 h (option B without pole shapes: 13 %
        at 12 h; ``benchmarks/results/forecast_accuracy_after.txt``); with method 1 (one
        20-block window) it is worse than raw SSI on the 12-h demo.
    cases : None, "derive", CaseRule, column name, path or DataFrame, optional
        Operating cases (:func:`workbench.stats.cases.case_labels`). Each window then
        trains on its blocks of the case the first forecast block is in, so the forecast
        uses the model of the current case (the whole window when the case has fewer than
        *min_train_blocks* of them; :func:`workbench.stats.case_training_mask`).
        ``model="memory"``: each refit uses the history's blocks of that case (all of the
        history when it holds fewer than *min_train_blocks*), and the terms are selected
        again when the case changes.
    method, shape_mac_min
        Deprecated names of *scheme* and *mac_min* (a DeprecationWarning).

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
    *No look-ahead*: each window's predictors are z-scored with that window's mean and
    standard deviation only, and a window model sees only its own blocks.

    *Kalman blending* per mode (see :mod:`workbench.forecasting.kalman`): state = frequency;
    a-priori x⁻_k = m_k + φ (x⁺_{k-1} - m_{k-1}) with m the current window model's
    prediction (F = φ, B u = m_k - φ m_{k-1}); P⁻ = φ² P⁺ + Q; update with the SSI estimate
    z_k (H = 1) in Joseph form. R is the scatter of the block measurements about the window
    model: the variance of its white part, estimated robustly from successive differences,
    σ² = (1.4826 MAD(Δr))² / 2 (differencing removes the slowly varying model error, the
    MAD ignores the odd wrong pole; plain residual variance for fewer than 6 values); Q
    from *trust* as above. P starts at the
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

    *Re-acquisition of a lost track.* When the model cannot follow a regime change, the
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
    scheme = renamed_argument("sliding_forecast()", "method", method, "scheme", scheme, 1)
    mac_min = renamed_argument(
        "sliding_forecast()", "shape_mac_min", shape_mac_min, "mac_min", mac_min, 0.9
    )
    option = option_label(option)
    method = method_label(scheme)
    if model not in ("memory", "window"):
        raise ValueError(f"model={model!r} must be 'memory' or 'window'")
    for name, frame, needed in (
        ("modal", modal, ("block", "mode", "frequency_hz")),
        ("predictors", predictors, ("block", "block_start")),
    ):
        missing = [c for c in needed if c not in frame.columns]
        if missing:
            raise ValueError(f"{name} lacks column(s) {missing}")
    if option == "B" and poles is None:
        raise ValueError("option='B' needs poles (the stabilisation diagrams)")
    horizon = DEFAULT_HORIZON[method] if horizon is None else int(horizon)
    if horizon < 1:
        raise ValueError(f"horizon={horizon} must be >= 1")
    check_trust(trust, model)
    if model == "memory":
        options_m = model_options or ModelOptions(
            train_blocks=train_blocks,
            min_train_blocks=min_train_blocks,
            predictor_columns=predictor_columns,
            stepwise_options=stepwise_options,
            extrapolation_limit=extrapolation_limit,
            alpha=alpha,
        )
        return memory_forecast(
            modal,
            predictors,
            poles=poles,
            method=method,
            horizon=horizon,
            start_block=start_block,
            end_block=end_block,
            modes=modes,
            model=options_m,
            noise=noise_options or NoiseOptions(),
            measurement=MeasurementOptions(
                option=option,
                gate_sigma=gate_sigma,
                mac_min=mac_min,
                reacquire_blocks=1 if reacquire_blocks is None else reacquire_blocks,
                reacquire_band=reacquire_band,
            ),
            gap_warning_blocks=gap_warning_blocks,
            cases=cases,
        )
    if trust == "auto":
        trust = 0.65
    if reacquire_blocks is None:
        reacquire_blocks = 1
    train_blocks = int(train_blocks)
    if train_blocks < 2:
        raise ValueError(f"train_blocks={train_blocks} must be >= 2")
    if trust is not None and not 0.0 < float(trust) < 1.0:
        raise ValueError(f"trust={trust!r} must be in (0, 1) or None")
    phi = relaxation_factor(correction_time_blocks)
    if trust is None and phi == 1.0:
        raise ValueError("trust=None needs a finite correction_time_blocks")
    if not gate_sigma > 0:
        raise ValueError(f"gate_sigma={gate_sigma!r} must be > 0")
    if not 0.0 <= mac_min < 1.0:
        raise ValueError(f"mac_min={mac_min!r} must be in [0, 1)")
    if int(reacquire_blocks) != reacquire_blocks or reacquire_blocks < 1:
        raise ValueError(f"reacquire_blocks={reacquire_blocks!r} must be an integer >= 1")
    reacquire_blocks = int(reacquire_blocks)
    if not reacquire_band > 0:
        raise ValueError(f"reacquire_band={reacquire_band!r} must be > 0")
    if not extrapolation_limit > 0:
        raise ValueError(f"extrapolation_limit={extrapolation_limit!r} must be > 0")
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha={alpha!r} must be in (0, 1)")
    check_train_blocks(train_blocks, min_train_blocks)
    min_train = (
        default_min_train_blocks(train_blocks)
        if min_train_blocks is None
        else int(min_train_blocks)
    )
    options = dict(stepwise_options or {})
    # a window's model uses the rows complete in every candidate predictor (the rule the
    # forecast was validated with); stepwise_options={"missing": "candidate"} for MATLAB's
    options.setdefault("missing", "complete")
    return window_forecast(
        modal,
        predictors,
        poles=poles,
        option=option,
        method=method,
        train_blocks=train_blocks,
        horizon=horizon,
        start_block=start_block,
        end_block=end_block,
        trust=trust,
        phi=phi,
        gate_sigma=gate_sigma,
        shape_mac_min=mac_min,
        reacquire_blocks=reacquire_blocks,
        reacquire_band=reacquire_band,
        predictor_columns=predictor_columns,
        stepwise_options=options,
        min_train=min_train,
        gap_warning_blocks=gap_warning_blocks,
        modes=modes,
        alpha=alpha,
        extrapolation_limit=extrapolation_limit,
        cases=cases,
    )


#: Former keyword names of :func:`sliding_forecast` (README, "Glossary").
sliding_forecast.__deprecated_parameters__ = {"method": "scheme", "shape_mac_min": "mac_min"}
