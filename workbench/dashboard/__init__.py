"""Bridge dashboard: a live, read-only web view of a monitor's state folder.

``workbench dashboard --state DIR`` serves, on localhost by default, the current modes
with their forecast bounds, the last hours of each tracked mode in relative change (%)
against its reference with the model's 95 % band, the shaft orders and the tracked lines
that are harmonics, the structural-health chart with its control limit, data health and
alarms. The page polls a small JSON
endpoint and fetches only the panels whose state files changed (ETags from the files'
signatures); it needs no network beyond the dashboard server (no CDN).
"""

from .demo import DemoReplay, DemoState, demo_state
from .server import (
    DashboardOptions,
    DashboardServer,
    is_loopback,
    make_server,
    serve_until_stopped,
)
from .state import DATA_HEALTH, STATE_FILES, StateFolder

__all__ = [
    "DATA_HEALTH",
    "STATE_FILES",
    "DashboardOptions",
    "DashboardServer",
    "DemoReplay",
    "DemoState",
    "StateFolder",
    "demo_state",
    "is_loopback",
    "make_server",
    "serve_until_stopped",
]
