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
:mod:`workbench.forecast` (sliding model, Kalman blending), :mod:`workbench.reporting`.
Importing :mod:`workbench` is light: everything is imported on first use.
"""

from __future__ import annotations

import importlib
import sys
import types

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


class _StageAndPackage:
    """``workbench.forecast``, ``workbench.identify``, ``workbench.health``: the stage when
    called, the library package (or module) of the same name for everything else.

    ``wb.forecast(modal, predictors)`` runs :func:`workbench.stages.forecast`, while
    ``wb.forecast.sliding_forecast``, ``from workbench.forecast import ...`` and
    ``import workbench.forecast as f`` keep reaching the package (attribute reads and
    writes are passed on to it, so monkeypatching works as on the module).
    """

    __slots__ = ("_stage_name", "_package_name")

    def __init__(self, stage_name: str, package_name: str):
        object.__setattr__(self, "_stage_name", stage_name)
        object.__setattr__(self, "_package_name", package_name)

    @property
    def _package(self):
        return importlib.import_module(self._package_name)

    @property
    def __wrapped__(self):  # inspect.signature and help() show the stage's
        return getattr(importlib.import_module("workbench.stages"), self._stage_name)

    @property
    def __doc__(self):  # type: ignore[override]
        return self.__wrapped__.__doc__

    def __call__(self, *args, **kwargs):
        return self.__wrapped__(*args, **kwargs)

    def __getattr__(self, name: str):
        return getattr(self._package, name)

    def __setattr__(self, name: str, value) -> None:
        setattr(self._package, name, value)

    def __delattr__(self, name: str) -> None:
        delattr(self._package, name)

    def __dir__(self) -> list[str]:
        return dir(self._package)

    def __repr__(self) -> str:
        return (
            f"<workbench.{self._stage_name}: the stage workbench.stages.{self._stage_name} "
            f"and the module {self._package_name}>"
        )


#: Stage names that are also the names of a package or module of workbench.
_SHARED = {
    name: _StageAndPackage(name, f"workbench.{name}") for name in ("forecast", "identify", "health")
}


class _Workbench(types.ModuleType):
    """The package's module type: its shared names stay the stage entries even after the
    import system records the subpackage of the same name as an attribute."""

    def __getattribute__(self, name: str):
        if name in _SHARED:
            return _SHARED[name]
        return super().__getattribute__(name)

    def __setattr__(self, name: str, value) -> None:
        if name in _SHARED and isinstance(value, types.ModuleType):
            return  # importing workbench.<name>: the module stays in sys.modules
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Workbench


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
