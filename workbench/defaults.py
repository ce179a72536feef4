"""Default values of every command-line option, in one place.

Each value is read from the library object that defines it (an options dataclass, a
module constant, a function's keyword default), so the command line, the library and
``--help`` cannot drift apart; ``tests/test_vocabulary.py`` checks that every option with
a default shows it in ``--help`` and that the values here are the library's. The few
defaults that exist only on the command line are defined here and say why.

Names follow the glossary (README, "Glossary"): ``<COMMAND>_<PARAMETER>``.
"""

from __future__ import annotations

import inspect
from pathlib import Path

from .blocks import DEFAULT_BLOCK_LENGTH_S, DEFAULT_BLOCK_STEP_S
from .dashboard import DashboardOptions, make_server
from .forecasting.options import DEFAULT_HORIZON, DEFAULT_TRUST, ForecastOptions
from .identification import IdentifyOptions
from .monitor import ForecastSettings, MonitorOptions
from .shm import HealthOptions
from .sid.harmonics import HarmonicOptions
from .sid.tracking import TrackingOptions
from .signals.moments import ChannelCheckOptions
from .simulate.voyage import DEFAULT_HOURS, SAMPLING_RATE_HZ, ShaftHarmonics
from .stats.stepwise.regression import DEFAULT_THRESHOLDS


def _keyword_default(function, name: str):
    return inspect.signature(function).parameters[name].default


_IDENTIFY = IdentifyOptions()
_CHANNEL_CHECK = ChannelCheckOptions()
_TRACK = TrackingOptions()
_FORECAST = ForecastOptions()
_HEALTH = HealthOptions()
_MONITOR = MonitorOptions()
_SHAFT = ShaftHarmonics()
_DASHBOARD = DashboardOptions()
_MONITOR_FORECAST = ForecastSettings()

# --------------------------------------------------------------------------- blocks
#: Block length and step of the block grid. [min]
BLOCK_MINUTES = DEFAULT_BLOCK_LENGTH_S / 60.0
STEP_MINUTES = DEFAULT_BLOCK_STEP_S / 60.0

# --------------------------------------------------------------------------- simulate, demo
SEED = 0
#: Length of the demo voyage. [h]
HOURS = DEFAULT_HOURS
#: Sampling rate of simulated acceleration files (the analysis rate of the demo). [Hz]
SIMULATE_SAMPLING_RATE_HZ = SAMPLING_RATE_HZ
DEMO_OUT = Path("reports") / "demo"
#: Shaft orders and propeller blades in simulated accelerations, and the shaft rate per
#: knot of speed. [-], [-], [Hz/kn]
SIMULATE_SHAFT_ORDERS = ",".join(f"{k:d}" for k in _SHAFT.orders)
SIMULATE_BLADES = _SHAFT.blades
SIMULATE_SHAFT_HZ_PER_KN = _SHAFT.hz_per_kn

# --------------------------------------------------------------------------- identify
#: Shaft orders checked for harmonics, and the propeller's blades (0: no blade pass).
IDENTIFY_HARMONIC_ORDERS = ",".join(f"{k:g}" for k in HarmonicOptions().orders)
IDENTIFY_BLADES = HarmonicOptions().blades
IDENTIFY_METHOD = _IDENTIFY.method
IDENTIFY_BLOCK_ROWS = _IDENTIFY.block_rows
IDENTIFY_MIN_ORDER = min(_IDENTIFY.orders)
IDENTIFY_MAX_ORDER = max(_IDENTIFY.orders)
#: Step between model orders (SSI poles come in complex-conjugate pairs). [-]
IDENTIFY_ORDER_STEP = 2
IDENTIFY_LSCF_MAX_ORDER = max(_IDENTIFY.lscf_orders)
IDENTIFY_WEIGHTING = _IDENTIFY.weighting
IDENTIFY_RATE = _IDENTIFY.target_rate_hz
IDENTIFY_MAX_GAP_S = _IDENTIFY.max_gap_s
IDENTIFY_SELECTION = _IDENTIFY.selection
IDENTIFY_SHORT_RECORD = _IDENTIFY.short_record
IDENTIFY_CONDITIONING = _IDENTIFY.conditioning
IDENTIFY_KURTOSIS_MIN, IDENTIFY_KURTOSIS_MAX = _CHANNEL_CHECK.kurtosis_limits
IDENTIFY_KURTOSIS_Z_MAX = _CHANNEL_CHECK.max_kurtosis_z
IDENTIFY_VARIANCE_Z_MAX = _CHANNEL_CHECK.max_variance_z
IDENTIFY_MAX_NAN_FRACTION = _CHANNEL_CHECK.max_nan_fraction
#: Blocks the per-block store writes together (an interruption loses at most these).
IDENTIFY_BATCH_BLOCKS = 16
#: Blocks drawn as stabilisation diagrams (and with their total prediction errors); none
#: unless asked for: the figures are a look at chosen blocks, not a result of identify.
IDENTIFY_STABILISATION_FIGURES = IDENTIFY_TPE_FIGURES = 0

