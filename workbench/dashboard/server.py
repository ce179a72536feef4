"""HTTP server of the bridge dashboard (standard library only).

Routes (GET and HEAD only; the server never writes into the state folder):

``/``                     the page
``/static/<file>``        its script and style sheet, from the package data
``/api/versions``         one ETag per panel and the server's clock
``/api/<panel>``          a panel's data as JSON (``status``, ``modes``, ``tracked``,
                          ``health``, ``alarms``, ``data_health``)

The page polls ``/api/versions`` and fetches only the panels whose ETag changed. A
panel's ETag is a digest of the signatures (mtime in ns, size, inode) of the state files
it reads and of the dashboard's options, so an unchanged panel costs one small request
and no parsing. Every panel answers with ``available: false`` and a message while its
files are absent or unreadable; an internal error gives a one-line JSON 500, never a
traceback page.

Why the standard library's :class:`~http.server.ThreadingHTTPServer`: the dashboard is a
read-only view for a handful of screens on a ship's network, serving a fixed set of
routes (no file serving by path, no uploads, no sessions), so it needs neither an async
framework nor a WSGI/ASGI server, and it adds no dependency to install on the bridge
computer. A thread per connection with a read timeout, answers built once per change of
the state files and shared by all clients, and small JSON bodies keep it light; the
Python documentation's warning about ``http.server`` concerns its file-serving handlers,
which are not used.
"""

from __future__ import annotations

import hashlib
import ipaddress
import json
import logging
import signal
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

import pandas as pd

from .state import StateFolder
from .views import (
    alarms_view,
    data_health_view,
    health_view,
    modes_view,
    status_view,
    tracked_view,
)

__all__ = [
    "DashboardOptions",
    "DashboardServer",
    "is_loopback",
    "make_server",
    "serve_until_stopped",
]

log = logging.getLogger("workbench.dashboard")

#: Static files served under /static/, with their content types.
STATIC_FILES = {
    "dashboard.js": "text/javascript; charset=utf-8",
    "dashboard.css": "text/css; charset=utf-8",
}


@dataclass(frozen=True)
class DashboardOptions:
    """Options of the dashboard.

    Parameters
    ----------
    hours : float
        Span of the tracked-frequency plot and the data-health summary, back from the
        newest block. [h]
    health_hours : float
        Span of the health chart. [h]
    poll_seconds : float
        How often the page asks whether anything changed. [s]
    option : {"A", "B"}, optional
        Forecast option shown on the mode cards; default A when present, else B.
    stale_seconds : float
        A running monitor whose ``status.json`` is older than this is flagged as silent
        (default 15 min: three 5-min blocks missed). [s]
    """

    hours: float = 6.0
    health_hours: float = 24.0
    poll_seconds: float = 1.0
    option: str | None = None
    stale_seconds: float = 900.0

    def __post_init__(self) -> None:
        for name in ("hours", "health_hours", "poll_seconds", "stale_seconds"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0):
                raise ValueError(f"{name}={value!r} must be a positive number")
        if self.poll_seconds < 0.1:
            raise ValueError(f"poll_seconds={self.poll_seconds!r} must be >= 0.1")
        if self.option not in (None, "A", "B"):
            raise ValueError(f"option={self.option!r} must be 'A', 'B' or None")


@dataclass(frozen=True)
class Panel:
    """A panel: the state files it reads and how it turns them into JSON."""

    files: tuple[str, ...]
    build: Callable[[StateFolder, DashboardOptions], dict[str, Any]]


def _now() -> pd.Timestamp:
    return pd.Timestamp.now(tz="UTC")


def _unavailable(*messages: str | None) -> dict[str, Any]:
    text = "; ".join(m for m in messages if m)
    return {"available": False, "message": text or "waiting for data"}


def _panel(data: dict[str, Any], *messages: str | None) -> dict[str, Any]:
    """A panel's answer: its data, plus the reason when a file was unusable (the data
    are then the last good version)."""
    note = "; ".join(m for m in messages if m)
    return {"available": True, "message": note, **data}


def _status(state: StateFolder, options: DashboardOptions) -> dict[str, Any]:
    snap = state.read("status")
    if not snap.available:
        return _unavailable(snap.error)
    return _panel(status_view(snap.data, _now()), snap.error)


def _modes(state: StateFolder, options: DashboardOptions) -> dict[str, Any]:
    tracked, forecast = state.read("tracked"), state.read("forecast")
    if not (tracked.available or forecast.available):
        return _unavailable(tracked.error, forecast.error)
    view = modes_view(tracked.data, forecast.data, option=options.option)
    if view["block"] is None:
        return _unavailable("no block identified yet")
    return _panel(view, tracked.error, forecast.error)


