"""Forecast with a model that has memory, noise from the data and an AR(1) measurement error.

The steps, each in its own module:

1. window model - :mod:`workbench.forecast.memory` (stepwise terms, exponentially
   weighted least squares over the history, refit every *horizon* blocks);
2. noise estimation - :mod:`workbench.forecast.noise` (covariance matching of the
   out-of-sample residuals);
3. measurement choice - :mod:`workbench.forecast.measurement` (tracked pole or consistent
   pole cluster, per-block scatter);
4. Kalman pass - :func:`kalman_pass_step` below.

Kalman model per mode, with m_k the model's prediction and z_k the block's SSI estimate:

.. math::

    x_k = m_k + c_k, \\quad z_k = x_k + e_k + v_k, \\quad
    \\begin{bmatrix} c_k \\\\ e_k \\end{bmatrix} =
    \\begin{bmatrix} φ & 0 \\\\ 0 & ρ \\end{bmatrix}
    \\begin{bmatrix} c_{k-1} \\\\ e_{k-1} \\end{bmatrix} + w_k,

Q = diag(σ_c²(1 - φ²), σ_e²(1 - ρ²) s_k), R_k = σ_v² s_k, H = [1 1], with s_k the block's
measurement scale (pole scatter across model orders). With the excitation term
(:mod:`workbench.forecast.excitation`) the measurement is about the model at the
excitation-weighted speed: z_k = m̃_k + c_k + e_k + v_k, m̃_k = m(v̄_k + κ σ²_{v,k}, ...),
while the state stays x_k = m_k + c_k: SSI's bias in a block whose speed changes goes into
the measurement equation, not into the estimate. The identification error e is a state
because 75 %-overlapping blocks share their data: a white R would count the same error
several times. The blended estimate is x̂ = m + ĉ.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections import Counter

import numpy as np
import pandas as pd

from ..stats.distributions import t_quantile
from .excitation import sub_windows_per_block, within_block_variance
from .measurement import (
    ClusterChooser,
    PoleIndex,
    cluster_around,
    scatter_scale,
)
from .memory import MemoryModel, constant_model, fit_memory_model, select_terms
from .noise import MIN_CORRECTION_STD, MIN_RESIDUALS, NoiseModel, estimate_noise, prior_noise
from .options import MeasurementOptions, ModelOptions, NoiseOptions
from .predictor_grid import predictor_matrix

__all__ = ["kalman_pass_step", "memory_forecast"]

#: Fewest non-overlapping measured blocks for a stepwise term selection; with fewer the
#: model is the weighted mean (a 20-block window holds only 5 independent SSI estimates,
#: and a stepwise fit on its 20 overlapping ones extrapolates wildly).
_MIN_SELECTION_ROWS = 10
#: Entry p-value of the short-history selection before the division by the overlap.
_SHORT_P_ENTER = 0.05
#: Fewest consecutive large innovations of one sign that mean the model is off (at least
#: one more than the blocks sharing data with the first: one corrupted stretch of data is
#: in all the blocks that overlap it).
_PERSIST_BLOCKS = 3
#: Oldest history a refit looks at, in forgetting time constants (weight e^-6 beyond).
_HISTORY_CONSTANTS = 6.0


def kalman_pass_step(
    state,
    P,
    F,
    Q,
    residual,
    R,
    huber_sigma,
    model_variance=None,
    previous_run=None,
    persist_blocks=3,
):
    """One predict + update of the two-state filter for several modes at once.

    Parameters
    ----------
    state : ndarray (n, 2)
        [c, e] a-posteriori of the previous block.
    P : ndarray (n, 2, 2)
    F : ndarray (n, 2)
        Diagonal of F: (φ, ρ).
    Q : ndarray (n, 2)
        Diagonal of Q.
    residual : ndarray (n,)
        z - m (NaN: predict only). [Hz]
    R : ndarray (n,)
        White measurement variance. [Hz²]
    huber_sigma : float or ndarray (n,)
    model_variance : ndarray (n,), optional
        s_m², variance of the model's mean prediction in this block: a white error of the
        model term, x = m + δ + c with δ ~ N(0, s_m²). [Hz²]
    previous_run : ndarray of int (n,), optional
        Signed count of the consecutive measured blocks just before, whose normalised
        innovation was beyond *huber_sigma* (+: above, -: below). When this block's makes
        the run *persist_blocks* long, the model is wrong, not the measurement: no Huber
        weight, and P_cc is raised to y² (gain on c about 1). Shorter runs are what an
        AR(1) identification error with heavy tails produces and get the Huber weight.
    persist_blocks : int

    Returns
    -------
    state, P, white model correction δ̂ (n,), normalised innovation y/sqrt(S) (n,)
    """
    # x = Fx ; P = FPF' + Q
    state = state * F
    P = P * (F[:, :, None] * F[:, None, :])
    P[:, 0, 0] += Q[:, 0]
    P[:, 1, 1] += Q[:, 1]
    n = state.shape[0]
    delta = np.zeros(n)
    normalised = np.full(n, np.nan)
    ok = np.isfinite(residual)
    if not ok.any():
        return state, P, delta, normalised
    idx = np.flatnonzero(ok)
    Pm, xm = P[idx], state[idx]
    sm2 = np.zeros(idx.size) if model_variance is None else model_variance[idx]
    # y = z - Hx ; S = HPH' + R + s_m²  (H = [1 1])
    y = residual[idx] - xm.sum(axis=1)
    S = Pm[:, 0, 0] + Pm[:, 1, 1] + 2 * Pm[:, 0, 1] + R[idx] + sm2
    nu = y / np.sqrt(S)
    normalised[idx] = nu
    huber_sigma = np.broadcast_to(np.asarray(huber_sigma, dtype=float), (n,))[idx]
    keep_on = np.zeros(idx.size, dtype=bool)
    if previous_run is not None:
        before = previous_run[idx]
        keep_on = (np.abs(nu) > huber_sigma) & (np.abs(before) >= persist_blocks - 1)
        keep_on &= np.sign(nu) == np.sign(before)
    if keep_on.any():  # the model is off: P_cc ← max(P_cc, y²)
        grow = np.maximum(y[keep_on] ** 2 - Pm[keep_on, 0, 0], 0.0)
        Pm[keep_on, 0, 0] += grow
        S[keep_on] += grow
    # Huber weight: beyond huber_sigma sqrt(S) an isolated measurement counts as if it
    # were there, i.e. R ← R + S (ν/k - 1), ν = |y| / sqrt(S)
    a = np.abs(nu)
    extra = np.where((a > huber_sigma) & ~keep_on, S * (a / huber_sigma - 1.0), 0.0)
    R_eff = R[idx] + extra
    S = S + extra
    delta[idx] = sm2 / S * y  # δ̂ = s_m² S⁻¹ y
    # K = PH'S⁻¹
    PH = np.stack([Pm[:, 0, 0] + Pm[:, 0, 1], Pm[:, 1, 0] + Pm[:, 1, 1]], axis=1)
    K = PH / S[:, None]
    # x = x + Ky
    xm = xm + K * y[:, None]
    # P = (I - KH) P (I - KH)' + K R K'   (Joseph form)
    A = np.eye(2)[None, :, :] - K[:, :, None] * np.ones((1, 1, 2))
    Pm = A @ Pm @ np.transpose(A, (0, 2, 1)) + (R_eff + sm2)[:, None, None] * (
        K[:, :, None] * K[:, None, :]
    )
    state[idx], P[idx] = xm, Pm
    return state, P, delta, normalised


#: Largest excitation sensitivity d ln P / dv accepted: the response power at most
#: doubling per knot. [1/kn]
_MAX_KAPPA = float(np.log(2.0))


def _excitation_statistics(fitted, X, y, age, speed_col, speed_var, memory, limit):
    """Weighted normal-equation terms of κ for one mode, and the model's speed slope.

    With d_k = ∂m/∂v the model's speed slope at block k (1-kn difference) the
    measurement's excitation bias is d_k κ σ_k² (:mod:`~workbench.forecast.excitation`);
    the least-squares κ of the residuals r_k on g_k = d_k σ_k², with forgetting weights
    w_k, is Σ w g r / Σ w g². Each mode's sums are divided by its residual variance, so
    that κ (a property of the excitation, common to all modes) is pooled by precision.

    Returns
    -------
    (numerator, denominator, slope) or None
    """
    ok = np.isfinite(y) & (speed_var > 0)
    if ok.sum() < 3:
        return None
    Xp = X.copy()
    Xp[:, speed_col] += 1.0
    base = fitted.predict(X, limit)[0]
    slope = fitted.predict(Xp, limit)[0] - base  # ∂m/∂v [Hz/kn]
    g = slope * speed_var
    w = np.exp(-age / memory) / fitted.residual_variance
    good = ok & np.isfinite(g) & np.isfinite(base)
    if not good.any():
        return None
    numerator = float((w[good] * g[good] * (y[good] - base[good])).sum())
    denominator = float((w[good] * g[good] ** 2).sum())
    return numerator, denominator, slope


def _debiased_refit(fitted, X, y, age, bias, memory, limit):
    """Refit *fitted*'s terms on the targets minus the excitation bias (time averages)."""
    refitted = fit_memory_model(
        X,
        y - np.where(np.isfinite(bias), bias, 0.0),
        age,
        columns=fitted.columns,
        names=fitted.names,
        terms=fitted.terms,
        mean=fitted.mean,
        scale=fitted.scale,
        memory_blocks=memory,
        limit=limit,
    )
    return fitted if refitted is None else refitted


