"""Forecast with a model that has memory, noise from the data and an AR(1) measurement error.

The steps, each in its own module:

1. window model - :mod:`workbench.forecasting.memory` (stepwise terms, exponentially
   weighted least squares over the history, refit every *horizon* blocks);
2. noise estimation - :mod:`workbench.forecasting.noise` (covariance matching of the
   residuals, with the model error at least what the out-of-sample residuals show beyond
   the measurement noise: :func:`~workbench.forecasting.noise.model_error_floor`), and the
   safeguard :mod:`workbench.forecasting.innovation_consistency` (model variance added while
   the filter's innovations are larger or more one-sided than its noise model says); the
   identification error is capped at what the residuals' second difference across blocks
   that share no data allows (:func:`~workbench.forecasting.noise.identification_error_bound`),
   so a model error of a few blocks' time constant is not taken for SSI scatter;
3. measurement choice - :mod:`workbench.forecasting.measurement` (tracked pole or consistent
   pole cluster, per-block scatter);
4. Kalman pass - :func:`~workbench.forecasting.memory_kalman.kalman_pass_step`;
5. guard - :mod:`workbench.forecasting.model_trust`: the blend is weighed against a filter
   that does not use the model by how well each predicts the measurements out of sample;
   while the model does not explain a mode (an unrecorded change: fuel, ballast, ice) the
   estimate follows the model-free filter, i.e. SSI. The weight is the forecast table's
   ``model_probability``, and the run notes say when a mode's model stopped explaining it.

:func:`memory_forecast` below runs the windows and the Kalman pass over their rows; each
mode's term selection, refits and predictions are in :mod:`workbench.forecasting.memory_terms`,
the excitation bias (κ) in :mod:`workbench.forecasting.memory_excitation`, the first window's
noise, the filter matrices and the runs of large innovations in
:mod:`workbench.forecasting.memory_noise`, option B's chooser in
:mod:`workbench.forecasting.memory_poles`, the output table in
:mod:`workbench.forecasting.memory_output`.

Kalman model per mode, with m_k the model's prediction and z_k the block's SSI estimate:

.. math::

    x_k = m_k + c_k, \\quad z_k = x_k + e_k + v_k, \\quad
    \\begin{bmatrix} c_k \\\\ e_k \\end{bmatrix} =
    \\begin{bmatrix} φ & 0 \\\\ 0 & ρ \\end{bmatrix}
    \\begin{bmatrix} c_{k-1} \\\\ e_{k-1} \\end{bmatrix} + w_k,

Q = diag(σ_c²(1 - φ²), σ_e²(1 - ρ²) s_k), R_k = σ_v² s_k, H = [1 1], with s_k the block's
measurement scale (pole scatter across model orders). With the excitation term
(:mod:`workbench.forecasting.excitation`) the measurement is about the model at the
excitation-weighted speed: z_k = m̃_k + c_k + e_k + v_k, m̃_k = m(v̄_k + κ σ²_{v,k}, ...),
while the state stays x_k = m_k + c_k: SSI's bias in a block whose speed changes goes into
the measurement equation, not into the estimate. The identification error e is a state
because 75 %-overlapping blocks share their data: a white R would count the same error
several times. The blended estimate is x̂ = m + ĉ.
"""

from __future__ import annotations

import math
import warnings
from collections import Counter

import numpy as np
import pandas as pd

from .excitation import sub_windows_per_block
from .innovation_consistency import MIN_BLOCKS, InnovationConsistency
from .measurement import PoleIndex, cluster_around, nearer_to_another_mode, scatter_scale
from .memory import MemoryModel
from .memory_excitation import excitation_bias
from .memory_kalman import kalman_pass_step, stationary_covariance
from .memory_noise import filter_matrices, first_window_noise, update_run
from .memory_output import OUTPUT_ARRAYS, assemble_table
from .memory_poles import option_b_chooser
from .memory_terms import MemoryRefits
from .model_trust import ModelTrust
from .noise import NoiseModel, estimate_noise, model_error_floor
from .options import MeasurementOptions, ModelOptions, NoiseOptions
from .predictor_grid import mode_matrix, modes_to_forecast, predictor_matrix

__all__ = ["kalman_pass_step", "memory_forecast"]

