"""Sliding-window regression forecasts of modal frequencies and Kalman blending with SSI.

Laid out by responsibility:

* :mod:`.options` - :class:`ForecastOptions`, every setting of a forecast, one object from
  the command line or the API down to the filter, with the defaults;
* :mod:`.sliding` - :func:`sliding_forecast`, the run of each measurement option with the
  window or the memory model (the method in its docstring);
* :mod:`.window` - the reference model (stepwise fit on the last *train_blocks* blocks,
  hand-set trust): model, noise levels, Kalman pass;
* :mod:`.memory` - the default model (stepwise terms, coefficients over the history with
  forgetting, noise levels from the data): terms, excitation bias, noise, option B's
  chooser, Kalman step, output table; the safeguards :mod:`.noise`,
  :mod:`.innovation_consistency` and :mod:`.model_trust`;
* :mod:`.kalman` - scalar Kalman functions, steady state, trust -> Q;
* :mod:`.measurement` - option B's pole clusters (pole index, cluster chooser);
  :mod:`.pole_selection` and :mod:`.shape_reference` - mode-shape checks;
* :mod:`.results` - :class:`ForecastResult` (what a forecast returns, the library's and
  the forecast stage's: table, warnings, window models, ``summary()``, ``plot()``,
  ``evaluate()``, ``save()``), :class:`ForecastWarning`, :class:`WindowModel`;
* :mod:`.plot` - the forecast figure of a mode (matplotlib, imported when drawing);
* :mod:`.evaluate` - a forecast against the truth: :func:`evaluate_against_truth`
  (cumulative absolute errors and improvements), the pairing of tracked and true mode
  labels, :class:`~.evaluate.EvaluateResult` (the evaluate stage's result);
* :mod:`.experiment` - :func:`run_temperature_experiment` (the 5-DOF temperature
  experiment, simulated by :mod:`workbench.simulate.experiment`).
"""

from typing import TYPE_CHECKING

from .._lazy import attach

#: Public names and the module defining each, imported on first use (PEP 562): importing
#: :mod:`.options` for a command's defaults does not import the forecast machinery (the
#: stepwise search, the simulation of the experiment: 0.15 s of every command's start).
_EXPORTS = {
    "evaluate_against_truth": ".evaluate",
    "ExperimentResult": ".experiment",
    "run_temperature_experiment": ".experiment",
    "ModeKalmanBank": ".kalman",
    "ScalarKalmanFilter": ".kalman",
    "ScalarUpdate": ".kalman",
    "SteadyState": ".kalman",
    "process_variance_for_gain": ".kalman",
    "relaxation_factor": ".kalman",
    "scalar_kalman_predict": ".kalman",
    "scalar_kalman_update": ".kalman",
    "steady_state": ".kalman",
    "ForecastOptions": ".options",
    "NoiseOptions": ".options",
    "ForecastResult": ".results",
    "ForecastWarning": ".results",
    "WindowModel": ".results",
    "sliding_forecast": ".sliding",
}

if TYPE_CHECKING:
    from .evaluate import evaluate_against_truth
    from .experiment import ExperimentResult, run_temperature_experiment
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


__getattr__, __dir__ = attach(__name__, _EXPORTS, globals())


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
