"""Kalman pass of the reference forecast over the rows one window reports.

Step 3 of :func:`~workbench.forecasting.window.forecast.window_forecast`, all modes together
(:class:`~workbench.forecasting.kalman.ModeKalmanBank`): a-priori x⁻_k = m_k + φ (x⁺_{k-1} -
m_{k-1}); the measurement (option A: the tracked pole; option B: the pole chosen inside the
gate, :class:`~workbench.forecasting.pole_selection._PoleSelector`); the update; a track that leaves
the plausibility band restarts at the model. Then (method 2) the next windows' targets.
"""

from __future__ import annotations

import numpy as np

from ..fitted_model import _plausible

__all__ = ["kalman_pass", "next_targets"]


def kalman_pass(run, k_first: int, f1: int) -> None:
    """Filter rows [k_first, f1) of *run* (outputs written into *run*)."""
    bank, phi = run.bank, run.phi
    for i in range(k_first, f1):
        model_now = run.out_model[i]
        have = np.isfinite(model_now)
        # B u = m_k - φ m_{k-1}; a mode without m_{k-1} (no model in the last window)
        # restarts its correction from zero: B u = m_k - φ x⁺_{k-1}, so x⁻ = m_k
        control = np.where(
            np.isfinite(run.previous_model_value),
            model_now - phi * run.previous_model_value,
            model_now - phi * bank.state,
        )
        bank.predict(control, active=have & run.started)
        fresh = have & ~run.started
        if fresh.any():
            idx = np.flatnonzero(fresh)
            bank.initialise(idx, model_now[idx])
            run.started[idx] = True
        prior_x, prior_p = bank.state.copy(), bank.variance.copy()
        if run.option == "A":
            z = run.tracked[i].copy()
        else:
            z = _pole_cluster_measurement(run, i, prior_x, prior_p, have)
        z[~have] = np.nan
        bank.update(z)
        lost = have & run.started & ~_plausible(bank.state, run.reference_hz)
        if lost.any():  # track lost (model or measurements far off): restart at model
            idx = np.flatnonzero(lost)
            bank.initialise(idx, model_now[idx])
            for j in idx:
                run.warn_rows(
                    [i],
                    j,
                    "Kalman track implausible: restarted at the model",
                    "Kalman tracks restarted at the model (estimate implausible)",
                )
        run.measured[i] = z
        run.out_ssi[i] = z
        run.out_kalman[i] = np.where(have, bank.state, np.nan)
        run.out_std[i] = np.where(have, np.sqrt(np.maximum(bank.variance, 0.0)), np.nan)
        has_z = np.isfinite(z)
        run.gap = np.where(has_z, 0, run.gap + have)
        for j in np.flatnonzero(have & (run.gap >= run.gap_warning_blocks)):
            run.warn_rows(
                [i],
                j,
                f"no SSI estimate for {run.gap[j]} blocks: predict-only",
                "rows in a long stretch without SSI estimates (predict-only)",
            )
        run.previous_model_value = np.where(have, model_now, run.previous_model_value)


def _pole_cluster_measurement(run, i, prior_x, prior_p, have) -> np.ndarray:
    """Option B: the pole chosen in the gate g = gate_sigma sqrt(P⁻ + R) (or re-acquired)."""
    bank = run.bank
    with np.errstate(invalid="ignore"):
        gate = run.gate_sigma * np.sqrt(prior_p + bank.measurement_variance)
    choice = run.selector.select(i, prior_x, gate, have & run.started)
    z = choice.frequency
    run.out_order[i], run.out_damping[i], run.out_mac[i] = (
        choice.order,
        choice.damping,
        choice.mac,
    )
    for j in np.flatnonzero(choice.no_reference):
        run.warn_rows(
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
            run.warn_rows(
                [i],
                j,
                f"track re-acquired: pole at {z[j]:.4f} Hz (MAC {choice.mac[j]:.3f}) "
                f"outside the gate {prior_x[j]:.4f} ± {gate[j]:.4f} Hz",
                "tracks re-acquired outside the gate (option B: mode seen only "
                f"outside the gate for {run.reacquire_blocks} block(s))",
            )
    return z


def next_targets(run, f0: int, f1: int) -> None:
    """Method 2: the Kalman estimates of rows [f0, f1) become training targets.

    Only blocks with a measurement: predict-only blocks carry no new information
    (re-training on them would feed the model its own extrapolation); modes not started
    keep their tracked values.
    """
    kalman_rows = run.out_kalman[f0:f1]
    run.targets[f0:f1] = np.where(
        np.isfinite(kalman_rows),
        np.where(np.isfinite(run.measured[f0:f1]), kalman_rows, np.nan),
        run.tracked[f0:f1],
    )
