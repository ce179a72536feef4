"""Sliding-window predictive model of modal frequencies with Kalman blending.

For every tracked mode a stepwise regression of the frequency on the block predictors is
trained on the last ``train_blocks`` blocks and predicts ahead with 95 % prediction bounds;
a Kalman filter per mode (:mod:`workbench.forecast.kalman`) blends the prediction with the
SSI estimate of each block.

* method 1: one training window, one long forward prediction of ``horizon`` blocks;
* method 2: predict ``horizon`` blocks, Kalman-filter them, slide the window forward by
  ``horizon`` blocks taking the Kalman estimates as the new training targets, refit, repeat
  to the end of the data.

Measurement options: A, the block's tracked pole (modal table); B, a pole of the block's
stabilisation diagram chosen automatically: inside a gate around the a-priori estimate, with
a mode shape matching the mode's reference shape (MAC), and re-acquired outside the gate
when the model has lost the mode (an automatic modal parameter selection).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd

from .._deprecation import DEPRECATED, renamed_argument
from ..stats.distributions import t_quantile
from .kalman import relaxation_factor
from .options import MeasurementOptions, ModelOptions, NoiseOptions, method_label, option_label

__all__ = ["ForecastResult", "ForecastWarning", "WindowModel", "sliding_forecast"]

#: Default forecast horizon per method. [blocks]
DEFAULT_HORIZON = {1: 34, 2: 4}
#: A mode's frequency is plausible within a factor of this of its first window's median.
_PLAUSIBLE_FACTOR = 2.0
#: Fewest successive differences for the robust scatter estimate of R.
_MIN_DIFFERENCES = 5
#: Relative floor on the measurement standard deviation, sqrt(R) >= this x frequency. [-]
_MIN_RELATIVE_STD = 1e-5
#: Relative measurement standard deviation assumed when a window has too little data to
#: estimate the scatter and no earlier estimate exists. [-]
_DEFAULT_RELATIVE_STD = 5e-3


class ForecastWarning(UserWarning):
    """A forecast went on with a fallback (constant or last good model, predict-only steps)."""


@dataclass(frozen=True)
class WindowModel:
    """The model used for one mode over one training window.

    Parameters
    ----------
    mode : int
        Mode label.
    window_start_block, window_end_block : int
        First and last block of the training window.
    kind : {"stepwise", "constant", "last_good"}
        Stepwise fit of this window; constant model (mean of the window's targets);
        the last good stepwise model of an earlier window, reused.
    terms : tuple of str
        Model terms (empty for the constant model).
    coefficients : dict
        Term -> estimate on normalised predictors (intercept included as the fit names it).
    n_train : int
        Training targets available in the window.
    rmse_hz : float
        Residual standard deviation of the fit (constant model: of the targets). [Hz]
    measurement_variance : float
        R, scatter of the measurements about the model in the window. [Hz²]
    process_variance : float
        Q of the Kalman filter for the blocks this window predicts. [Hz²]
    normalisation : dict
        Predictor -> (mean, standard deviation) of the window, used to z-score.
    warning : str
        Why a fallback was used ("" when none).
    """

    mode: int
    window_start_block: int
    window_end_block: int
    kind: Literal["stepwise", "constant", "last_good"]
    terms: tuple[str, ...]
    coefficients: Mapping[str, float]
    n_train: int
    rmse_hz: float
    measurement_variance: float
    process_variance: float
    normalisation: Mapping[str, tuple[float, float]]
    warning: str = ""


@dataclass(frozen=True)
class ForecastResult:
    """Output of :func:`sliding_forecast`.

    Parameters
    ----------
    table : DataFrame
        FORECAST contract table plus ``warning`` (str, "" when none) and, for option B,
        ``selected_model_order`` (Int64), ``selected_damping_ratio`` and ``selected_mac``
        (MAC of the chosen pole's shape with the mode's reference shape; NaN when no pole
        was chosen or shapes were not used).
    warnings : tuple of str
        Distinct warnings with their counts, also issued as :class:`ForecastWarning`.
    models : tuple of WindowModel
        The model of every mode and training window, in order.
    """

    table: pd.DataFrame
    warnings: tuple[str, ...] = ()
    models: tuple[WindowModel, ...] = field(default=())


# --------------------------------------------------------------------------- fitted models
@dataclass
class _Model:
    """A fitted window model ready to predict (internal)."""

    kind: str
    fit: Any  # stepwise fit or None (constant)
    columns: tuple[str, ...]  # predictor columns the fit saw
    mean: np.ndarray  # normalisation of those columns
    scale: np.ndarray
    level: float = math.nan  # constant model: mean of targets
    spread: float = math.nan  # constant model: std of targets
    n_train: int = 0
    n_params: int = 1
    rmse: float = math.nan
    used: frozenset = frozenset()  # predictor columns named in the model's terms

    def terms(self) -> tuple[str, ...]:
        return tuple(getattr(self.fit, "terms", ())) if self.fit is not None else ()


def _constant_prediction(
    level: float, spread: float, n: int, n_rows: int, alpha: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Constant model ȳ ± t s sqrt(1 + 1/n): mean, lower, upper, mean-prediction variance."""
    mean = np.full(n_rows, level)
    t = t_quantile(1 - alpha / 2, max(n - 1, 1))
    half = t * spread * math.sqrt(1.0 + 1.0 / max(n, 1))
    return mean, mean - half, mean + half, np.full(n_rows, spread**2 / max(n, 1))


def _z_scores(rows: np.ndarray, mean: np.ndarray, scale: np.ndarray, limit: float) -> np.ndarray:
    """z = (x - mean) / scale, clipped to ±limit (NaN stays NaN)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.clip((rows - mean) / scale, -limit, limit)


def _predict(
    model: _Model,
    rows: np.ndarray,
    alpha: float,
    limit: float,
    frame: pd.DataFrame | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean, lower, upper (prediction interval) and mean-prediction variance on raw *rows*.

    *frame*, when given, holds *rows* already z-scored (and clipped to ±*limit*) with the
    model's normalisation. Rows the model cannot predict (a predictor it uses is NaN) are
    NaN.
    """
    n_rows = rows.shape[0]
    if model.fit is None:
        return _constant_prediction(model.level, model.spread, model.n_train, n_rows, alpha)
    if frame is None:
        z = _z_scores(rows, model.mean, model.scale, limit)
        frame = pd.DataFrame(z, columns=list(model.columns))
    try:
        out = model.fit.predict(frame, interval="prediction", alpha=alpha)
        mean = np.array(out["mean"], dtype=float)
        lower = np.array(out["lower"], dtype=float)
        upper = np.array(out["upper"], dtype=float)
        mean_variance = np.array(out["mean_se"], dtype=float) ** 2  # se² of the mean
    except Exception:  # a fit that cannot predict these rows: fall back per row
        nan = np.full(n_rows, np.nan)
        return nan, nan.copy(), nan.copy(), nan.copy()
    return mean, lower, upper, mean_variance


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
        stable poles preferred, no MAC check (with a warning).
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
        model). Q follows from R (:func:`~workbench.forecast.kalman.process_variance_for_gain`).
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
        against 7.7 Hz with k = 1). [blocks]
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
        the data, an AR(1) measurement-error state (:func:`workbench.forecast.blend.
        memory_forecast`; *model_options*, *noise_options*), and a measurement equation for
        SSI's excitation weighting (:mod:`workbench.forecast.excitation`). With method 2
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

    *Kalman blending* per mode (see :mod:`workbench.forecast.kalman`): state = frequency;
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
    if model == "memory":
        if trust not in ("auto", None):
            raise ValueError(
                f"trust={trust!r} applies to model='window' (the reference configuration); "
                "model='memory' estimates its noise levels from the data"
            )
        if option == "B" and poles is None:
            raise ValueError("option='B' needs poles (the stabilisation diagrams)")
        from .blend import memory_forecast

        horizon = DEFAULT_HORIZON[method] if horizon is None else int(horizon)
        if horizon < 1:
            raise ValueError(f"horizon={horizon} must be >= 1")
        options_m = model_options or ModelOptions(
            train_blocks=train_blocks,
            min_train_blocks=min_train_blocks,
            predictor_columns=predictor_columns,
            stepwise_options=stepwise_options,
            extrapolation_limit=extrapolation_limit,
            alpha=alpha,
        )
        for name, frame, needed in (
            ("modal", modal, ("block", "mode", "frequency_hz")),
            ("predictors", predictors, ("block", "block_start")),
        ):
            missing = [c for c in needed if c not in frame.columns]
            if missing:
                raise ValueError(f"{name} lacks column(s) {missing}")
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
                reacquire_blocks=2 if reacquire_blocks is None else reacquire_blocks,
                reacquire_band=reacquire_band,
            ),
            gap_warning_blocks=gap_warning_blocks,
            cases=cases,
        )
    if trust == "auto":
        trust = 0.65
    if reacquire_blocks is None:
        reacquire_blocks = 1
    if option == "B" and poles is None:
        raise ValueError("option='B' needs poles (the stabilisation diagrams)")
    train_blocks = int(train_blocks)
    if train_blocks < 2:
        raise ValueError(f"train_blocks={train_blocks} must be >= 2")
    horizon = DEFAULT_HORIZON[method] if horizon is None else int(horizon)
    if horizon < 1:
        raise ValueError(f"horizon={horizon} must be >= 1")
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
    min_train = max(5, train_blocks // 2) if min_train_blocks is None else int(min_train_blocks)
    if not 2 <= min_train <= train_blocks:
        raise ValueError(f"min_train_blocks={min_train} must be in [2, train_blocks]")
    for name, frame, needed in (
        ("modal", modal, ("block", "mode", "frequency_hz")),
        ("predictors", predictors, ("block", "block_start")),
    ):
        missing = [c for c in needed if c not in frame.columns]
        if missing:
            raise ValueError(f"{name} lacks column(s) {missing}")
    options = dict(stepwise_options or {})
    # a window's model uses the rows complete in every candidate predictor (the rule the
    # forecast was validated with); stepwise_options={"missing": "candidate"} for MATLAB's
    options.setdefault("missing", "complete")
    from .window import window_forecast

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


def _plausible(frequency: np.ndarray, reference: np.ndarray | float) -> np.ndarray:
    """f > 0 and, where a reference level is known, ref / c < f < c ref (c = 2)."""
    f = np.asarray(frequency, dtype=float)
    ref = np.asarray(reference, dtype=float)
    with np.errstate(invalid="ignore"):
        band = (f > ref / _PLAUSIBLE_FACTOR) & (f < ref * _PLAUSIBLE_FACTOR)
        return (f > 0) & np.where(np.isfinite(ref), band, True)


def _white_scatter_variance(residuals: np.ndarray) -> float:
    """Variance of the white part of *residuals*, robustly, from successive differences.

    Notes
    -----
    For r_k = e_k + v_k with e slowly varying (model error) and v white (SSI scatter),
    Δr_k ≈ Δv_k has variance 2 σ_v². With the MAD as a robust standard deviation,
    σ_v² = (1.4826 MAD(Δr))² / 2; differencing removes the model error, the MAD ignores
    the odd mis-selected pole. Falls back to the mean square when the MAD is zero.
    """
    differences = np.diff(residuals)
    mad = float(np.median(np.abs(differences - np.median(differences))))
    if mad > 0:
        return (1.4826 * mad) ** 2 / 2.0
    return float(np.mean(residuals**2))


def _used_columns(fit, names: Sequence[str]) -> frozenset:
    """Predictor columns named in the fit's terms (e.g. "speed_kn:water_temp_c")."""
    tokens: set[str] = set()
    for term in getattr(fit, "terms", ()):
        tokens.update(re.split(r"[^0-9A-Za-z_]+", str(term)))
    return frozenset(name for name in names if name in tokens)


def _coefficients(model: _Model) -> dict[str, float]:
    if model.fit is None:
        return {"const": float(model.level)}
    table = getattr(model.fit, "coefficients", None)
    if isinstance(table, pd.DataFrame) and "estimate" in table.columns:
        names = table.index.tolist()
        values = table["estimate"].to_numpy(dtype=float).tolist()
        return dict(zip(map(str, names), values, strict=True))
    return {}


#: Fewest channels two shapes must share for their MAC to count (one channel gives MAC = 1).
_MIN_SHAPE_CHANNELS = 3


def _mac_on_common_channels(reference: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """MAC of *reference* (n_channels,) with every row of *shapes* (n, n_channels).

    Each pair is compared on the channels both have (finite components); a pair sharing
    fewer than ``_MIN_SHAPE_CHANNELS`` channels gives NaN. Rows with the same set of
    available channels (usually every pole of a block) go to :func:`workbench.sid.assurance.mac`
    together.
    """
    from workbench.sid.assurance import mac

    out = np.full(shapes.shape[0], np.nan)
    if shapes.shape[0] == 0:
        return out
    ok = np.isfinite(shapes) & np.isfinite(reference)[None, :]
    if (ok == ok[0]).all():  # one set of channels for every row (the usual case)
        if ok[0].sum() < _MIN_SHAPE_CHANNELS:
            return out
        if ok[0].all():
            return np.asarray(mac(reference, shapes.T), dtype=float).reshape(-1)
        return np.asarray(mac(reference[ok[0]], shapes[:, ok[0]].T), dtype=float).reshape(-1)
    patterns, inverse = np.unique(ok, axis=0, return_inverse=True)
    inverse = np.asarray(inverse).reshape(-1)
    for p, pattern in enumerate(patterns):
        if pattern.sum() < _MIN_SHAPE_CHANNELS:
            continue
        rows = inverse == p
        out[rows] = np.asarray(mac(reference[pattern], shapes[rows][:, pattern].T)).reshape(-1)
    return out


def _shape_channels(modal: pd.DataFrame, poles: pd.DataFrame) -> list[str]:
    """Channels with shape columns in both tables, in the modal table's order."""
    in_poles = {str(c)[len("shape_re_") :] for c in poles.columns if str(c).startswith("shape_re_")}
    return [
        str(c)[len("shape_re_") :]
        for c in modal.columns
        if str(c).startswith("shape_re_") and str(c)[len("shape_re_") :] in in_poles
    ]


def _shape_matrix(frame: pd.DataFrame, channels: Sequence[str]) -> np.ndarray:
    """Complex shapes (n_rows, n_channels) of *channels* via :func:`shapes_from_frame`."""
    from data_contracts import shapes_from_frame

    names, shapes = shapes_from_frame(frame)
    if list(names) == list(channels):
        return shapes
    position = {name: k for k, name in enumerate(names)}
    return shapes[:, [position[c] for c in channels]]


@dataclass
class _BlockChoice:
    """Option B's measurements of one block (internal)."""

    frequency: np.ndarray  # chosen pole per mode, NaN: none
    mac: np.ndarray  # its MAC with the reference shape, NaN: not checked
    order: np.ndarray
    damping: np.ndarray
    reacquired: np.ndarray  # bool: chosen outside the gate (track re-acquired)
    no_reference: np.ndarray  # bool: shapes in use but the mode had no reference shape


class _PoleSelector:
    """Option B pole selection with mode-shape admissibility and track re-acquisition.

    Holds the pole table sorted by block, the pole shapes on the channels shared with the
    modal table, each mode's reference shape per grid row (see :func:`sliding_forecast`,
    Notes) and, per mode, the count of consecutive blocks with the mode seen only outside
    the gate and the frequency of the last chosen pole.
    """

    def __init__(
        self,
        poles: pd.DataFrame,
        modal: pd.DataFrame,
        blocks: np.ndarray,
        mode_labels: np.ndarray,
        *,
        shape_mac_min: float,
        reacquire_blocks: int,
        reacquire_band: float,
    ):
        needed = ("block", "model_order", "frequency_hz", "damping_ratio", "stable")
        missing = [c for c in needed if c not in poles.columns]
        if missing:
            raise ValueError(f"poles lacks column(s) {missing}")
        order = np.argsort(poles["block"].to_numpy(dtype=np.int64), kind="stable")
        pole_block = poles["block"].to_numpy(dtype=np.int64)[order]
        self.frequency = poles["frequency_hz"].to_numpy(dtype=float)[order]
        self.order = poles["model_order"].to_numpy(dtype=float)[order]
        self.damping = poles["damping_ratio"].to_numpy(dtype=float)[order]
        self.stable = poles["stable"].to_numpy(dtype=bool, na_value=False)[order]
        self.lo = np.searchsorted(pole_block, blocks, side="left")
        self.hi = np.searchsorted(pole_block, blocks, side="right")
        self.mac_min = float(shape_mac_min)
        self.reacquire_blocks = int(reacquire_blocks)
        self.band = float(reacquire_band)
        n_modes = mode_labels.size
        self.misses = np.zeros(n_modes, dtype=np.int64)
        self.anchor = np.full(n_modes, np.nan)  # frequency of the last chosen pole [Hz]
        self.channels = _shape_channels(modal, poles)
        self.shapes: np.ndarray | None = None
        self.reference_shapes = np.empty((0, 0), dtype=complex)
        self.reference_row = np.full((blocks.size, n_modes), -1, dtype=np.int64)
        if len(self.channels) < _MIN_SHAPE_CHANNELS:
            return
        self.shapes = _shape_matrix(poles, self.channels)  # table order: row self.rows[p]
        self.rows = order
        self._references(modal, blocks, mode_labels)

    @property
    def uses_shapes(self) -> bool:
        return self.shapes is not None

    def _references(self, modal: pd.DataFrame, blocks: np.ndarray, labels: np.ndarray) -> None:
        """Reference shape of each mode at each grid row: the latest confirmed tracked shape.

        A tracked shape is confirmed when its MAC with the mode's previous tracked shape is
        >= ``mac_min``; before the first confirmation, the mode's first tracked shape.
        Only tracked rows at or before the grid row's block are used (no look-ahead).
        """
        parts = []
        offset = 0
        for j, label in enumerate(labels):
            same = (modal["mode"] == label).to_numpy(dtype=bool, na_value=False)
            rows = modal[same].sort_values("block", kind="stable")
            rows = rows.drop_duplicates("block", keep="last")
            if rows.empty:
                continue
            shapes = _shape_matrix(rows, self.channels)
            usable = np.isfinite(shapes).sum(axis=1) >= _MIN_SHAPE_CHANNELS
            shapes = shapes[usable]
            track_blocks = rows["block"].to_numpy(dtype=np.int64)[usable]
            if track_blocks.size == 0:
                continue
            reference = np.zeros(track_blocks.size, dtype=np.int64)
            for r in range(1, track_blocks.size):
                agree = _mac_on_common_channels(shapes[r], shapes[r - 1 : r])[0]
                reference[r] = r if agree >= self.mac_min else reference[r - 1]
            position = np.searchsorted(track_blocks, blocks, side="right") - 1
            self.reference_row[:, j] = np.where(
                position >= 0, offset + reference[np.maximum(position, 0)], -1
            )
            parts.append(shapes)
            offset += shapes.shape[0]
        if parts:
            self.reference_shapes = np.concatenate(parts)

    def select(
        self, i: int, prior: np.ndarray, gate: np.ndarray, active: np.ndarray
    ) -> _BlockChoice:
        """Measurements of grid row *i* for the *active* modes (see sliding_forecast Notes).

        *prior* is x⁻ [Hz] and *gate* the gate half-width g = gate_sigma sqrt(P⁻ + R) [Hz]
        of each mode.
        """
        n_modes = prior.size
        choice = _BlockChoice(
            np.full(n_modes, np.nan),
            np.full(n_modes, np.nan),
            np.full(n_modes, np.nan),
            np.full(n_modes, np.nan),
            np.zeros(n_modes, dtype=bool),
            np.zeros(n_modes, dtype=bool),
        )
        lo, hi = int(self.lo[i]), int(self.hi[i])
        if hi <= lo:
            return choice
        f = self.frequency[lo:hi]
        stable = self.stable[lo:hi]
        for j in np.flatnonzero(active & np.isfinite(prior)):
            distance = np.abs(f - prior[j])
            with np.errstate(invalid="ignore"):
                inside = distance <= gate[j]
            ref = int(self.reference_row[i, j])
            if self.shapes is None or ref < 0:
                pick = self._nearest(inside, stable, distance)
                choice.no_reference[j] = self.shapes is not None and pick is not None
                mac_pick = math.nan
            else:
                pick, mac_pick = self._admissible_in_gate(
                    lo, inside, stable, float(gate[j]), self.reference_shapes[ref]
                )
                if pick is None:
                    pick, mac_pick = self._outside_gate(
                        lo, j, f, inside, stable, prior[j], self.reference_shapes[ref]
                    )
                    choice.reacquired[j] = pick is not None
                else:
                    self.misses[j] = 0
            if pick is None:
                continue
            choice.frequency[j] = f[pick]
            choice.mac[j] = mac_pick
            choice.order[j] = self.order[lo + pick]
            choice.damping[j] = self.damping[lo + pick]
            self.anchor[j] = f[pick]
        return choice

    @staticmethod
    def _nearest(inside: np.ndarray, stable: np.ndarray, distance: np.ndarray) -> int | None:
        """Without shapes: the nearest pole inside the gate, stable poles first."""
        candidates = inside & stable
        if not candidates.any():
            candidates = inside
            if not candidates.any():
                return None
        return int(np.flatnonzero(candidates)[np.argmin(distance[candidates])])

    def _admissible_in_gate(self, lo, inside, stable, gate, reference):
        """Best admissible pole inside the gate: stable first, then the lowest score."""
        index = np.flatnonzero(inside)
        if index.size == 0:
            return None, math.nan
        macs = _mac_on_common_channels(reference, self.shapes[self.rows[lo + index]])
        with np.errstate(invalid="ignore"):
            ok = macs >= self.mac_min
        if not ok.any():
            return None, math.nan
        index, macs = index[ok], macs[ok]
        if stable[index].any():
            keep = stable[index]
            index, macs = index[keep], macs[keep]
        # s = |f - median(f)| / g + (1 - MAC) / (1 - MAC_min), lowest wins
        f = self.frequency[lo + index]
        score = np.abs(f - np.median(f)) / gate + (1.0 - macs) / max(1.0 - self.mac_min, 1e-12)
        best = int(np.argmin(score))
        return int(index[best]), float(macs[best])

    def _outside_gate(self, lo, j, f, inside, stable, prior, reference):
        """Count a block with the mode only outside the gate; re-acquire after k of them."""
        near = np.zeros(f.size, dtype=bool)
        for centre in (self.anchor[j], prior):
            if np.isfinite(centre):
                near |= np.abs(f - centre) <= self.band * abs(centre)
        index = np.flatnonzero(near & ~inside)
        if index.size == 0:
            return None, math.nan
        macs = _mac_on_common_channels(reference, self.shapes[self.rows[lo + index]])
        with np.errstate(invalid="ignore"):
            ok = macs >= self.mac_min
        if not ok.any():  # the mode is not seen in this block: no evidence either way
            return None, math.nan
        self.misses[j] += 1
        if self.misses[j] < self.reacquire_blocks:
            return None, math.nan
        self.misses[j] = 0
        index, macs = index[ok], macs[ok]
        if stable[index].any():
            keep = stable[index]
            index, macs = index[keep], macs[keep]
        best = int(np.argmax(macs))  # highest MAC with the reference shape
        return int(index[best]), float(macs[best])


def _drop_unusable(out_phase, model, kalman, notes) -> None:
    """Rows without a model or Kalman value (a mode without any data yet) get phase 0:
    no row rather than a NaN row; counted in *notes*."""
    unusable = (out_phase > 0) & ~(np.isfinite(model) & np.isfinite(kalman))
    if unusable.any():
        notes["rows left out: no model value available (mode without data so far)"] += int(
            unusable.sum()
        )
        out_phase[unusable] = 0


def _assemble(
    blocks,
    block_start,
    mode_labels,
    option,
    phase,
    ssi,
    model,
    lower,
    upper,
    kalman,
    std,
    w0,
    w1,
    order,
    damping,
    selected_mac,
    warning_map,
) -> pd.DataFrame:
    rows, cols = np.nonzero(phase)
    n = rows.size
    warning_text = np.full(n, "", dtype=object)
    if warning_map:
        position = {(int(r), int(c)): p for p, (r, c) in enumerate(zip(rows, cols, strict=True))}
        for key, messages in warning_map.items():
            p = position.get(key)
            if p is not None:
                warning_text[p] = "; ".join(dict.fromkeys(m for m in messages if m))
    frame = pd.DataFrame(
        {
            "block": blocks[rows],
            "block_start": pd.to_datetime(block_start[rows], utc=True),
            "mode": mode_labels[cols].astype(np.int64),
            "phase": np.where(phase[rows, cols] == 1, "train", "forecast"),
            "ssi_frequency_hz": ssi[rows, cols],
            "model_frequency_hz": model[rows, cols],
            "model_lower_hz": lower[rows, cols],
            "model_upper_hz": upper[rows, cols],
            "kalman_frequency_hz": kalman[rows, cols],
            "kalman_std_hz": std[rows, cols],
            "option": option,
            "window_start_block": w0[rows, cols],
            "window_end_block": w1[rows, cols],
        }
    )
    if option == "B":
        frame["selected_model_order"] = pd.array(
            np.where(np.isfinite(order[rows, cols]), order[rows, cols], np.nan)
        ).astype("Int64")
        frame["selected_damping_ratio"] = damping[rows, cols]
        frame["selected_mac"] = selected_mac[rows, cols]
    frame["warning"] = pd.array(warning_text.tolist(), dtype="string")
    frame = frame.sort_values(["mode", "block"], kind="stable").reset_index(drop=True)
    return frame


#: Former keyword names of :func:`sliding_forecast` (README, "Glossary").
sliding_forecast.__deprecated_parameters__ = {"method": "scheme", "shape_mac_min": "mac_min"}
