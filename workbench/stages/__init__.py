"""The user's jobs, one stage function each, in one place.

=============  ===========================  ====================================  ===================
stage          module                       takes                                 returns
=============  ===========================  ====================================  ===================
``identify``   :mod:`.identification`       acceleration files, IdentifyOptions   IdentifyResult
``track``      :mod:`.tracking`             selected modes, TrackingOptions       TrackResult
``correlate``  :mod:`.correlation`          modal + predictors, CorrelateOptions  CorrelateResult
``fit``        :mod:`.fitting`              modal + predictors, FitOptions        FitResult
``forecast``   :mod:`.forecasting`          modal + predictors, ForecastOptions   ForecastResult
``evaluate``   :mod:`.evaluation`           forecast + true modal table           EvaluateResult
``health``     :mod:`.structural_health`    forecast, HealthOptions               HealthResult
=============  ===========================  ====================================  ===================

Modules are named by noun so that ``workbench.stages.track`` is always the function (a
submodule of the same name would shadow it once imported).

Every result has ``.table`` (a DataFrame following its contract), ``.summary()``, an HTML
view for notebooks and ``.save(dir)`` (atomic writes, contract formats); ``.plot()`` where a
figure fits. The CLI parses arguments and calls these; the demo calls them too. Importing
this package is light: each stage module is imported on first use.

A result leads to the next stage with the same call on its table:
``identify(...).track()`` (keeping the poles for forecast option B), then
``TrackResult.predictors(dship)``, ``.correlate``, ``.fit``, ``.forecast``, and
``ForecastResult.evaluate(truth)``.
"""

from __future__ import annotations

import importlib

#: Public name -> module of this package that defines it (or a dotted module path).
_EXPORTS = {
    "identify": "identification",
    "IdentifyOptions": "identification",
    "HarmonicOptions": "identification",
    "IdentifyResult": "identification",
    "track": "tracking",
    "TrackResult": "tracking",
    "TrackingOptions": "tracking",
    "correlate": "correlation",
    "CorrelateOptions": "correlation",
    "CorrelateResult": "correlation",
    "read_correlation": "correlation",
    "fit": "fitting",
    "FitOptions": "fitting",
    "FitResult": "fitting",
    "ModeResults": "fitting",
    "PredictionResults": "fitting",
    "read_fit": "fitting",
    "FitDataMissing": "fitting",
    "Summary": "workbench.results",
    "forecast": "forecasting",
    "ForecastOptions": "forecasting",
    "ForecastResult": "forecasting",
    "forecast_modes": "forecasting",
    "evaluate": "evaluation",
    "EvaluateResult": "evaluation",
    "pair_with_truth": "workbench.forecasting.evaluate",
    "relabel_truth": "workbench.forecasting.evaluate",
    "health": "structural_health",
    "HealthOptions": "structural_health",
    "HealthResult": "structural_health",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    path = module if "." in module else f"{__name__}.{module}"
    value = getattr(importlib.import_module(path), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