def _tracked(state: StateFolder, options: DashboardOptions) -> dict[str, Any]:
    snap = state.read("tracked")
    if not snap.available:
        return _unavailable(snap.error)
    if snap.data.empty:
        return _unavailable("no block identified yet")
    lines = state.read("harmonics")  # optional: only with a logged shaft speed
    harmonics = lines.data if lines.available else None
    return _panel(tracked_view(snap.data, hours=options.hours, harmonics=harmonics), snap.error)


def _health(state: StateFolder, options: DashboardOptions) -> dict[str, Any]:
    snap = state.read("health")
    if not snap.available:
        return _unavailable(snap.error)
    if snap.data.empty:
        return _unavailable("the health chart has no block yet")
    return _panel(health_view(snap.data, hours=options.health_hours), snap.error)


def _alarms(state: StateFolder, options: DashboardOptions) -> dict[str, Any]:
    alarms, health = state.read("alarms"), state.read("health")
    if not alarms.available:
        return _unavailable(alarms.error)
    return _panel(alarms_view(alarms.data, health.data), alarms.error)


def _data_health(state: StateFolder, options: DashboardOptions) -> dict[str, Any]:
    snap = state.read("data_health")
    if not snap.available:
        return _unavailable(snap.error)
    if snap.data.empty:
        return _unavailable("no block identified yet")
    return _panel(data_health_view(snap.data, hours=options.hours), snap.error)


#: Panels by name, in the order the page shows them.
PANELS: dict[str, Panel] = {
    "status": Panel(("status",), _status),
    "modes": Panel(("tracked", "forecast"), _modes),
    "tracked": Panel(("tracked", "harmonics"), _tracked),
    "health": Panel(("health",), _health),
    "alarms": Panel(("alarms", "health"), _alarms),
    "data_health": Panel(("data_health",), _data_health),
}


def is_loopback(host: str) -> bool:
    """True when *host* (a name or address) only reaches this machine."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class DashboardServer(ThreadingHTTPServer):
    """Threaded HTTP server of one state folder (see the module docstring for routes).

    Parameters
    ----------
    address : (host, port)
        Where to listen; port 0 takes a free port (see ``server_address``).
    state : path
        The monitor's state folder.
    options : DashboardOptions, optional
    """

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], state, options: DashboardOptions | None = None):
        self.state = StateFolder(state)
        self.options = options or DashboardOptions()
        self._answers: dict[str, tuple[str, bytes]] = {}
        self._answers_lock = threading.Lock()
        self._page = _render_page(self.options)
        if ":" in address[0]:
            self.address_family = socket.AF_INET6
        #: bound to this machine only: answer only requests addressed to it by a local
        #: name, so a web page elsewhere cannot read the dashboard by pointing one of its
        #: own host names at 127.0.0.1 (DNS rebinding)
        self.local_only = is_loopback(address[0])
        super().__init__(address, _Handler)

    def host_allowed(self, host_header: str | None) -> bool:
        """Whether a request with this ``Host`` header is served."""
        if not self.local_only:
            return True
        if not host_header:
            return False
        host = urlsplit(f"//{host_header}").hostname or ""
        return is_loopback(host)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        host = f"[{host}]" if ":" in str(host) else host
        return f"http://{host}:{port}/"

    def etag(self, panel: str) -> str:
        """ETag of *panel*: digest of its files' signatures and the options."""
        signatures = [self.state.signature(name) for name in PANELS[panel].files]
        text = repr((panel, signatures, self.options))
        return '"' + hashlib.blake2s(text.encode(), digest_size=10).hexdigest() + '"'

    def answer(self, panel: str) -> tuple[str, bytes]:
        """(ETag, JSON body) of *panel*, built once per change of its files."""
        tag = self.etag(panel)
        with self._answers_lock:
            cached = self._answers.get(panel)
        if cached is not None and cached[0] == tag:
            return cached
        data = PANELS[panel].build(self.state, self.options)
        body = json.dumps(data, allow_nan=False, separators=(",", ":")).encode()
        # the files may have changed while being read: tag with the signatures seen
        # *before* reading, so the next poll fetches again rather than missing a change
        with self._answers_lock:
            self._answers[panel] = (tag, body)
        return tag, body

    def versions(self) -> dict[str, Any]:
        return {
            "server_time": _now().strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
            "poll_seconds": self.options.poll_seconds,
            "panels": {name: self.etag(name) for name in PANELS},
        }


