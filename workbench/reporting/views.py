"""The figures of a run report: what structural engineers look at first.

Every function takes contract tables (or arrays) and returns a matplotlib figure; nothing
here reads files or knows the report layout (:mod:`workbench.reporting.report` does).
Damping ratios are drawn in percent and labelled so; mode colours follow the tracked mode
label (:func:`mode_colour`), the same in every figure.

The figures live by subject: :mod:`.mode_views` (tracked modes and shapes),
:mod:`.signal_views` (spectra, channel moments, stabilisation diagrams), :mod:`.model_views`
(correlation, forecasts); :mod:`.view_style` holds what they share. This module gathers
them under one name.
"""

from __future__ import annotations

from .mode_views import (
    mean_mode_shapes,
    plot_automac,
    plot_campbell,
    plot_mode_shapes,
    plot_tracked_modes,
)
from .model_views import (
    plot_correlation_heatmap,
    plot_forecast_overview,
    plot_observed_vs_predicted,
)
from .signal_views import (
    plot_channel_moments,
    plot_spectra_by_case,
    plot_stabilisation_block,
)
from .view_style import mode_colour

__all__ = [
    "mean_mode_shapes",
    "mode_colour",
    "plot_automac",
    "plot_campbell",
    "plot_channel_moments",
    "plot_correlation_heatmap",
    "plot_forecast_overview",
    "plot_mode_shapes",
    "plot_observed_vs_predicted",
    "plot_spectra_by_case",
    "plot_stabilisation_block",
    "plot_tracked_modes",
]
