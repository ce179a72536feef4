"""workbench: hull vibration monitoring for ships.

The notebook front door, one function per user job (:mod:`workbench.stages`)::

    import workbench as wb
    tracked = wb.track(selected)                     # modes followed through the voyage
    fit = wb.fit(tracked.table, predictors)          # stepwise model per mode
    fit[4].params, fit[4].conf_int(), fit.summary()

``identify``, ``track``, ``correlate``, ``fit``, ``forecast``, ``evaluate`` and ``health``
take DataFrames (or paths) and typed options and return results with ``.table``,
``.summary()``, ``.save(dir)`` and ``.plot()``. Packages below them:
:mod:`workbench.signals` (conditioning, blocks), :mod:`workbench.sid` (stochastic subspace
identification, stabilisation, MAC/MACXP, tracking), :mod:`workbench.predictors` (ship log
onto blocks), :mod:`workbench.stats` (correlation, stepwise regression),
:mod:`workbench.forecasting` (sliding model, Kalman blending), :mod:`workbench.reporting`.
Importing :mod:`workbench` is light: everything is imported on first use.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: Public name -> module that defines it (imported on first use).
_EXPORTS = {
    **{
        name: "workbench.stages"
        for name in (
            "identify",
            "track",
            "correlate",
            "fit",
            "forecast",
            "evaluate",
            "health",
            "read_fit",
            "read_correlation",
            "IdentifyOptions",
            "HarmonicOptions",
            "TrackingOptions",
            "CorrelateOptions",
            "FitOptions",
            "ForecastOptions",
            "HealthOptions",
        )
    },
    "load_predictors": "workbench.predictors",
    "canonical_predictors": "workbench.predictors",
    "simulate_voyage": "workbench.simulate",
    "read_table": "data_contracts",
}

__all__ = ["__version__", *sorted(_EXPORTS)]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
