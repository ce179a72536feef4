"""HTTP server of the bridge dashboard (standard library only).

Routes (GET and HEAD only; the server never writes into the state folder):

``/``                     the page
``/static/<file>``        its script and style sheet, from the package data
``/api/versions``         one ETag per panel and the server's clock
``/api/<panel>``          a panel's data as JSON (``status``, ``modes``, ``tracked``,
                          ``shaft``, ``health``, ``alarms``, ``data_health``)

The page polls ``/api/versions`` and fetches only the panels whose ETag changed. A
panel's ETag is a digest of the signatures (mtime in ns, size, inode) of the state files
it reads and of the dashboard's options, so an unchanged panel costs one small request
and no parsing. Every panel answers with ``available: false`` and a message while its
files are absent or unreadable; an internal error gives a one-line JSON 500, never a
traceback page.

Why the standard library's :class:`~http.server.HTTPServer`: the dashboard is a
read-only view for a handful of screens on a ship's network, serving a fixed set of
routes (no file serving by path, no uploads, no sessions), so it needs neither an async
framework nor a WSGI/ASGI server, and it adds no dependency to install on the bridge
computer. Answers built once per change of the state files and shared by all clients,
and small JSON bodies keep it light; the Python documentation's warning about
``http.server`` concerns its file-serving handlers, which are not used.

Bounded under load: connections are served by a fixed pool of
:attr:`DashboardOptions.threads` threads from a queue of at most
:attr:`DashboardOptions.queued` connections (a listen backlog of 128 in front of it); a
connection arriving when the queue is full is answered ``503`` with ``Retry-After`` at
once, and a connection that has not completed a request within
:attr:`DashboardOptions.request_seconds` (a slow or silent client, an idle keep-alive) is
closed, so slow clients cannot hold the threads. While connections wait, answers close
their keep-alive connection to let the next one in.

Every answer carries a strict Content-Security-Policy (the page's script and style sheet
from this server only, no inline script or style, no framing, requests to this server
only), ``X-Frame-Options: DENY``, ``Referrer-Policy: no-referrer`` and
``X-Content-Type-Options: nosniff``.
"""

from __future__ import annotations

import hashlib
import ipaddress
import json
import logging
import queue
import signal
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, HTTPServer
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
    shaft_view,
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