def _render_page(options: DashboardOptions) -> bytes:
    page = resources.files(__package__).joinpath("static", "index.html").read_text("utf-8")
    config = json.dumps(
        {"poll_ms": int(options.poll_seconds * 1000), "stale_s": options.stale_seconds}
    )
    return page.replace("{{CONFIG}}", config).encode()


class _Handler(BaseHTTPRequestHandler):
    server: DashboardServer
    server_version = "workbench-dashboard"
    sys_version = ""
    protocol_version = "HTTP/1.1"
    #: seconds a silent connection is kept (a stalled client cannot hold a thread)
    timeout = 30

    def log_message(self, format: str, *args) -> None:  # noqa: A002 (stdlib signature)
        log.debug("%s - %s", self.address_string(), format % args)

    def do_HEAD(self) -> None:  # noqa: N802 (stdlib name)
        self._serve(head=True)

    def do_GET(self) -> None:  # noqa: N802 (stdlib name)
        self._serve(head=False)

    def _send(
        self,
        status: HTTPStatus,
        body: bytes,
        content_type: str,
        *,
        head: bool,
        etag: str | None = None,
        cache: str = "no-cache",
    ) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", cache)
        self.send_header("X-Content-Type-Options", "nosniff")
        if etag is not None:
            self.send_header("ETag", etag)
        self.end_headers()
        if not head:
            self.wfile.write(body)

    def _json(self, status: HTTPStatus, data: dict, *, head: bool) -> None:
        body = json.dumps(data, allow_nan=False).encode()
        self._send(status, body, "application/json", head=head, cache="no-store")

    def _serve(self, *, head: bool) -> None:
        path = urlsplit(self.path).path
        try:
            if not self.server.host_allowed(self.headers.get("Host")):
                self._json(
                    HTTPStatus.MISDIRECTED_REQUEST,
                    {"error": "this dashboard answers to localhost only"},
                    head=head,
                )
            elif path in ("/", "/index.html"):
                self._send(
                    HTTPStatus.OK,
                    self.server._page,
                    "text/html; charset=utf-8",
                    head=head,
                )
            elif path.startswith("/static/") and path[8:] in STATIC_FILES:
                name = path[8:]
                body = resources.files(__package__).joinpath("static", name).read_bytes()
                self._send(HTTPStatus.OK, body, STATIC_FILES[name], head=head)
            elif path == "/api/versions":
                self._json(HTTPStatus.OK, self.server.versions(), head=head)
            elif path.startswith("/api/") and path[5:] in PANELS:
                tag, body = self.server.answer(path[5:])
                if tag in _etags(self.headers.get("If-None-Match", "")):
                    self.send_response(HTTPStatus.NOT_MODIFIED)
                    self.send_header("ETag", tag)
                    self.send_header("Cache-Control", "no-cache")
                    self.end_headers()
                else:
                    self._send(HTTPStatus.OK, body, "application/json", head=head, etag=tag)
            else:
                self._json(HTTPStatus.NOT_FOUND, {"error": f"no such page: {path}"}, head=head)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the browser went away mid-answer
        except Exception as error:  # never a traceback page: log it, answer one line
            log.exception("dashboard: %s failed", path)
            try:
                self._json(
                    HTTPStatus.INTERNAL_SERVER_ERROR,
                    {"available": False, "message": f"internal error: {type(error).__name__}"},
                    head=head,
                )
            except OSError:
                pass


def _etags(header: str) -> set[str]:
    return {part.strip().removeprefix("W/") for part in header.split(",") if part.strip()}


def make_server(
    state, *, host: str = "127.0.0.1", port: int = 8050, options: DashboardOptions | None = None
) -> DashboardServer:
    """A :class:`DashboardServer` bound to *host*:*port* (0: a free port), not started;
    call ``serve_forever()`` (or run it in a thread) and ``shutdown()``."""
    return DashboardServer((host, port), state, options)


def serve_until_stopped(server: DashboardServer) -> None:
    """Serve until Ctrl+C or SIGTERM (how a service manager stops it), then close.

    The SIGTERM handler is installed only in the main thread and restored afterwards.
    """
    previous = None
    if threading.current_thread() is threading.main_thread():

        def stop(signum, frame):
            raise KeyboardInterrupt

        previous = signal.signal(signal.SIGTERM, stop)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        server.server_close()
