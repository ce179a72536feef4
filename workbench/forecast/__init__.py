"""Sliding-window regression forecasts of modal frequencies and Kalman blending with SSI."""

from .kalman import (
    ModeKalmanBank,
    ScalarKalmanFilter,
    ScalarUpdate,
    SteadyState,
    process_variance_for_gain,
    relaxation_factor,
    scalar_kalman_predict,
    scalar_kalman_update,
    steady_state,
)

__all__ = [
    "ModeKalmanBank",
    "ScalarKalmanFilter",
    "ScalarUpdate",
    "SteadyState",
    "process_variance_for_gain",
    "relaxation_factor",
    "scalar_kalman_predict",
    "scalar_kalman_update",
    "steady_state",
]
