"""Structural-health indicators: a multivariate control chart of frequency residuals.

* :func:`health_chart` - MEWMA/Hotelling chart of the forecast's standardised residuals
  with a robust reference period and a bootstrap control limit; HEALTH and ALARMS tables;
* :func:`simulate_health_voyage` - block-level voyages with a stiffness loss part-way, for
  tests and ``benchmarks/bench_health.py``.
"""

from .chart import HealthOptions, HealthReference, HealthResult, health_chart
from .scenario import (
    HealthVoyage,
    detection_delay_hours,
    frozen_forecast,
    law_forecast,
    simulate_health_voyage,
)

__all__ = [
    "HealthOptions",
    "HealthReference",
    "HealthResult",
    "HealthVoyage",
    "detection_delay_hours",
    "frozen_forecast",
    "health_chart",
    "law_forecast",
    "simulate_health_voyage",
]