def _stationary(noise: NoiseModel) -> np.ndarray:
    return np.diag([noise.correction_variance, noise.error_variance + 1e-300])


def memory_forecast(
    modal: pd.DataFrame,
    predictors: pd.DataFrame,
    *,
    poles: pd.DataFrame | None,
    method: int,
    horizon: int,
    start_block: int | None,
    end_block: int | None,
    modes,
    model: ModelOptions,
    noise: NoiseOptions,
    measurement: MeasurementOptions,
    gap_warning_blocks: int = 12,
    cases=None,
):
    """Forecast with :mod:`memory <workbench.forecast.memory>` models (see module docs).

    Called by :func:`~workbench.forecast.sliding_forecast` for ``model="memory"``;
    returns a :class:`~workbench.forecast.ForecastResult`.
    """
    from .sliding import (
        _MIN_SHAPE_CHANNELS,
        ForecastResult,
        ForecastWarning,
        WindowModel,
        _assemble,
        _drop_unusable,
        _mac_on_common_channels,
        _plausible,
        _PoleSelector,
    )

    option = measurement.option
    notes: Counter[str] = Counter()
    grid, blocks, block_start, columns, X_all = predictor_matrix(
        predictors, model.predictor_columns
    )
    n_blocks = blocks.size
    if model.time_trend and model.predictor_columns is None:  # explicit columns: as given
        # slow drifts no log records (fuel burn, ballast): a trend term with memory
        start_ns = pd.to_datetime(grid["block_start"], utc=True).astype("int64").to_numpy()
        hours = (start_ns - start_ns[0]) / 3.6e12
        X_all = np.column_stack([X_all, hours.astype(float)])
        columns = [*columns, "elapsed_hours"]
    # SSI's excitation weighting: in a block whose speed changes, SSI sees the frequency at
    # about v̄ + κ σ_v² (workbench.forecast.excitation); σ_v² from the overlapping blocks
    speed_col = columns.index("speed_kn") if "speed_kn" in columns else None
    n_sub = sub_windows_per_block(grid) if model.excitation_bias else None
    # blocks that share data with a block: its identification error (an ice impact, a
    # badly excited stretch) is in all of them, so a run of large innovations is evidence
    # that the model is off only when it reaches a block that shares no data with the first
    overlap = sub_windows_per_block(grid) or 1
    speed_var = shift_cap = None
    if n_sub is not None and speed_col is not None:
        speed_var = within_block_variance(X_all[:, speed_col], n_sub)
        speed_var = np.where(np.isfinite(speed_var), speed_var, 0.0)
        # a weighted mean of n sub-windows lies at most sqrt(n - 1) σ from their mean
        shift_cap = np.sqrt((n_sub - 1) * speed_var)
        if not speed_var.max(initial=0.0) > 0:
            speed_var = None
    mode_labels = (
        np.array(sorted(int(m) for m in modal["mode"].dropna().unique()))
        if modes is None
        else np.asarray(modes, dtype=np.int64)
    )
    n_modes = mode_labels.size
    if n_modes == 0:
        raise ValueError("modal has no modes to forecast")
    kappa = np.zeros(n_modes)  # excitation sensitivity d ln P / dv per mode [1/kn]
    tracked = np.full((n_blocks, n_modes), np.nan)
    tracked_damping = np.full((n_blocks, n_modes), np.nan)
    rows = np.searchsorted(blocks, modal["block"].to_numpy(dtype=np.int64))
    rows_ok = (rows < n_blocks) & (
        blocks[np.minimum(rows, n_blocks - 1)] == modal["block"].to_numpy()
    )
    mode_index = {int(m): j for j, m in enumerate(mode_labels)}
    cols = np.array([mode_index.get(int(m), -1) for m in modal["mode"].to_numpy()])
    keep = rows_ok & (cols >= 0)
    tracked[rows[keep], cols[keep]] = modal["frequency_hz"].to_numpy(dtype=float)[keep]
    if "damping_ratio" in modal.columns:
        tracked_damping[rows[keep], cols[keep]] = modal["damping_ratio"].to_numpy(dtype=float)[keep]

    first = 0 if start_block is None else int(np.searchsorted(blocks, start_block))
    if start_block is not None and (first >= n_blocks or blocks[first] != start_block):
        raise ValueError(f"start_block={start_block} is not a block of predictors")
    last = n_blocks - 1
    if end_block is not None:
        last = int(np.searchsorted(blocks, int(end_block), side="right")) - 1
    train = int(model.train_blocks)
    if last - first + 1 < train + 1:
        raise ValueError(
            f"train_blocks={train} needs at least {train + 1} blocks from "
            f"start_block to end_block, got {max(last - first + 1, 0)}"
        )
    min_train = max(5, train // 2) if model.min_train_blocks is None else model.min_train_blocks
    if not 2 <= min_train <= train:
        raise ValueError(f"min_train_blocks={min_train} must be in [2, train_blocks]")
    limit = float(model.extrapolation_limit)
    memory = float(model.memory_blocks)
    history_limit = int(math.ceil(_HISTORY_CONSTANTS * memory))

    # ---- poles: per-block scatter and option B's chooser
    index = PoleIndex(poles, blocks) if poles is not None else None
    chooser = None
    if option == "B":
        if index is None:
            raise ValueError("option='B' needs poles (the stabilisation diagrams)")
        selector = _PoleSelector(
            poles,
            modal,
            blocks,
            mode_labels,
            shape_mac_min=measurement.mac_min,
            reacquire_blocks=measurement.reacquire_blocks,
            reacquire_band=measurement.reacquire_band,
        )
        shape_mac = None
        if selector.uses_shapes:
            # selector rows are in the table order of its own sort; map PoleIndex positions
            table_row_to_selector = np.empty(len(poles), dtype=np.int64)
            table_row_to_selector[selector.rows] = np.arange(selector.rows.size)

            def shape_mac(i, j, positions):
                ref = int(selector.reference_row[i, j])
                if ref < 0:
                    return np.full(positions.size, np.nan)
                table_rows = index.rows[positions]
                shapes = selector.shapes[selector.rows[table_row_to_selector[table_rows]]]
                return _mac_on_common_channels(selector.reference_shapes[ref], shapes)
        else:
            notes[
                "option B without mode shapes (poles or modal lack shape_re_<channel> columns "
                f"for {_MIN_SHAPE_CHANNELS}+ shared channels): consistent pole cluster in the "
                "gate, no MAC check"
            ] += 1
        chooser = ClusterChooser(
            index,
            shape_mac,
            shape_mac_min=measurement.mac_min,
            reacquire_blocks=measurement.reacquire_blocks,
            reacquire_band=measurement.reacquire_band,
        )

    shape = (n_blocks, n_modes)
    out_phase = np.zeros(shape, dtype=np.int8)
    out = {
        k: np.full(shape, np.nan)
        for k in (
            "ssi",
            "model",
            "lower",
            "upper",
            "kalman",
            "std",
            "order",
            "damping",
            "mac",
            "n_orders",
            "scatter",
            "min_order",
            "max_order",
            "seen",
        )
    }
    out_w0 = np.zeros(shape, dtype=np.int64)
    out_w1 = np.zeros(shape, dtype=np.int64)
    out_warning: dict[tuple[int, int], list[str]] = {}

    def warn(i, j, message, kind):
        notes[kind] += 1
        out_warning.setdefault((i, j), []).append(message)

    meas = np.full(shape, np.nan)  # measurement used per block (training: tracked)
    meas[first : first + train] = tracked[first : first + train]
    resid = np.full(shape, np.nan)  # z - m, out of sample after the first window
    scatter = np.full(shape, np.nan)  # cluster scatter of the block's measurement
    with warnings.catch_warnings():  # a mode without data in the first window: NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        reference_hz = np.nanmedian(tracked[first : first + train], axis=0)
        damping_ref = np.nanmedian(tracked_damping[first : first + train], axis=0)
    terms_of: list[tuple | None] = [None] * n_modes
    selected_case: list = [None] * n_modes  # operating case of each mode's term selection
    train_y: list = [None] * n_modes  # targets of each mode's last refit (case rows only)
    labels = None
    if cases is not None:
        from workbench.stats import case_labels, case_training_mask

        labels = case_labels(grid, cases).to_numpy()
    selected_at = np.full(n_modes, -(10**9))
    current: list[MemoryModel | None] = [None] * n_modes
    noise_of: list[NoiseModel | None] = [None] * n_modes
    noise_at = np.full(n_modes, -(10**9))  # grid row of each mode's last noise estimate
    state = np.zeros((n_modes, 2))
    P = np.zeros((n_modes, 2, 2))
    started = np.zeros(n_modes, dtype=bool)
    gap = np.zeros(n_modes, dtype=np.int64)
    models_out = []
    t_cache: dict[int, float] = {}

    selection_range: list = [None] * n_modes  # predictor ranges of each term selection
    # predictors whose range is not a question of operating region: the time trend always
    # leaves it, by design
    regional = np.array([name != "elapsed_hours" for name in columns])

    def left_selection_range(j: int, i: int, rows_ok: np.ndarray) -> int | None:
        """The newest measured block since mode j's term selection outside its range, or None.

        A term selection only judges predictors the history exercised: one made while the
        ship held one speed has no speed term, whatever the speed law, and keeps none until
        the next scheduled selection (``reselect_blocks`` later). When a measured block
        since the selection has a predictor the selected terms do not use outside the range
        the selection saw, widened by half its width on each side, the selection could not
        judge that predictor where the ship now is, and the terms are selected again (at
        most every ``reselect_blocks // 4`` blocks; the time trend is not watched, it leaves
        its range by design). Predictors in the terms extrapolate as their fit says.
        """
        if selection_range[j] is None or i - selected_at[j] < max(1, model.reselect_blocks // 4):
            return None
        since = rows_ok[rows_ok >= selected_at[j]]
        if since.size == 0:
            return None
        low, high = selection_range[j]
        margin = 0.5 * (high - low)
        watch = regional.copy()  # predictors outside the selected terms
        if terms_of[j] is not None:
            use_j, _, _, terms_j = terms_of[j]
            for term in terms_j:
                for c in term:
                    watch[use_j[c]] = False
        X = X_all[since][:, watch]
        with np.errstate(invalid="ignore"):
            outside = (X < (low - margin)[watch]) | (X > (high + margin)[watch])
        rows = since[outside.any(axis=1)]
        return int(rows[-1]) if rows.size else None

    def refit(j: int, i: int) -> MemoryModel | None:
        """Model of mode j from the measured blocks before grid row i."""
        lo = max(first, i - history_limit)
        y = meas[lo:i, j]
        case = None
        if labels is not None:  # the model of the current operating case
            in_case = case_training_mask(labels, slice(lo, i), i, min_train, np.isfinite(y))
            if in_case is not None:
                y = np.where(in_case, y, np.nan)
                case = labels[i]
        train_y[j] = y
        ok = np.isfinite(y)
        if ok.sum() < min_train:
            return None
        rows_ok = np.flatnonzero(ok) + lo
        newest_outside = left_selection_range(j, i, rows_ok)
        if (
            terms_of[j] is None
            or i - selected_at[j] >= model.reselect_blocks
            or (labels is not None and case != selected_case[j])
            or newest_outside is not None
        ):
            selected_case[j] = case
            # non-overlapping blocks only (75 % overlap: every 4th block shares no data), so
            # the F-tests of the selection do not count one correlated error several times;
            # the spacing keeps the newest block, or the newest block of a new operating
            # region when that is what triggered the selection
            anchor = i - 1 if newest_outside is None else newest_outside
            recent = rows_ok[rows_ok >= i - int(model.selection_blocks)]
            spaced = recent[(anchor - recent) % int(model.selection_stride) == 0]
            short = spaced.size < max(min_train, _MIN_SELECTION_ROWS)
            selection_options = model.stepwise_options
            if short and recent.size >= min_train and model.short_history_selection:
                # a short history (the first window): every measured block, main effects
                # only, and an entry p-value divided by the overlap (the F-tests count each
                # correlated error up to `stride` times)
                selection_options = {
                    "upper": "linear",
                    "p_enter": _SHORT_P_ENTER / int(model.selection_stride),
                    "p_remove": 2 * _SHORT_P_ENTER / int(model.selection_stride),
                    **dict(model.stepwise_options or {}),
                }
                few = False
            else:
                recent, few = spaced, short
            Xs = X_all[recent]
            selection_range[j] = None
            if Xs.shape[0]:
                with warnings.catch_warnings():  # an all-NaN column: no range, never "left"
                    warnings.simplefilter("ignore", RuntimeWarning)
                    selection_range[j] = (np.nanmin(Xs, axis=0), np.nanmax(Xs, axis=0))
            use, names = [], []
            for c, name in enumerate(columns):
                v = Xs[:, c]
                valid = np.isfinite(v)
                if valid.sum() < min_train:
                    continue
                if np.ptp(v[valid]) <= 1e-12 * max(1.0, float(np.abs(v[valid]).max())):
                    continue
                use.append(c)
                names.append(name)
            if use and not few:
                mean = np.nanmean(Xs[:, use], axis=0)
                scale = np.nanstd(Xs[:, use], axis=0, ddof=1)
                Z = pd.DataFrame((Xs[:, use] - mean) / scale, columns=names)
                try:
                    terms = select_terms(Z, meas[recent, j], selection_options)
                except Exception:  # singular selection: keep the last terms
                    terms = terms_of[j][3] if terms_of[j] is not None else ((),)
                terms_of[j] = (tuple(use), tuple(names), (mean, scale), terms)
            else:
                terms_of[j] = ((), (), (np.empty(0), np.empty(0)), ((),))
            selected_at[j] = i
        use, names, (mean, scale), terms = terms_of[j]
        if use:
            # z-scores from the newest history (not frozen at the selection): a speed first
            # seen after the selection is then inside the clipping range
            newest = X_all[rows_ok[rows_ok >= i - int(model.selection_blocks)]][:, list(use)]
            if newest.shape[0] >= 2 and np.isfinite(newest).all():  # the usual case: fast
                m_new = newest.mean(axis=0)
                s_new = newest.std(axis=0, ddof=1)
            else:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    m_new = np.nanmean(newest, axis=0)
                    s_new = np.nanstd(newest, axis=0, ddof=1)
            good = np.isfinite(s_new) & (s_new > 1e-12 * np.maximum(1.0, np.abs(m_new)))
            mean = np.where(good, m_new, mean)
            scale = np.where(good, s_new, scale)
        # the whole history slice (a view, no copy): the fits skip blocks without a
        # measurement themselves, so they use exactly the rows of rows_ok, in order
        age = (i - 1 - np.arange(lo, i)).astype(float)
        fitted = None
        if use and terms != ((),):
            fitted = fit_memory_model(
                X_all[lo:i],
                y,
                age,
                columns=use,
                names=names,
                terms=terms,
                mean=mean,
                scale=scale,
                memory_blocks=memory,
                limit=limit,
            )
        if fitted is None:
            fitted = constant_model(y, age, memory)
        return fitted

    def excitation_refit(fits: list, i: int) -> None:
        """κ pooled over the modes whose model has a speed term; refit those de-biased.

        κ is constrained to [0, ln 2 per kn]: excitation grows with speed (κ >= 0), and no
        realistic hull response more than doubles its power per knot. The shift κ σ_k² is
        capped at sqrt(n - 1) σ_k (a weighted mean of the block's n sub-windows cannot lie
        further from their mean). The refit on y - d κ σ² makes the state model a model of
        the time averages, not of the excitation-weighted history.
        """
        kappa[:] = 0.0
        if speed_var is None:
            return
        lo = max(first, i - history_limit)
        age = (i - 1 - np.arange(lo, i)).astype(float)
        stats = {}
        for j, fitted in enumerate(fits):
            if fitted is None or fitted.kind == "constant" or speed_col not in fitted.columns:
                continue
            found = _excitation_statistics(
                fitted,
                X_all[lo:i],
                train_y[j],
                age,
                speed_col,
                speed_var[lo:i],
                memory,
                limit,
            )
            if found is not None:
                stats[j] = found
        denominator = sum(d for _, d, _ in stats.values())
        if not denominator > 0:
            return
        # constrained least squares: the sign of the bias is known from physics, so no
        # significance gate (on the block-level regimes a 2-standard-error gate changed the
        # scores by less than 1 point; it only withheld the term on short histories)
        pooled = sum(n for n, _, _ in stats.values()) / denominator
        pooled = min(max(pooled, 0.0), _MAX_KAPPA)
        if pooled == 0.0:
            return
        shift = np.minimum(pooled * speed_var[lo:i], shift_cap[lo:i])
        for j, (_, _, slope) in stats.items():
            fits[j] = _debiased_refit(
                fits[j], X_all[lo:i], train_y[j], age, slope * shift, memory, limit
            )
            kappa[j] = pooled

    def seen_by_ssi(m: MemoryModel, rows_: np.ndarray, j: int, mean: np.ndarray):
        """Model of the measurement: the model at the excitation-weighted speed."""
        if kappa[j] <= 0 or speed_var is None:
            return mean
        X = X_all[rows_].copy()
        X[:, speed_col] += np.minimum(kappa[j] * speed_var[rows_], shift_cap[rows_])
        seen = m.predict(X, limit)[0]
        return np.where(np.isfinite(seen), seen, mean)

    def predict(m: MemoryModel, rows_: np.ndarray):
        X = X_all[rows_]
        mean, mvar = m.predict(X, limit)
        bad = ~np.isfinite(mean)
        if bad.any() and m.kind != "constant":
            level = float(m.coefficients[0])  # z = 0: the weighted centre of the data
            mean[bad], mvar[bad] = level, m.residual_variance
        dof = max(int(round(m.dof)), 1)
        t = t_cache.get(dof)
        if t is None:
            t = t_cache[dof] = t_quantile(1 - model.alpha / 2, dof)
        half = t * np.sqrt(m.residual_variance + mvar)
        return mean, mean - half, mean + half, bad, mvar

    # ---- windows
    i0 = first + train
    is_first = True
    previous_m = np.full(n_modes, np.nan)
    run = np.zeros(n_modes, dtype=np.int64)  # signed run of large innovations per mode
    while i0 <= (last if method == 2 else n_blocks - 1):
        f1 = min(i0 + horizon, (last + 1) if method == 2 else n_blocks)
        k_first = first if is_first else i0
        report = np.arange(k_first, f1)
        m_rows = np.full((f1 - k_first, n_modes), np.nan)  # model of the state
        z_rows = np.full((f1 - k_first, n_modes), np.nan)  # model of the measurement
        v_rows = np.zeros((f1 - k_first, n_modes))
        if is_first or method == 2:
            fits = [refit(j, i0) for j in range(n_modes)]
            excitation_refit(fits, i0)
            for j in range(n_modes):
                if fits[j] is not None:
                    current[j] = fits[j]
        for j in range(n_modes):
            m = current[j]
            if m is None:
                notes[f"mode {mode_labels[j]}: too few measured blocks, no forecast"] += 1
                continue
            # predictions from the row before (model switch) to the end of this window
            from_row = max(k_first - 1, first)
            mean, lower, upper, bad, mvar = predict(m, np.arange(from_row, f1))
            # what SSI sees (measurement equation); the state is the time average
            seen = seen_by_ssi(m, np.arange(from_row, f1), j, mean)
            implausible = np.isfinite(mean) & ~_plausible(mean, reference_hz[j])
            implausible |= np.isfinite(seen) & ~_plausible(seen, reference_hz[j])
            if implausible.any():
                level = float(np.nanmedian(meas[max(first, i0 - 36) : i0, j]))
                mean[implausible] = level
                seen[implausible] = level
                lower[implausible] = level - (upper - lower)[implausible] / 2
                upper[implausible] = level + (upper - lower)[implausible] / 2
            shift = from_row < k_first
            # c carries over unchanged: successive models are fitted on nearly the same
            # history, so the model error c is the same quantity before and after a refit
            sl = slice(1, None) if shift else slice(None)
            m_rows[:, j] = mean[sl]
            z_rows[:, j] = seen[sl]
            out["seen"][report, j] = seen[sl]
            v_rows[:, j] = mvar[sl]
            out["model"][report, j] = mean[sl]
            out["lower"][report, j] = lower[sl]
            out["upper"][report, j] = upper[sl]
            out_w0[report, j] = blocks[max(first, i0 - history_limit)]
            out_w1[report, j] = blocks[i0 - 1]
            out_phase[report, j] = np.where(report < first + train, 1, 2)
            for k in report[bad[sl]]:
                warn(k, j, "predictor NaN: model centre", "blocks with a needed predictor NaN")
            # noise from the out-of-sample residuals so far
            level_hz = float(abs(np.nanmedian(mean)))
            lo = max(first, i0 - int(noise.noise_blocks))
            r_hist = resid[lo:i0, j]
            if np.isfinite(r_hist).sum() == 0 and is_first:
                # first window: in-sample residuals (estimate_noise falls back to a
                # conservative prior when there are too few of them)
                insample = meas[first:i0, j] - out["seen"][first:i0, j]
                if np.isfinite(insample).sum() >= 3 * MIN_RESIDUALS:
                    # a long first window: the measurement noise from the in-sample
                    # residuals; their slow part is not evidence of model error (the fit
                    # absorbed it), the model's own uncertainty enters as s_m² instead
                    nz = estimate_noise(insample, level_hz)
                    nz = dataclasses.replace(
                        nz,
                        correction_variance=(MIN_CORRECTION_STD * level_hz) ** 2,
                        white_variance=nz.white_variance + nz.correction_variance,
                    )
                else:  # a short first window: scatter of the measurements themselves
                    zf = meas[first:i0, j]
                    zf = zf[np.isfinite(zf)]
                    nz = prior_noise(
                        level_hz,
                        float(np.var(np.diff(zf)) / 2.0) if zf.size >= 3 else None,
                        float(np.var(zf)) if zf.size >= 3 else None,
                    )
            elif (
                noise_of[j] is None
                or i0 - first < int(noise.noise_blocks)  # residual window still filling
                or i0 - noise_at[j] >= model.reselect_blocks
            ):  # then with the terms' schedule (the grid search is the costly part)
                nz = estimate_noise(r_hist, level_hz)
                noise_at[j] = i0
            else:
                nz = noise_of[j]
            noise_of[j] = nz
            if not started[j]:
                P[j] = _stationary(nz)
                state[j] = 0.0
                started[j] = True
            models_out.append(
                WindowModel(
                    mode=int(mode_labels[j]),
                    window_start_block=int(blocks[max(first, i0 - history_limit)]),
                    window_end_block=int(blocks[i0 - 1]),
                    kind="stepwise" if m.kind == "memory" else "constant",
                    terms=m.term_names(),
                    coefficients=dict(
                        zip(
                            ["(Intercept)", *m.term_names()],
                            map(float, m.coefficients),
                            strict=False,
                        )
                    ),
                    n_train=m.n_train,
                    rmse_hz=float(math.sqrt(m.residual_variance)),
                    measurement_variance=float(nz.error_variance + nz.white_variance),
                    process_variance=float(nz.correction_variance * (1 - nz.transition**2)),
                    normalisation={
                        n: (float(a), float(b))
                        for n, a, b in zip(m.names, m.mean, m.scale, strict=True)
                    },
                )
            )

        # typical cluster scatter per mode (RMS over the noise window)
        typical = np.full(n_modes, np.nan)
        if index is not None and noise.pole_scatter:
            lo = max(first, i0 - int(noise.noise_blocks))
            s = scatter[lo:i0]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                typical = np.sqrt(np.nanmean(s**2, axis=0))
        F = np.array(
            [[nz.transition, nz.error_correlation] if nz else [1.0, 0.0] for nz in noise_of]
        )
        q_c = np.array(
            [nz.correction_variance * (1 - nz.transition**2) if nz else 0.0 for nz in noise_of]
        )
        q_e = np.array(
            [nz.error_variance * (1 - nz.error_correlation**2) if nz else 0.0 for nz in noise_of]
        )
        r_v = np.array([nz.white_variance if nz else 1.0 for nz in noise_of])
        # no Huber weights while the noise levels are the prior's (nothing to judge by)
        huber = np.array(
            [noise.huber_sigma if nz and nz.n_residuals else np.inf for nz in noise_of]
        )
        have_model = np.array([c is not None for c in current])

        # ---- Kalman pass
        for r, k in enumerate(report):
            m_now = m_rows[r]
            z_now = z_rows[r]
            have = np.isfinite(m_now) & have_model
            z = np.full(n_modes, np.nan)
            scale = np.ones(n_modes)
            if option == "A" or k < first + train:
                z = tracked[k].copy()
                if index is not None and noise.pole_scatter:
                    for j in np.flatnonzero(np.isfinite(z) & have):
                        cl = cluster_around(index, k, z[j])
                        if cl is not None and cl.n_orders >= 3:
                            scatter[k, j] = cl.scatter_hz
                            scale[j] = scatter_scale(cl.scatter_hz, typical[j])
                        elif np.isfinite(typical[j]):
                            scale[j] = scatter_scale(math.nan, typical[j])
            else:
                # gate on the innovation standard deviation of the a-priori state
                prior_state = state * F
                Pp = P * (F[:, :, None] * F[:, None, :])
                S = Pp[:, 0, 0] + Pp[:, 1, 1] + 2 * Pp[:, 0, 1] + q_c + q_e + r_v
                prior_z = z_now + prior_state[:, 0] + prior_state[:, 1]
                # g = gate_sigma sqrt(S), at most max_gate x the frequency: a filter that has
                # lost confidence must not open its gate onto other modes and harmonics
                gate = np.minimum(
                    measurement.gate_sigma * np.sqrt(S), measurement.max_gate * np.abs(prior_z)
                )
                for j in np.flatnonzero(have):
                    choice = chooser.choose(k, j, prior_z[j], gate[j], damping_ref[j])
                    if choice is None:
                        continue
                    cl = choice.cluster
                    z[j] = cl.frequency_hz
                    out["order"][k, j] = cl.max_order
                    out["damping"][k, j] = cl.damping_ratio
                    out["mac"][k, j] = choice.mac
                    out["n_orders"][k, j] = cl.n_orders
                    out["scatter"][k, j] = cl.scatter_hz
                    out["min_order"][k, j] = cl.min_order
                    out["max_order"][k, j] = cl.max_order
                    scatter[k, j] = cl.scatter_hz
                    if noise.pole_scatter:
                        scale[j] = scatter_scale(cl.scatter_hz, typical[j])
                    if np.isfinite(cl.damping_ratio) and cl.damping_ratio > 0:
                        damping_ref[j] = (
                            math.exp(
                                0.95 * math.log(damping_ref[j]) + 0.05 * math.log(cl.damping_ratio)
                            )
                            if np.isfinite(damping_ref[j]) and damping_ref[j] > 0
                            else cl.damping_ratio
                        )
                    if choice.reacquired:
                        y = z[j] - prior_z[j]
                        P[j, 0, 0] = max(P[j, 0, 0], y * y / max(F[j, 0] ** 2, 1e-12))
                        warn(
                            k,
                            j,
                            f"track re-acquired: cluster at {z[j]:.4f} Hz outside the gate "
                            f"{prior_z[j]:.4f} ± {gate[j]:.4f} Hz",
                            "tracks re-acquired outside the gate (option B)",
                        )
            z[~have] = np.nan
            residual = z - z_now  # innovation about what SSI is expected to see
            Q = np.column_stack([q_c, q_e * scale])
            state, P, delta, nu = kalman_pass_step(
                state,
                P,
                F,
                Q,
                residual,
                r_v * scale,
                huber,
                model_variance=v_rows[r],
                previous_run=run,
                persist_blocks=max(_PERSIST_BLOCKS, overlap + 1),
            )
            exceed = np.where(np.abs(nu) > huber, np.sign(nu), 0).astype(np.int64)
            grow = (exceed != 0) & (np.sign(run) == exceed)
            run = np.where(np.isfinite(nu), np.where(grow, run + exceed, exceed), run)
            estimate = m_now + state[:, 0] + delta
            lost = have & ~_plausible(estimate, reference_hz)
            for j in np.flatnonzero(lost):
                state[j] = 0.0
                P[j] = _stationary(noise_of[j])
                estimate[j] = m_now[j]
                warn(
                    k,
                    j,
                    "Kalman track implausible: restarted at the model",
                    "Kalman tracks restarted at the model (estimate implausible)",
                )
            if k >= first + train:
                meas[k] = z
            resid[k] = residual
            out["ssi"][k] = z
            out["kalman"][k] = np.where(have, estimate, np.nan)
            out["std"][k] = np.where(have, np.sqrt(np.maximum(P[:, 0, 0], 0.0)), np.nan)
            gap = np.where(np.isfinite(z), 0, gap + have)
            for j in np.flatnonzero(have & (gap >= gap_warning_blocks)):
                warn(
                    k,
                    j,
                    f"no SSI estimate for {gap[j]} blocks: predict-only",
                    "rows in a long stretch without SSI estimates (predict-only)",
                )
            previous_m = np.where(have, m_now, previous_m)
        if method == 1 or f1 > last:
            break
        is_first = False
        i0 = f1

    _drop_unusable(out_phase, out["model"], out["kalman"], notes)
    table = _assemble(
        blocks,
        block_start,
        mode_labels,
        option,
        out_phase,
        out["ssi"],
        out["model"],
        out["lower"],
        out["upper"],
        out["kalman"],
        out["std"],
        out_w0,
        out_w1,
        out["order"],
        out["damping"],
        out["mac"],
        out_warning,
    )
    if option == "B":
        rows_, cols_ = np.nonzero(out_phase)
        extra = pd.DataFrame(
            {
                "block": blocks[rows_],
                "mode": mode_labels[cols_].astype(np.int64),
                "selected_n_orders": pd.array(
                    np.where(
                        np.isfinite(out["n_orders"][rows_, cols_]),
                        out["n_orders"][rows_, cols_],
                        np.nan,
                    )
                ).astype("Int64"),
                "selected_min_order": pd.array(
                    np.where(
                        np.isfinite(out["min_order"][rows_, cols_]),
                        out["min_order"][rows_, cols_],
                        np.nan,
                    )
                ).astype("Int64"),
                "selected_scatter_hz": out["scatter"][rows_, cols_],
            }
        )
        table = table.merge(extra, on=["block", "mode"], how="left", validate="one_to_one")
        table = table.rename(columns={"selected_model_order": "selected_max_order"})
        table["selected_model_order"] = table["selected_max_order"]
    messages = tuple(f"{kind} (x{count})" for kind, count in notes.items())
    for message in messages:
        warnings.warn(message, ForecastWarning, stacklevel=3)
    return ForecastResult(table=table, warnings=messages, models=tuple(models_out))