# --------------------------------------------------------------------------- track
TRACK_MAC_MIN = _TRACK.mac_min
TRACK_GATE = _TRACK.gate
TRACK_FREQUENCY_TOL = _TRACK.frequency_tol

# --------------------------------------------------------------------------- correlate, fit
#: Share of the blocks a mode must be measured in to be modelled (short-lived tracks are
#: shaft harmonics sweeping past or spurious poles). [-]
MIN_PRESENCE = 0.5
CORRELATE_ALPHA = 0.05
CORRELATE_CORRECTION = "none"
FIT_P_ENTER, FIT_P_REMOVE = DEFAULT_THRESHOLDS["sse"]
FIT_UPPER = "interactions"

# --------------------------------------------------------------------------- forecast
#: The measurement of the reference work's option A.
FORECAST_OPTION = "tracked-pole"
#: The reference work's method 2.
FORECAST_SCHEME = "rolling"
FORECAST_TRAIN_BLOCKS = _FORECAST.train_blocks
#: Forecast horizon per scheme. [blocks]
FORECAST_HORIZON = {"single-window": DEFAULT_HORIZON[1], "rolling": DEFAULT_HORIZON[2]}
#: The predictive model ("memory"; "window" is the reference configuration).
FORECAST_MODEL = _FORECAST.model
#: Steady-state weight on the SSI estimate of ``--model window``. [-]
FORECAST_TRUST = DEFAULT_TRUST
FORECAST_MAC_MIN = _FORECAST.mac_min
#: Prior relative frequency change per unit of a predictor beyond the model's range. [1/unit]
FORECAST_EXTRAPOLATION_SENSITIVITY = _FORECAST.sensitivities()
FORECAST_REACQUIRE_BLOCKS = {
    "memory": _FORECAST.reacquire_blocks,
    "window": _FORECAST.reacquire_blocks,
}
FORECAST_WORKERS = _FORECAST.n_workers

# --------------------------------------------------------------------------- evaluate, health
EVALUATE_PHASE = "forecast"
HEALTH_REFERENCE_HOURS = 6.0
HEALTH_EWMA_LAMBDA = _HEALTH.ewma_lambda
HEALTH_FALSE_ALARMS_PER_DAY = _HEALTH.false_alarms_per_day
HEALTH_STATISTIC = _HEALTH.statistic

# --------------------------------------------------------------------------- monitor
# (the monitor's identification, tracking, forecast and health options are the batch
# commands': workbench.cli.monitoring copies their declarations)
#: Seconds between polls of the watched folder and between heartbeats. [s]
MONITOR_POLL_S = _MONITOR.poll_s
#: A file is taken once unmodified this long. [s]
MONITOR_SETTLE_S = _MONITOR.settle_s
MONITOR_LATE_S = _MONITOR.late_s
MONITOR_FLUSH_AFTER_S = _MONITOR.flush_after_s
MONITOR_ON_ALARM_TIMEOUT_S = _MONITOR.on_alarm_timeout_s
MONITOR_HEALTH_MODEL = _MONITOR_FORECAST.health_model
#: Hours the health chart's operational model is fitted on. [h]
MONITOR_HEALTH_TRAIN_HOURS = _MONITOR_FORECAST.health_train_hours
#: Time constant of the health chart's slowly following baseline (0: fixed). [h]
MONITOR_BASELINE_HOURS = _MONITOR_FORECAST.baseline_hours

# --------------------------------------------------------------------------- dashboard
DASHBOARD_HOST = _keyword_default(make_server, "host")
DASHBOARD_PORT = _keyword_default(make_server, "port")
#: Spans of the tracked frequencies and of the health chart; the page's poll. [h], [h], [s]
DASHBOARD_HOURS = _DASHBOARD.hours
DASHBOARD_HEALTH_HOURS = _DASHBOARD.health_hours
DASHBOARD_POLL_S = _DASHBOARD.poll_seconds
