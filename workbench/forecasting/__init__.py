"""Sliding-window regression forecasts of modal frequencies and Kalman blending with SSI.

* :class:`ForecastOptions` - every setting of a forecast, one object from the command
  line or the API down to the filter;
* :func:`sliding_forecast` - stepwise model per mode on a sliding training window,
  methods 1 (one long forecast) and 2 (refit every *horizon* blocks on Kalman estimates),
  measurement options A (tracked pole) and B (nearest stabilisation-diagram pole in a gate);
* :mod:`~workbench.forecasting.kalman` - scalar Kalman functions, steady state, trust -> Q;
* :func:`evaluate_against_truth` - cumulative absolute errors and improvements;
* :func:`run_temperature_experiment` - the 5-DOF temperature experiment
  (simulated by :mod:`workbench.simulate.experiment`).
"""

from .evaluate import ExperimentResult, evaluate_against_truth, run_temperature_experiment
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
from .options import ForecastOptions, NoiseOptions
from .results import ForecastResult, ForecastWarning, WindowModel
from .sliding import sliding_forecast

__all__ = [
    "ExperimentResult",
    "ForecastOptions",
    "ForecastResult",
    "ForecastWarning",
    "ModeKalmanBank",
    "NoiseOptions",
    "ScalarKalmanFilter",
    "ScalarUpdate",
    "SteadyState",
    "WindowModel",
    "evaluate_against_truth",
    "process_variance_for_gain",
    "relaxation_factor",
    "run_temperature_experiment",
    "scalar_kalman_predict",
    "scalar_kalman_update",
    "sliding_forecast",
    "steady_state",
]
