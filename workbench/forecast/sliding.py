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

import functools
import math
import re
import warnings
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd
from scipy import stats as _scipy_stats

from .._deprecation import DEPRECATED, renamed_argument
from .kalman import ModeKalmanBank, process_variance_for_gain, relaxation_factor
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


@functools.lru_cache(maxsize=4096)
def _t_quantile(alpha: float, dof: int) -> float:
    """Two-sided Student-t quantile t_{1-α/2, dof} (cached: called per window and mode)."""
    return float(_scipy_stats.t.ppf(1 - alpha / 2, dof))


def _constant_prediction(
    level: float, spread: float, n: int, n_rows: int, alpha: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Constant model ȳ ± t s sqrt(1 + 1/n): mean, lower, upper, mean-prediction variance."""
    mean = np.full(n_rows, level)
    t = _t_quantile(alpha, max(n - 1, 1))
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
        ``"window"`` (default): the reference configuration, a stepwise model fitted on the
        last *train_blocks* blocks, Kalman trust *trust*. ``"memory"``: stepwise terms with
        coefficients over the whole history with exponential forgetting, noise levels from
        the data, an AR(1) measurement-error state (:func:`workbench.forecast.blend.
        memory_forecast`; *model_options*, *noise_options*). ``"memory"`` beats raw SSI by
        31-49 % on the block-level regimes of ``benchmarks/bench_forecast_accuracy.py`` but
        not yet on the demo voyage (22 % worse than raw SSI at 3 h), so it is not the
        default yet.
    cases : None, "derive", CaseRule, column name, path or DataFrame, optional
        Operating cases (:func:`workbench.stats.cases.case_labels`). Each window then
        trains on its blocks of the case the first forecast block is in, so the forecast
        uses the model of the current case (the whole window when the case has fewer than
        *min_train_blocks* of them; :func:`workbench.stats.case_training_mask`).
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
        if cases is not None:
            raise ValueError("cases apply to model='window'; model='memory' takes no cases yet")
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
    from workbench.stats import case_labels, case_training_mask, stepwise  # optional stage

    options = dict(stepwise_options or {})
    # a window's model uses the rows complete in every candidate predictor (the rule the
    # forecast was validated with); stepwise_options={"missing": "candidate"} for MATLAB's
    options.setdefault("missing", "complete")
    notes: Counter[str] = Counter()

    # ---- block grid and predictor matrix
    grid = predictors.sort_values("block").drop_duplicates("block", keep="last")
    blocks = grid["block"].to_numpy(dtype=np.int64)
    block_start = pd.to_datetime(grid["block_start"], utc=True).to_numpy()
    if predictor_columns is None:
        predictor_columns = [
            c
            for c in grid.columns
            if c != "block"
            and pd.api.types.is_numeric_dtype(grid[c].dtype)
            and not pd.api.types.is_bool_dtype(grid[c].dtype)
        ]
    else:
        missing = [c for c in predictor_columns if c not in grid.columns]
        if missing:
            raise ValueError(f"predictor_columns {missing} are not columns of predictors")
    columns = list(predictor_columns)
    X_all = (
        grid[columns].to_numpy(dtype=float, na_value=np.nan)
        if columns
        else np.empty((len(grid), 0))
    )
    n_blocks = len(blocks)
    labels = None if cases is None else case_labels(grid, cases).to_numpy()

    # ---- modes, tracked frequencies on the grid
    mode_labels = (
        np.array(sorted(int(m) for m in modal["mode"].dropna().unique()))
        if modes is None
        else np.asarray(modes, dtype=np.int64)
    )
    n_modes = len(mode_labels)
    if n_modes == 0:
        raise ValueError("modal has no modes to forecast")
    tracked = np.full((n_blocks, n_modes), np.nan)
    rows = np.searchsorted(blocks, modal["block"].to_numpy(dtype=np.int64))
    rows_ok = (rows < n_blocks) & (
        blocks[np.minimum(rows, n_blocks - 1)] == modal["block"].to_numpy()
    )
    mode_index = {int(m): j for j, m in enumerate(mode_labels)}
    cols = np.array([mode_index.get(int(m), -1) for m in modal["mode"].to_numpy()])
    keep = rows_ok & (cols >= 0)
    tracked[rows[keep], cols[keep]] = modal["frequency_hz"].to_numpy(dtype=float)[keep]

    # ---- poles per grid row and reference shapes (option B)
    selector: _PoleSelector | None = None
    if option == "B":
        selector = _PoleSelector(
            poles,
            modal,
            blocks,
            mode_labels,
            shape_mac_min=mac_min,
            reacquire_blocks=reacquire_blocks,
            reacquire_band=reacquire_band,
        )
        if not selector.uses_shapes:
            notes[
                "option B without mode shapes (poles or modal lack shape_re_<channel> columns "
                f"for {_MIN_SHAPE_CHANNELS}+ shared channels): nearest pole in the gate, "
                "no MAC check"
            ] += 1

    # ---- first window
    if start_block is None:
        first = 0
    else:
        first = int(np.searchsorted(blocks, start_block))
        if first >= n_blocks or blocks[first] != start_block:
            raise ValueError(f"start_block={start_block} is not a block of predictors")
    last = n_blocks - 1
    if end_block is not None:
        last = int(np.searchsorted(blocks, int(end_block), side="right")) - 1
    if last - first + 1 < train_blocks + 1:
        raise ValueError(
            f"train_blocks={train_blocks} needs at least {train_blocks + 1} blocks from "
            f"start_block to end_block, got {max(last - first + 1, 0)}"
        )

    # ---- outputs on the grid (row index) x mode
    shape = (n_blocks, n_modes)
    out_phase = np.zeros(shape, dtype=np.int8)  # 0 none, 1 train, 2 forecast
    out_ssi = np.full(shape, np.nan)
    out_model = np.full(shape, np.nan)
    out_lower = np.full(shape, np.nan)
    out_upper = np.full(shape, np.nan)
    out_kalman = np.full(shape, np.nan)
    out_std = np.full(shape, np.nan)
    out_w0 = np.zeros(shape, dtype=np.int64)
    out_w1 = np.zeros(shape, dtype=np.int64)
    out_order = np.full(shape, np.nan)
    out_damping = np.full(shape, np.nan)
    out_mac = np.full(shape, np.nan)
    out_warning: dict[tuple[int, int], list[str]] = {}

    def warn_rows(row_slice: range | list[int], j: int, message: str, kind: str) -> None:
        notes[kind] += 1
        for i in row_slice:
            out_warning.setdefault((i, j), []).append(message)

    targets = tracked.copy()  # training targets: tracked, then Kalman estimates (method 2)
    measured = np.full(shape, np.nan)  # measurement used in each block (for R)
    measured[first : first + train_blocks] = tracked[first : first + train_blocks]
    bank = ModeKalmanBank(n_modes, transition=phi)
    last_good: list[_Model | None] = [None] * n_modes
    last_r = np.full(n_modes, np.nan)
    previous_model_value = np.full(n_modes, np.nan)  # m_{k-1} under the current model
    gap = np.zeros(n_modes, dtype=np.int64)
    models_out: list[WindowModel] = []
    started = np.zeros(n_modes, dtype=bool)
    reference_hz = np.full(n_modes, np.nan)  # first window's median: plausibility band

    window_start = first
    while True:
        w0, w1 = window_start, window_start + train_blocks  # training rows [w0, w1)
        f0 = w1
        f1 = min(f0 + horizon, last + 1) if method == 2 else min(f0 + horizon, n_blocks)
        if f0 >= f1:
            break
        is_first = w0 == first
        X_train = X_all[w0:w1]
        # ---- candidate predictors of this window (enough valid values, not constant)
        use = []
        for c, name in enumerate(columns):
            values = X_train[:, c]
            valid = np.isfinite(values)
            if valid.sum() < min_train:
                notes[f"predictor '{name}' left out: fewer than {min_train} valid values"] += 1
                continue
            v = values[valid]
            if np.ptp(v) <= 1e-12 * max(1.0, float(np.abs(v).max())):
                notes[f"predictor '{name}' left out: constant in the window"] += 1
                continue
            use.append(c)
        use_names = tuple(columns[c] for c in use)
        Xw = X_train[:, use]
        mean = np.nanmean(Xw, axis=0) if use else np.empty(0)
        scale = np.nanstd(Xw, axis=0, ddof=1) if use else np.empty(0)
        z_train = pd.DataFrame((Xw - mean) / scale, columns=list(use_names))
        pred_rows = np.arange(w0, f1)  # training rows then forecast rows
        window_models: list[_Model | None] = []
        window_frame: pd.DataFrame | None = None  # z-scored rows [w0, f1), built once
        for j in range(n_modes):
            y = targets[w0:w1, j]
            in_case = case_training_mask(labels, slice(w0, w1), f0, min_train, np.isfinite(y))
            if in_case is not None:  # the model of the current operating case
                y = np.where(in_case, y, np.nan)
            valid_y = np.isfinite(y)
            n_valid = int(valid_y.sum())
            model: _Model | None = None
            reason = ""
            if not np.isfinite(reference_hz[j]) and n_valid >= 1:
                reference_hz[j] = float(np.median(y[valid_y]))
            if n_valid >= min_train and use:
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        fit = stepwise(z_train, y, **options)
                    rmse = float(fit.rmse)
                    n_params = len(getattr(fit, "coefficients", ())) or 1
                    if not np.isfinite(rmse):
                        raise ValueError("non-finite rmse")
                    model = _Model(
                        "stepwise",
                        fit,
                        use_names,
                        mean,
                        scale,
                        n_train=n_valid,
                        n_params=n_params,
                        rmse=rmse,
                        used=_used_columns(fit, use_names),
                    )
                    last_good[j] = model
                except Exception as error:  # rank deficiency, singular fits...
                    reason = f"stepwise fit failed ({type(error).__name__})"
            elif n_valid < min_train:
                reason = f"too few valid blocks ({n_valid} < {min_train})"
            else:
                reason = "no usable predictor"
            if model is None and n_valid >= min_train and not use:
                model = None  # constant model below is the right model here
            elif model is None and last_good[j] is not None:
                model = last_good[j]
                model = _Model(**{**model.__dict__, "kind": "last_good"})
                reason += ": last good model"
            if model is None:
                if n_valid >= 1:
                    level = float(np.mean(y[valid_y]))
                    spread = float(np.std(y[valid_y], ddof=1)) if n_valid >= 2 else math.nan
                elif started[j]:
                    level, spread = float(bank.state[j]), math.nan
                    n_valid = 1
                else:
                    level = math.nan
                if not np.isfinite(level):
                    warn_rows([], j, "", f"mode {mode_labels[j]}: no data yet, no forecast")
                    window_models.append(None)
                    continue
                if not np.isfinite(spread) or spread <= 0:
                    spread = (
                        math.sqrt(last_r[j])
                        if np.isfinite(last_r[j])
                        else _DEFAULT_RELATIVE_STD * abs(level)
                    )
                model = _Model(
                    "constant",
                    None,
                    (),
                    np.empty(0),
                    np.empty(0),
                    level=level,
                    spread=spread,
                    n_train=max(n_valid, 1),
                    n_params=1,
                    rmse=spread,
                )
                if reason:
                    reason += ": constant model"
            window_models.append(model)

            # ---- predictions on training + forecast rows
            if model.kind == "stepwise":  # this window's normalisation: shared frame
                rows_X = X_all[w0:f1][:, use]
                if window_frame is None:
                    z_rows = _z_scores(rows_X, mean, scale, extrapolation_limit)
                    window_frame = pd.DataFrame(z_rows, columns=list(use_names))
                mean_p, lower_p, upper_p, mvar = _predict(
                    model, rows_X, alpha, extrapolation_limit, window_frame
                )
            else:
                rows_X = X_all[w0:f1][:, [columns.index(c) for c in model.columns]]
                mean_p, lower_p, upper_p, mvar = _predict(model, rows_X, alpha, extrapolation_limit)
            if model.fit is not None:
                used = [c for c, name in enumerate(model.columns) if name in model.used]
                if used:
                    with np.errstate(invalid="ignore", divide="ignore"):
                        far = np.abs((rows_X[:, used] - model.mean[used]) / model.scale[used])
                    clipped = pred_rows[(far > extrapolation_limit).any(axis=1)]
                    clipped = clipped[clipped >= (w0 if is_first else f0)]
                    if clipped.size:
                        warn_rows(
                            clipped.tolist(),
                            j,
                            f"predictors beyond ±{extrapolation_limit:g} sd of the window: clipped",
                            "blocks with predictors far outside the training window (clipped)",
                        )
            with np.errstate(invalid="ignore"):
                implausible = np.isfinite(mean_p) & ~_plausible(mean_p, reference_hz[j])
            mean_p[implausible] = np.nan  # non-physical: constant model below
            bad = ~np.isfinite(mean_p)
            if bad.any():
                # needed predictor NaN in these blocks: constant model of the window
                if n_valid >= 1:
                    level = float(np.mean(y[valid_y]))
                    spread = float(np.std(y[valid_y], ddof=1)) if n_valid >= 2 else model.rmse
                elif started[j]:
                    level, spread = float(bank.state[j]), model.rmse
                else:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore", RuntimeWarning)
                        level, spread = float(np.nanmean(mean_p)), model.rmse
                cm, cl, cu, cv = _constant_prediction(
                    level,
                    spread if spread > 0 else model.rmse,
                    max(n_valid, 1),
                    int(bad.sum()),
                    alpha,
                )
                mean_p[bad], lower_p[bad], upper_p[bad], mvar[bad] = cm, cl, cu, cv
                shown_from = w0 if is_first else f0
                for mask, message, kind in (
                    (
                        bad & ~implausible,
                        "predictor NaN: constant-model prediction",
                        "blocks predicted by the constant model (a needed predictor is NaN)",
                    ),
                    (
                        implausible,
                        "model implausible: constant-model prediction",
                        "blocks predicted by the constant model (model value outside "
                        f"{1 / _PLAUSIBLE_FACTOR:g}-{_PLAUSIBLE_FACTOR:g} x the mode's level)",
                    ),
                ):
                    shown = pred_rows[mask]
                    shown = shown[shown >= shown_from]
                    if shown.size:
                        warn_rows(shown.tolist(), j, message, kind)
            n_tr = w1 - w0
            m_train = mean_p[:n_tr]
            # ---- R: scatter of the measurements about the model in the window
            resid = measured[w0:w1, j] - m_train
            resid = resid[np.isfinite(resid)]
            dof = resid.size - model.n_params
            level_hz = float(np.nanmean(np.abs(mean_p)))
            if resid.size >= _MIN_DIFFERENCES + 1:
                r = _white_scatter_variance(resid)
            elif dof >= 2:
                r = float(resid @ resid) / dof
            elif np.isfinite(last_r[j]):
                r = float(last_r[j])
            elif np.isfinite(model.rmse) and model.rmse > 0:
                r = model.rmse**2
            else:
                r = (_DEFAULT_RELATIVE_STD * level_hz) ** 2
            r = max(r, (_MIN_RELATIVE_STD * level_hz) ** 2)
            last_r[j] = r
            # ---- Q: from trust, or the model's own mean-prediction variance
            if trust is not None:
                q = process_variance_for_gain(float(trust), r, transition=phi)
            else:
                s2 = float(np.nanmean(mvar[n_tr:])) if np.isfinite(mvar[n_tr:]).any() else r
                q = max(s2, (_MIN_RELATIVE_STD * level_hz) ** 2) * (1.0 - phi * phi)
            bank.process_variance[j] = q
            bank.measurement_variance[j] = r
            if reason:
                shown_rows = range(w0 if is_first else f0, f1)
                warn_rows(
                    shown_rows,
                    j,
                    f"window {blocks[w0]}-{blocks[w1 - 1]}: {reason}",
                    f"windows with a fallback model ({reason.split(' (')[0]})",
                )
            models_out.append(
                WindowModel(
                    mode=int(mode_labels[j]),
                    window_start_block=int(blocks[w0]),
                    window_end_block=int(blocks[w1 - 1]),
                    kind=model.kind,  # type: ignore[arg-type]
                    terms=model.terms(),
                    coefficients=_coefficients(model),
                    n_train=n_valid,
                    rmse_hz=float(model.rmse),
                    measurement_variance=r,
                    process_variance=q,
                    normalisation={
                        c: (float(a), float(b))
                        for c, a, b in zip(model.columns, model.mean, model.scale, strict=True)
                    },
                    warning=reason,
                )
            )
            # ---- store the model track of the rows this window reports
            report = slice(0, None) if is_first else slice(n_tr, None)
            rows_rep = pred_rows[report]
            out_model[rows_rep, j] = mean_p[report]
            out_lower[rows_rep, j] = lower_p[report]
            out_upper[rows_rep, j] = upper_p[report]
            out_w0[rows_rep, j] = blocks[w0]
            out_w1[rows_rep, j] = blocks[w1 - 1]
            out_phase[rows_rep, j] = np.where(rows_rep < w1, 1, 2)
            # m_{k-1} under this window's model for the first reported row's predict step
            previous_model_value[j] = mean_p[n_tr - 1] if not is_first else math.nan

        # ---- Kalman pass over the reported rows (all modes together)
        k_first = w0 if is_first else f0
        for i in range(k_first, f1):
            model_now = out_model[i]
            have = np.isfinite(model_now)
            # B u = m_k - φ m_{k-1}; a mode without m_{k-1} (no model in the last window)
            # restarts its correction from zero: B u = m_k - φ x⁺_{k-1}, so x⁻ = m_k
            control = np.where(
                np.isfinite(previous_model_value),
                model_now - phi * previous_model_value,
                model_now - phi * bank.state,
            )
            bank.predict(control, active=have & started)
            fresh = have & ~started
            if fresh.any():
                idx = np.flatnonzero(fresh)
                bank.initialise(idx, model_now[idx])
                started[idx] = True
            prior_x, prior_p = bank.state.copy(), bank.variance.copy()
            if option == "A":
                z = tracked[i].copy()
            else:
                with np.errstate(invalid="ignore"):
                    gate = gate_sigma * np.sqrt(prior_p + bank.measurement_variance)
                choice = selector.select(i, prior_x, gate, have & started)
                z = choice.frequency
                out_order[i], out_damping[i], out_mac[i] = choice.order, choice.damping, choice.mac
                for j in np.flatnonzero(choice.no_reference):
                    warn_rows(
                        [i],
                        j,
                        "no reference shape yet: nearest pole, no MAC check",
                        "option B rows without a reference shape (nearest pole, no MAC check)",
                    )
                if choice.reacquired.any():
                    idx = np.flatnonzero(choice.reacquired)
                    # P⁻ ← max(P⁻, y²): the prior was wrong by y = z - x⁻, so K ≈ 1
                    bank.inflate(idx, (z[idx] - prior_x[idx]) ** 2)
                    for j in idx:
                        warn_rows(
                            [i],
                            j,
                            f"track re-acquired: pole at {z[j]:.4f} Hz (MAC {choice.mac[j]:.3f}) "
                            f"outside the gate {prior_x[j]:.4f} ± {gate[j]:.4f} Hz",
                            "tracks re-acquired outside the gate (option B: mode seen only "
                            f"outside the gate for {reacquire_blocks} block(s))",
                        )
            z[~have] = np.nan
            bank.update(z)
            lost = have & started & ~_plausible(bank.state, reference_hz)
            if lost.any():  # track lost (model or measurements far off): restart at model
                idx = np.flatnonzero(lost)
                bank.initialise(idx, model_now[idx])
                for j in idx:
                    warn_rows(
                        [i],
                        j,
                        "Kalman track implausible: restarted at the model",
                        "Kalman tracks restarted at the model (estimate implausible)",
                    )
            measured[i] = z
            out_ssi[i] = z
            out_kalman[i] = np.where(have, bank.state, np.nan)
            out_std[i] = np.where(have, np.sqrt(np.maximum(bank.variance, 0.0)), np.nan)
            has_z = np.isfinite(z)
            gap = np.where(has_z, 0, gap + have)
            for j in np.flatnonzero(have & (gap >= gap_warning_blocks)):
                warn_rows(
                    [i],
                    j,
                    f"no SSI estimate for {gap[j]} blocks: predict-only",
                    "rows in a long stretch without SSI estimates (predict-only)",
                )
            previous_model_value = np.where(have, model_now, previous_model_value)
        if method == 2:
            # the Kalman estimates of the blocks with a measurement are the next windows'
            # targets; predict-only blocks carry no new information (re-training on them
            # would feed the model its own extrapolation), modes not started keep tracked
            kalman_rows = out_kalman[f0:f1]
            targets[f0:f1] = np.where(
                np.isfinite(kalman_rows),
                np.where(np.isfinite(measured[f0:f1]), kalman_rows, np.nan),
                tracked[f0:f1],
            )
        if method == 1 or f1 > last:
            break
        window_start += horizon

    _drop_unusable(out_phase, out_model, out_kalman, notes)
    table = _assemble(
        blocks,
        block_start,
        mode_labels,
        option,
        out_phase,
        out_ssi,
        out_model,
        out_lower,
        out_upper,
        out_kalman,
        out_std,
        out_w0,
        out_w1,
        out_order,
        out_damping,
        out_mac,
        out_warning,
    )
    messages = tuple(f"{kind} (x{count})" for kind, count in notes.items())
    for message in messages:
        warnings.warn(message, ForecastWarning, stacklevel=2)
    return ForecastResult(table=table, warnings=messages, models=tuple(models_out))


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
    available channels (usually every pole of a block) go to :func:`workbench.sid.mac.mac`
    together.
    """
    from workbench.sid.mac import mac

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