#: Fewest consecutive large innovations of one sign that mean the model is off (at least
#: one more than the blocks sharing data with the first: one corrupted stretch of data is
#: in all the blocks that overlap it).
_PERSIST_BLOCKS = 3
#: Oldest history a refit looks at, in forgetting time constants (weight e^-6 beyond).
_HISTORY_CONSTANTS = 6.0


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
    """Forecast with :mod:`memory <workbench.forecasting.memory>` models (see module docs).

    Called by :func:`~workbench.forecasting.sliding_forecast` for ``model="memory"``;
    returns a :class:`~workbench.forecasting.ForecastResult`.
    """
    from .fitted_model import _plausible
    from .sliding import ForecastResult, ForecastWarning, WindowModel

    option = measurement.option
    notes: Counter[str] = Counter()
    grid, blocks, block_start, columns, X_all = predictor_matrix(
        predictors, model.predictor_columns
    )
    n_blocks = blocks.size
    if model.time_trend and model.predictor_columns is None:  # explicit columns: as given
        # slow drifts no log records (fuel burn, ballast): a trend term with memory
        # block centres: the same hours as the starts for blocks of one length, the
        # blocks' own times for blocks of varying length (--block-minutes auto)
        start_ns = pd.to_datetime(grid["block_start"], utc=True).astype("int64").to_numpy()
        if "block_end" in grid.columns:
            end_ns = pd.to_datetime(grid["block_end"], utc=True).astype("int64").to_numpy()
            start_ns = start_ns + (end_ns - start_ns) // 2
        hours = (start_ns - start_ns[0]) / 3.6e12
        X_all = np.column_stack([X_all, hours.astype(float)])
        columns = [*columns, "elapsed_hours"]
    # blocks that share data with a block: its identification error (an ice impact, a
    # badly excited stretch) is in all of them, so a run of large innovations is evidence
    # that the model is off only when it reaches a block that shares no data with the first
    overlap = sub_windows_per_block(grid) or 1
    # identification errors of blocks this far apart are independent (None: not known, no
    # cap on the identification error's variance, :func:`~.noise.estimate_noise`)
    independent_lag = sub_windows_per_block(grid)
    mode_labels = modes_to_forecast(modal, modes)
    n_modes = mode_labels.size
    tracked = mode_matrix(modal, blocks, mode_labels, "frequency_hz")
    # the combined modal model's uncertainty per block (identify --cross-check), when the
    # tracked table carries it: the block's measurement scatter instead of the pole cluster's
    combined_std = (
        mode_matrix(modal, blocks, mode_labels, "combined_frequency_std_hz")
        if "combined_frequency_std_hz" in modal.columns
        else None
    )
    tracked_damping = (
        mode_matrix(modal, blocks, mode_labels, "damping_ratio")
        if "damping_ratio" in modal.columns
        else np.full((n_blocks, n_modes), np.nan)
    )

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

    bias = excitation_bias(
        grid,
        X_all,
        columns,
        enabled=model.excitation_bias,
        n_modes=n_modes,
        first=first,
        history_limit=history_limit,
        memory=memory,
        limit=limit,
    )

    # ---- poles: per-block scatter and option B's chooser
    index = PoleIndex(poles, blocks) if poles is not None else None
    chooser = None
    if option == "B":
        if index is None:
            raise ValueError("option='B' needs poles (the stabilisation diagrams)")
        chooser = option_b_chooser(poles, modal, blocks, mode_labels, index, measurement, notes)

    shape = (n_blocks, n_modes)
    out_phase = np.zeros(shape, dtype=np.int8)
    out = {k: np.full(shape, np.nan) for k in OUTPUT_ARRAYS}
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
    labels = None
    if cases is not None:
        from workbench.stats import case_labels

        labels = case_labels(grid, cases).to_numpy()
    refits = MemoryRefits(
        model, X_all, columns, meas, labels, first, min_train, history_limit, memory, limit
    )
    current: list[MemoryModel | None] = [None] * n_modes
    noise_of: list[NoiseModel | None] = [None] * n_modes
    noise_at = np.full(n_modes, -(10**9))  # grid row of each mode's last noise estimate
    state = np.zeros((n_modes, 2))
    P = np.zeros((n_modes, 2, 2))
    started = np.zeros(n_modes, dtype=bool)
    gap = np.zeros(n_modes, dtype=np.int64)
    models_out = []

    # guard: the probability that the model explains each mode, against a model-free filter
    trust = (
        ModelTrust(
            n_modes, float(noise.huber_sigma), persist_blocks=max(_PERSIST_BLOCKS, overlap + 1)
        )
        if noise.model_trust
        else None
    )
    explained_lost = np.zeros(n_modes, dtype=np.int64)  # first block below 0.5, + 1
    # a mode's model explains it once its probability reached 0.5 on unseen blocks; only
    # then is a fall below 0.5 news (the prior starts low, :data:`~workbench.forecasting.model_trust.PRIOR_PROBABILITY`)
    explained = np.zeros(n_modes, dtype=bool)
    forecast_blocks = np.zeros(n_modes, dtype=np.int64)

    # ---- windows
    i0 = first + train
    is_first = True
    run = np.zeros(n_modes, dtype=np.int64)  # signed run of large innovations per mode
    # safeguard: model variance added where the filter's innovations are inconsistent
    consistency = InnovationConsistency(
        n_blocks,
        n_modes,
        float(noise.huber_sigma),
        window_blocks=max(int(noise.consistency_blocks), MIN_BLOCKS),
    )
    while i0 <= (last if method == 2 else n_blocks - 1):
        f1 = min(i0 + horizon, (last + 1) if method == 2 else n_blocks)
        k_first = first if is_first else i0
        report = np.arange(k_first, f1)
        m_rows = np.full((f1 - k_first, n_modes), np.nan)  # model of the state
        z_rows = np.full((f1 - k_first, n_modes), np.nan)  # model of the measurement
        v_rows = np.zeros((f1 - k_first, n_modes))
        if is_first or method == 2:
            fits = [refits.refit(j, i0) for j in range(n_modes)]
            bias.refit(fits, i0, refits.train_y)
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
            mean, lower, upper, bad, mvar = refits.predict(m, np.arange(from_row, f1))
            # what SSI sees (measurement equation); the state is the time average
            seen = bias.seen_by_ssi(m, np.arange(from_row, f1), j, mean)
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
                nz = first_window_noise(meas[first:i0, j], out["seen"][first:i0, j], level_hz)
            elif (
                noise_of[j] is None
                or i0 - first < int(noise.noise_blocks)  # residual window still filling
                or i0 - noise_at[j] >= model.reselect_blocks
            ):  # then with the terms' schedule (the grid search is the costly part)
                nz = estimate_noise(r_hist, level_hz, correlated_lags=independent_lag)
                if nz.n_residuals:  # fitted, not the prior: no less model error than shown
                    nz = model_error_floor(nz, resid[max(lo, first + train) : i0, j])
                noise_at[j] = i0
            else:
                nz = noise_of[j]
            noise_of[j] = nz
            if not started[j]:
                P[j] = stationary_covariance(nz)
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
        if (index is not None or combined_std is not None) and noise.pole_scatter:
            lo = max(first, i0 - int(noise.noise_blocks))
            s = scatter[lo:i0]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                typical = np.sqrt(np.nanmean(s**2, axis=0))
        F, q_c, q_e, r_v, huber = filter_matrices(noise_of, noise.huber_sigma)
        added_variance = (
            consistency.update(i0).copy() if noise.consistency_blocks else np.zeros(n_modes)
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
                if (index is not None or combined_std is not None) and noise.pole_scatter:
                    for j in np.flatnonzero(np.isfinite(z) & have):
                        if combined_std is not None and np.isfinite(combined_std[k, j]):
                            scatter[k, j] = combined_std[k, j]
                            scale[j] = scatter_scale(combined_std[k, j], typical[j])
                            continue
                        if index is None:
                            continue
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
                # without shapes a cluster in the gate may be a close neighbour's column:
                # each mode's anchor is its tracked pole of the block (else its prior)
                anchors = np.where(np.isfinite(tracked[k]), tracked[k], prior_z)
                for j in np.flatnonzero(have):
                    choice = chooser.choose(k, j, prior_z[j], gate[j], damping_ref[j])
                    if choice is None:
                        continue
                    cl = choice.cluster
                    if chooser.shape_mac is None and nearer_to_another_mode(
                        cl.frequency_hz, j, anchors
                    ):
                        other = int(np.nanargmin(np.abs(np.delete(anchors, j) - cl.frequency_hz)))
                        other += other >= j
                        warn(
                            k,
                            j,
                            f"option B pole {cl.frequency_hz:.4f} Hz nearer to mode "
                            f"{mode_labels[other]} than to this mode's "
                            f"{anchors[j]:.4f} Hz: "
                            + ("tracked pole used" if np.isfinite(tracked[k, j]) else "refused"),
                            "option B poles nearer to another mode (tracked pole used or "
                            "predict-only)",
                        )
                        if not np.isfinite(tracked[k, j]):
                            continue
                        z[j] = tracked[k, j]
                        cl = cluster_around(index, k, z[j])
                        if cl is not None and cl.n_orders >= 3:
                            scatter[k, j] = cl.scatter_hz
                            if noise.pole_scatter:
                                scale[j] = scatter_scale(cl.scatter_hz, typical[j])
                        elif np.isfinite(typical[j]) and noise.pole_scatter:
                            scale[j] = scatter_scale(math.nan, typical[j])
                        continue
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
                    if choice.outside_gate:  # measured, Huber-weighted; no reset
                        warn(
                            k,
                            j,
                            f"measured outside the gate: column at {z[j]:.4f} Hz, gate "
                            f"{prior_z[j]:.4f} ± {gate[j]:.4f} Hz",
                            "option B measurements outside the gate",
                        )
            z[~have] = np.nan
            residual = z - z_now  # innovation about what SSI is expected to see
            Q = np.column_stack([q_c, q_e * scale])
            state, P, delta, nu, innovation_variance = kalman_pass_step(
                state,
                P,
                F,
                Q,
                residual,
                r_v * scale,
                huber,
                model_variance=v_rows[r] + added_variance,
                previous_run=run,
                persist_blocks=max(_PERSIST_BLOCKS, overlap + 1),
            )
            if k >= first + train:  # out of sample: the model had not seen block k
                consistency.record(k, nu, innovation_variance, residual)
            run = update_run(run, nu, huber)
            estimate = m_now + state[:, 0] + delta
            lost = have & ~_plausible(estimate, reference_hz)
            for j in np.flatnonzero(lost):
                state[j] = 0.0
                P[j] = stationary_covariance(noise_of[j])
                estimate[j] = m_now[j]
                warn(
                    k,
                    j,
                    "Kalman track implausible: restarted at the model",
                    "Kalman tracks restarted at the model (estimate implausible)",
                )
            variance = np.maximum(P[:, 0, 0], 0.0)
            if trust is not None:
                out_of_sample = np.full(n_modes, k >= first + train)
                trust.step(
                    np.where(have, z, np.nan),
                    F[:, 1],
                    q_e * scale / np.maximum(1 - F[:, 1] ** 2, 1e-12),
                    r_v * scale,
                    nu,
                    innovation_variance,
                    out_of_sample & ~lost,
                )
                estimate, variance = trust.combine(estimate, variance)
                out["probability"][k] = np.where(have, trust.probability, np.nan)
                for j in np.flatnonzero(have & out_of_sample):
                    forecast_blocks[j] += 1
                    below = trust.probability[j] < 0.5
                    explained[j] |= not below
                    if below and explained[j] and not explained_lost[j]:
                        explained_lost[j] = int(blocks[k]) + 1
                    if below and explained[j]:
                        notes[
                            f"mode {mode_labels[j]}: the model stopped explaining it (model "
                            f"probability below 0.5, first at block {explained_lost[j] - 1}; "
                            "blocks below, the estimate follows SSI)"
                        ] += 1
            if k >= first + train:
                meas[k] = z
            resid[k] = residual
            out["ssi"][k] = z
            out["kalman"][k] = np.where(have, estimate, np.nan)
            out["std"][k] = np.where(have, np.sqrt(variance), np.nan)
            gap = np.where(np.isfinite(z), 0, gap + have)
            for j in np.flatnonzero(have & (gap >= gap_warning_blocks)):
                warn(
                    k,
                    j,
                    f"no SSI estimate for {gap[j]} blocks: predict-only",
                    "rows in a long stretch without SSI estimates (predict-only)",
                )
        if method == 1 or f1 > last:
            break
        is_first = False
        i0 = f1

    for j in np.flatnonzero((forecast_blocks > 0) & ~explained):
        notes[
            f"mode {mode_labels[j]}: the model never explained it well enough to be leaned on "
            f"(model probability below 0.5 in all {forecast_blocks[j]} forecast blocks; the "
            "estimate follows SSI)"
        ] += 1
    table = assemble_table(
        blocks,
        block_start,
        mode_labels,
        option,
        out_phase,
        out,
        out_w0,
        out_w1,
        out_warning,
        notes,
    )
    messages = tuple(f"{kind} (x{count})" for kind, count in notes.items())
    for message in messages:
        warnings.warn(message, ForecastWarning, stacklevel=3)
    return ForecastResult(table=table, warnings=messages, models=tuple(models_out))
