"""Noise levels and innovation runs of the memory forecast's Kalman filter.

The noise model itself (covariance matching of out-of-sample residuals, the prior) is in
:mod:`workbench.forecasting.noise`; here: the noise of the first window, before any
out-of-sample residual exists; the filter's F, Q and R for all modes of a window; and the
signed runs of large innovations that tell a model error from an identification error.
Used by :func:`~workbench.forecasting.memory.forecast.memory_forecast`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..noise import MIN_CORRECTION_STD, MIN_RESIDUALS, NoiseModel, estimate_noise, prior_noise
from .kalman import transition_matrices

__all__ = ["filter_matrices", "first_window_noise", "run_after_hole", "update_run"]


def first_window_noise(
    measured: np.ndarray, seen: np.ndarray, level_hz: float, error_segments: int = 0
) -> NoiseModel:
    """Noise of one mode from the first window's in-sample residuals.

    Parameters
    ----------
    measured : ndarray
        The first window's measurements of the mode (NaN: none). [Hz]
    seen : ndarray
        The model's prediction of those measurements. [Hz]
    level_hz : float
        Typical frequency of the mode. [Hz]
    error_segments : int
        The identification error's shape (:func:`~workbench.forecasting.noise.estimate_noise`).
    """
    # first window: in-sample residuals (estimate_noise falls back to a
    # conservative prior when there are too few of them)
    insample = measured - seen
    if np.isfinite(insample).sum() >= 3 * MIN_RESIDUALS:
        # a long first window: the measurement noise from the in-sample
        # residuals; their slow part is not evidence of model error (the fit
        # absorbed it), the model's own uncertainty enters as s_m² instead
        nz = estimate_noise(insample, level_hz, error_segments=error_segments)
        return dataclasses.replace(
            nz,
            correction_variance=(MIN_CORRECTION_STD * level_hz) ** 2,
            white_variance=nz.white_variance + nz.correction_variance,
        )
    # a short first window: scatter of the measurements themselves
    zf = measured[np.isfinite(measured)]
    return prior_noise(
        level_hz,
        float(np.var(np.diff(zf)) / 2.0) if zf.size >= 3 else None,
        float(np.var(zf)) if zf.size >= 3 else None,
    )


def filter_matrices(noise_of: Sequence[NoiseModel | None], huber_sigma: float, states: int = 2):
    """F, the diagonal of Q (model part and identification part), R and the Huber
    threshold of every mode's filter of *states* states
    (:func:`~workbench.forecasting.memory.kalman.transition_matrices`).

    A mode without a noise model (no model yet) gets F = diag(1, 0, ...), Q = 0, R = 1.

    Returns
    -------
    F (n, s, s), q_c (n, s), q_e (n, s), r_v (n,), huber (n,)
    """
    parts = [transition_matrices(nz, states) for nz in noise_of]
    F = np.array([p[0] for p in parts]).reshape(len(parts), states, states)
    q_c = np.array([p[1] for p in parts]).reshape(len(parts), states)
    q_e = np.array([p[2] for p in parts]).reshape(len(parts), states)
    r_v = np.array([nz.white_variance if nz else 1.0 for nz in noise_of])
    # no Huber weights while the noise levels are the prior's (nothing to judge by)
    huber = np.array([huber_sigma if nz and nz.n_residuals else np.inf for nz in noise_of])
    return F, q_c, q_e, r_v, huber


def run_after_hole(run: np.ndarray, innovation: np.ndarray, persist_blocks: int) -> np.ndarray:
    """The runs a filter's update judges *innovation* (measurement less prediction) by after a
    hole in the record: each measured mode's run as if already ``persist_blocks`` - 1 long in
    its innovation's sign, so that a large one is taken as the stale state's error, not as an
    outlier (:meth:`~workbench.forecasting.memory.forecast.MemoryRun._run_after_hole`); *run*
    where there is no innovation."""
    stale = np.isfinite(innovation) & (innovation != 0)
    return np.where(stale, np.sign(innovation).astype(np.int64) * (persist_blocks - 1), run)


def update_run(run: np.ndarray, normalised: np.ndarray, huber: np.ndarray) -> np.ndarray:
    """Signed runs of consecutive large innovations after one block.

    A normalised innovation beyond *huber* extends a run of its sign or starts a new one;
    one within resets the run to 0; a block without a measurement (NaN) leaves it.
    """
    exceed = np.where(np.abs(normalised) > huber, np.sign(normalised), 0).astype(np.int64)
    grow = (exceed != 0) & (np.sign(run) == exceed)
    return np.where(np.isfinite(normalised), np.where(grow, run + exceed, exceed), run)
