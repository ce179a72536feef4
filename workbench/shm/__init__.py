"""Structural health monitoring (SHM) indicators: a multivariate control chart of frequency
residuals (the package of the `health` stage, :func:`workbench.stages.health`).

* :func:`health_chart` - per-mode CUSUM (default) or MEWMA/Hotelling chart of the
  forecast's standardised residuals with a robust reference period and control limits
  for a target false-alarm rate; HEALTH and ALARMS tables;
* :class:`HealthMonitor` - the same chart fed block by block, with a JSON state;
* :func:`fit_operational_model` - a per-mode regression of log frequency on the ship log
  (speed, temperatures, fuel) whose FORECAST table feeds the chart;
* :class:`HealthBaseline` - model, chart reference and tracked modes of an earlier voyage,
  saved as JSON, so a new voyage is charted from its first block;
* :func:`frozen_forecast` - the forecast of a stepwise model trained once, over a
  block-level voyage of :func:`workbench.simulate.simulate_health_voyage` (the simulator
  lives with the other simulators; this stays here because it runs the forecast package,
  a layer above the simulator).
"""

from typing import TYPE_CHECKING

from .._lazy import attach

#: Public names and the module defining each, imported on first use (PEP 562): the command
#: line's defaults read :mod:`.options` alone, not the charts and models.
_EXPORTS = {
    "BaselineError": ".baseline",
    "HealthBaseline": ".baseline",
    "HealthReference": ".chart",
    "HealthResult": ".chart",
    "health_chart": ".chart",
    "DEFAULT_TERMS": ".model",
    "OperationalModel": ".model",
    "fit_operational_model": ".model",
    "frozen_forecast": ".model",
    "HealthMonitor": ".monitor",
    "MonitorUpdate": ".monitor",
    "HealthOptions": ".options",
}

if TYPE_CHECKING:
    from .baseline import BaselineError, HealthBaseline
    from .chart import HealthReference, HealthResult, health_chart
    from .model import DEFAULT_TERMS, OperationalModel, fit_operational_model, frozen_forecast
    from .monitor import HealthMonitor, MonitorUpdate
    from .options import HealthOptions


__getattr__, __dir__ = attach(__name__, _EXPORTS, globals())


__all__ = [
    "DEFAULT_TERMS",
    "BaselineError",
    "HealthBaseline",
    "HealthMonitor",
    "HealthOptions",
    "HealthReference",
    "HealthResult",
    "MonitorUpdate",
    "OperationalModel",
    "fit_operational_model",
    "frozen_forecast",
    "health_chart",
]
