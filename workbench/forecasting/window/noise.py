"""Noise levels of the reference forecast's Kalman filter for one window and mode.

Step 2 of :func:`~workbench.forecasting.window.forecast.window_forecast`. R is the scatter of the
window's measurements about the window model, its white part:
σ² = (1.4826 MAD(Δr))² / 2 (differencing removes the slowly varying model error, the MAD
the odd wrong pole; plain residual variance for fewer values). Q follows from the hand-set
trust (the steady-state gain, :func:`~workbench.forecasting.kalman.process_variance_for_gain`)
or, with ``trust=None``, from the model's own mean-prediction variance.
"""

from __future__ import annotations

import numpy as np

from ..fitted_model import (
    _DEFAULT_RELATIVE_STD,
    _MIN_DIFFERENCES,
    _MIN_RELATIVE_STD,
    _Model,
    _white_scatter_variance,
)
from ..kalman import process_variance_for_gain

__all__ = ["window_noise_levels"]


def window_noise_levels(
    run, j: int, model: _Model, mean_p: np.ndarray, mvar: np.ndarray, w0: int, w1: int
) -> tuple[float, float]:
    """(R, Q) of mode *j* for the window [w0, w1) with predictions *mean_p* from w0. [Hz²]"""
    n_tr = w1 - w0
    m_train = mean_p[:n_tr]
    resid = run.measured[w0:w1, j] - m_train
    resid = resid[np.isfinite(resid)]
    dof = resid.size - model.n_params
    level_hz = float(np.nanmean(np.abs(mean_p)))
    if resid.size >= _MIN_DIFFERENCES + 1:
        r = _white_scatter_variance(resid)
    elif dof >= 2:
        r = float(resid @ resid) / dof
    elif np.isfinite(run.last_r[j]):
        r = float(run.last_r[j])
    elif np.isfinite(model.rmse) and model.rmse > 0:
        r = model.rmse**2
    else:
        r = (_DEFAULT_RELATIVE_STD * level_hz) ** 2
    r = max(r, (_MIN_RELATIVE_STD * level_hz) ** 2)
    run.last_r[j] = r
    # Q: from trust, or the model's own mean-prediction variance
    phi = run.phi
    if run.trust is not None:
        q = process_variance_for_gain(float(run.trust), r, transition=phi)
    else:
        s2 = float(np.nanmean(mvar[n_tr:])) if np.isfinite(mvar[n_tr:]).any() else r
        q = max(s2, (_MIN_RELATIVE_STD * level_hz) ** 2) * (1.0 - phi * phi)
    return r, q