#: Headers of every answer (see the module notes). The page's configuration is a JSON
#: data block (``type="application/json"``), which a CSP does not treat as a script.
SECURITY_HEADERS = {
    "Content-Security-Policy": (
        "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; "
        "connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
    ),
    "X-Frame-Options": "DENY",
    "Referrer-Policy": "no-referrer",
    "X-Content-Type-Options": "nosniff",
}
#: Seconds a client refused with 503 is asked to wait before trying again.
RETRY_AFTER_SECONDS = 1

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
    threads : int
        Connections served at once (a handful of bridge screens, each browser keeping a
        few connections).
    queued : int
        Connections waiting for a thread, at most; more are answered 503 at once.
    request_seconds : float
        A connection that has not sent a whole request this long after it was taken (or
        after its previous answer) is closed. [s]
    """

    hours: float = 6.0
    health_hours: float = 24.0
    poll_seconds: float = 1.0
    option: str | None = None
    stale_seconds: float = 900.0
    threads: int = 16
    queued: int = 64
    request_seconds: float = 5.0

    def __post_init__(self) -> None:
        for name in ("hours", "health_hours", "poll_seconds", "stale_seconds", "request_seconds"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0):
                raise ValueError(f"{name}={value!r} must be a positive number")
        for name in ("threads", "queued"):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
                raise ValueError(f"{name}={value!r} must be a whole number of at least 1")
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
    beat = state.read("heartbeat")
    # an absent heartbeat is no error (a state written by something else than the monitor)
    note = beat.error if beat.signature is not None else None
    return _panel(status_view(snap.data, _now(), beat.data), snap.error, note)


def _liveness(state: StateFolder) -> str | None:
    """The status panel's liveness verdict now (part of its ETag, so that the page fetches
    the panel again when a heartbeat is missed although no file changed)."""
    snap = state.read("status")
    if not snap.available:
        return None
    return status_view(snap.data, _now(), state.read("heartbeat").data)["liveness"]


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
    # optional: the shaft orders only with a ship log; the model's band and the
    # health chart's reference period once they exist
    lines, forecast, health = (state.read(n) for n in ("harmonics", "forecast", "health"))
    view = tracked_view(
        snap.data,
        hours=options.hours,
        harmonics=lines.data,
        forecast=forecast.data,
        health=health.data,
        option=options.option,
    )
    return _panel(view, snap.error)


def _shaft(state: StateFolder, options: DashboardOptions) -> dict[str, Any]:
    lines, tracks = state.read("harmonics"), state.read("harmonic_tracks")
    if not (lines.available or tracks.available):
        # the monitor writes them from a ship log with the shaft speed, or with the speed
        # once a line follows it (the shaft rate per knot)
        return _unavailable(
            f"{lines.error}: the shaft orders are known only from a ship log with the "
            "shaft speed (shaft_rpm), or with the speed once a line follows it"
        )
    view = shaft_view(lines.data, tracks.data, hours=options.hours)
    if view["block"] is None:
        return _unavailable("no block with a shaft speed yet")
    return _panel(view, lines.error, tracks.error)


def _health(state: StateFolder, options: DashboardOptions) -> dict[str, Any]:
    snap = state.read("health")
    if not snap.available:
        return _unavailable(snap.error)
    if snap.data.empty:
        # the monitor's status says when the chart starts (a note that does not change
        # while the chart learns, so the panel need not follow status.json's every write)
        status = state.read("status")
        when = status.data.get("health_note", "") if status.available else ""
        return _unavailable("the health chart has no block yet", when.removeprefix("health: "))
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
    "status": Panel(("status", "heartbeat"), _status),
    "modes": Panel(("tracked", "forecast"), _modes),
    "tracked": Panel(("tracked", "harmonics", "forecast", "health"), _tracked),
    "shaft": Panel(("harmonics", "harmonic_tracks"), _shaft),
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


class DashboardServer(HTTPServer):
    """HTTP server of one state folder, with a bounded pool of threads (see the module
    docstring for routes and limits).

    Parameters
    ----------
    address : (host, port)
        Where to listen; port 0 takes a free port (see ``server_address``).
    state : path
        The monitor's state folder.
    options : DashboardOptions, optional
    """

    allow_reuse_address = True
    #: listen backlog: connections the system holds before the server takes them
    request_queue_size = 128

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
        self._waiting: queue.Queue = queue.Queue(maxsize=self.options.queued)
        #: connection -> monotonic time since which it owes a request
        self._reading: dict[socket.socket, float] = {}
        self._reading_lock = threading.Lock()
        #: connections answered 503 because the queue was full (for tests and logs)
        self.refused = 0
        self._pool: list[threading.Thread] = []
        super().__init__(address, _Handler)  # closes the server when it cannot bind
        for k in range(self.options.threads):
            thread = threading.Thread(target=self._serve_queue, name=f"dashboard-{k}", daemon=True)
            thread.start()
            self._pool.append(thread)

    # ------------------------------------------------------------------ the pool
    def process_request(self, request, client_address) -> None:
        """Queue the connection for a pool thread; answer 503 when the queue is full."""
        self.owes_request(request)  # the time spent waiting counts
        try:
            self._waiting.put_nowait((request, client_address))
        except queue.Full:
            self.forget(request)
            self.refused += 1
            _refuse(request)
            self.shutdown_request(request)

    def _serve_queue(self) -> None:
        while True:
            item = self._waiting.get()
            if item is None:
                return
            request, client_address = item
            try:
                self.finish_request(request, client_address)
            except Exception:  # noqa: BLE001 - one connection's failure, logged
                self.handle_error(request, client_address)
            finally:
                self.forget(request)
                self.shutdown_request(request)

    def handle_error(self, request, client_address) -> None:
        log.debug("dashboard: connection from %s failed", client_address, exc_info=True)

    def owes_request(self, connection: socket.socket) -> None:
        """*connection* is now expected to send a request (see ``request_seconds``);
        counted from when it was accepted, or from its previous answer."""
        with self._reading_lock:
            self._reading.setdefault(connection, time.monotonic())

    def forget(self, connection: socket.socket) -> None:
        with self._reading_lock:
            self._reading.pop(connection, None)

    def others_waiting(self) -> bool:
        return not self._waiting.empty()

    def service_actions(self) -> None:
        """Between two looks at the listening socket: close the connections that owe a
        request for longer than ``request_seconds`` (their thread then ends them)."""
        limit = time.monotonic() - self.options.request_seconds
        with self._reading_lock:
            late = [c for c, since in self._reading.items() if since < limit]
            for connection in late:
                del self._reading[connection]
        for connection in late:
            try:
                connection.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def server_close(self) -> None:
        """Stop listening, close the connections open or waiting, end the pool."""
        super().server_close()
        with self._reading_lock:
            open_connections = list(self._reading)
        for connection in open_connections:  # a thread reading from it ends at once
            try:
                connection.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        while True:
            try:
                item = self._waiting.get_nowait()
            except queue.Empty:
                break
            if item is not None:
                self.shutdown_request(item[0])
        for _ in self._pool:
            self._waiting.put(None)  # one stop per thread, taken as each thread is free
        for thread in self._pool:
            thread.join(timeout=self.options.request_seconds + 5)

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
        verdict = _liveness(self.state) if panel == "status" else None
        text = repr((panel, signatures, verdict, self.options))
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


def _refuse(connection: socket.socket) -> None:
    """Answer 503 with Retry-After without reading the request (the server is full)."""
    body = json.dumps(
        {"available": False, "message": "the dashboard is busy; try again in a moment"}
    ).encode()
    head = [
        "HTTP/1.1 503 Service Unavailable",
        "Content-Type: application/json",
        f"Content-Length: {len(body)}",
        f"Retry-After: {RETRY_AFTER_SECONDS}",
        "Cache-Control: no-store",
        "Connection: close",
        *(f"{name}: {value}" for name, value in SECURITY_HEADERS.items()),
    ]
    try:
        connection.settimeout(1.0)
        connection.sendall(("\r\n".join(head) + "\r\n\r\n").encode() + body)
        connection.setblocking(False)
        connection.recv(65536)  # what the client sent so far: closing with it unread resets
    except OSError:
        pass


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

    def setup(self) -> None:
        #: seconds one read or write may block (``request_seconds`` bounds a request)
        self.timeout = self.server.options.request_seconds
        super().setup()

    def handle_one_request(self) -> None:
        self.server.owes_request(self.connection)
        try:
            super().handle_one_request()
        finally:
            self.server.forget(self.connection)

    def end_headers(self) -> None:
        for name, value in SECURITY_HEADERS.items():
            self.send_header(name, value)
        if self.server.others_waiting():  # let a waiting connection have this thread
            self.send_header("Connection", "close")
            self.close_connection = True
        super().end_headers()

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
