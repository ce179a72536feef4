"""Drive a headless Chromium over the DevTools protocol, with the standard library only.

For the dashboard's browser tests and its latency benchmark: open a page, evaluate
JavaScript in it and wait for a condition while the page keeps running (live updates,
no reload). The protocol runs over a WebSocket (RFC 6455); the few dozen lines of client
below are enough for it, so the tests need neither a driver nor a browser download.

Example
-------
>>> with HeadlessChromium() as browser:                      # doctest: +SKIP
...     page = browser.open("http://127.0.0.1:8050/")
...     page.wait_for("document.querySelectorAll('.mode-card').length > 0")
"""

from __future__ import annotations

import base64
import hashlib
import itertools
import json
import os
import shutil
import socket
import struct
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

__all__ = ["HEADLESS_FLAGS", "BrowserError", "HeadlessChromium", "Page", "find_chromium"]

#: Executables tried, in order (Debian: chromium).
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
#: Flags for a quiet headless browser on a machine without internet (also what the
#: report's browser test runs chromium with).
HEADLESS_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
)
#: The headless flags plus the remote-debugging port and no timer throttling.
FLAGS = (
    *HEADLESS_FLAGS,
    "--disable-background-timer-throttling",
    "--disable-renderer-backgrounding",
    "--remote-debugging-port=0",
)
_WS_GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"


class BrowserError(RuntimeError):
    """The browser did not start, closed, or a script in the page failed."""


def find_chromium() -> str | None:
    """Path of the first Chromium-like browser on PATH, None when there is none."""
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


class _WebSocket:
    """Minimal RFC 6455 client: text frames, masked as clients must, pings answered."""

    def __init__(self, url: str, timeout: float):
        parts = urlsplit(url)
        self._sock = socket.create_connection((parts.hostname, parts.port), timeout=timeout)
        key = base64.b64encode(os.urandom(16)).decode()
        request = (
            f"GET {parts.path} HTTP/1.1\r\nHost: {parts.hostname}:{parts.port}\r\n"
            "Upgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
        )
        self._sock.sendall(request.encode())
        self._in = self._sock.makefile("rb")
        status = self._in.readline().decode("latin-1")
        headers = {}
        while (line := self._in.readline().decode("latin-1").strip()) != "":
            name, _, value = line.partition(":")
            headers[name.strip().lower()] = value.strip()
        accept = base64.b64encode(hashlib.sha1((key + _WS_GUID).encode()).digest()).decode()
        if " 101 " not in status or headers.get("sec-websocket-accept") != accept:
            raise BrowserError(f"WebSocket handshake with {url} failed: {status.strip()}")

    def send(self, text: str) -> None:
        payload = text.encode()
        n = len(payload)
        if n < 126:
            header = struct.pack("!BB", 0x81, 0x80 | n)
        elif n < 1 << 16:
            header = struct.pack("!BBH", 0x81, 0x80 | 126, n)
        else:
            header = struct.pack("!BBQ", 0x81, 0x80 | 127, n)
        mask = os.urandom(4)
        keystream = (mask * (n // 4 + 1))[:n]
        masked = (int.from_bytes(payload, "big") ^ int.from_bytes(keystream, "big")).to_bytes(
            n, "big"
        )
        self._sock.sendall(header + mask + masked)

    def _read(self, n: int) -> bytes:
        data = self._in.read(n)
        if data is None or len(data) < n:
            raise BrowserError("the browser closed the DevTools connection")
        return data

    def recv(self) -> str:
        message = b""
        while True:
            first, second = self._read(2)
            opcode, length = first & 0x0F, second & 0x7F
            if length == 126:
                (length,) = struct.unpack("!H", self._read(2))
            elif length == 127:
                (length,) = struct.unpack("!Q", self._read(8))
            mask = self._read(4) if second & 0x80 else None
            payload = self._read(length)
            if mask:
                keystream = (mask * (length // 4 + 1))[:length]
                payload = bytes(a ^ b for a, b in zip(payload, keystream, strict=True))
            if opcode == 0x8:
                raise BrowserError("the browser closed the DevTools connection")
            if opcode == 0x9:  # ping: answer with a (masked, empty) pong
                self._sock.sendall(struct.pack("!BB", 0x8A, 0x80) + os.urandom(4))
                continue
            if opcode in (0x0, 0x1, 0x2):
                message += payload
                if first & 0x80:
                    return message.decode()

    def settimeout(self, seconds: float) -> None:
        self._sock.settimeout(seconds)

    def close(self) -> None:
        try:
            self._sock.close()
        except OSError:
            pass


class Page:
    """One page (tab) of the browser, driven over its DevTools WebSocket."""

    def __init__(self, websocket_url: str, timeout: float = 30.0):
        self._ws = _WebSocket(websocket_url, timeout)
        self._ids = itertools.count(1)
        self.timeout = timeout

    def call(self, method: str, **params) -> dict:
        """Send a DevTools command and return its result (events are skipped)."""
        command_id = next(self._ids)
        self._ws.send(json.dumps({"id": command_id, "method": method, "params": params}))
        while True:
            message = json.loads(self._ws.recv())
            if message.get("id") == command_id:
                if "error" in message:
                    raise BrowserError(f"{method}: {message['error'].get('message')}")
                return message.get("result", {})

    def navigate(self, url: str) -> None:
        self.call("Page.navigate", url=url)

    def evaluate(self, expression: str) -> Any:
        """Value of a JavaScript *expression* in the page (promises awaited)."""
        result = self.call(
            "Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True
        )
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            text = details.get("exception", {}).get("description") or details.get("text")
            raise BrowserError(f"script failed in the page: {text}")
        return result.get("result", {}).get("value")

    def wait_for(self, expression: str, *, timeout: float = 15.0, interval: float = 0.05) -> Any:
        """Evaluate *expression* every *interval* seconds until it is truthy; its value.

        Raises
        ------
        TimeoutError
            Still falsy after *timeout* seconds.
        """
        deadline = time.monotonic() + timeout
        while True:
            try:
                value = self.evaluate(expression)
            except BrowserError:
                value = None  # the page may be between documents
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f"not true after {timeout} s: {expression}")
            time.sleep(interval)

    def close(self) -> None:
        self._ws.close()


class HeadlessChromium:
    """A headless Chromium with a throw-away profile, as a context manager.

    Parameters
    ----------
    executable : str, optional
        Browser to run; default the first of :data:`BROWSERS` on PATH.
    width, height : int
        Window size. [px]
    start_timeout : float
        Seconds to wait for the DevTools port. [s]
    """

    def __init__(
        self,
        executable: str | None = None,
        *,
        width: int = 1400,
        height: int = 1000,
        start_timeout: float = 30.0,
    ):
        self.executable = executable or find_chromium()
        if self.executable is None:
            raise BrowserError(f"no browser found (tried {', '.join(BROWSERS)})")
        self.width, self.height, self.start_timeout = width, height, start_timeout
        self._process: subprocess.Popen | None = None
        self._profile: str | None = None
        self._port: int | None = None
        self._pages: list[Page] = []

    def __enter__(self) -> HeadlessChromium:
        self._profile = tempfile.mkdtemp(prefix="workbench-chromium-")
        log = open(Path(self._profile) / "browser.log", "wb")  # noqa: SIM115 (kept open)
        self._process = subprocess.Popen(
            [
                self.executable,
                *FLAGS,
                f"--user-data-dir={self._profile}",
                f"--window-size={self.width},{self.height}",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=log,
            stdin=subprocess.DEVNULL,
        )
        log.close()
        active = Path(self._profile) / "DevToolsActivePort"
        deadline = time.monotonic() + self.start_timeout
        while self._port is None:
            if self._process.poll() is not None:
                self._stop()
                raise BrowserError(f"{self.executable} exited with {self._process.returncode}")
            if time.monotonic() > deadline:
                self._stop()
                raise BrowserError(f"{self.executable} opened no DevTools port")
            try:
                self._port = int(active.read_text().split()[0])
            except (OSError, ValueError, IndexError):
                time.sleep(0.05)
        return self

    def __exit__(self, *exc) -> None:
        self._stop()

    def _targets(self) -> list[dict]:
        with urllib.request.urlopen(f"http://127.0.0.1:{self._port}/json/list", timeout=10) as r:
            return json.loads(r.read())

    def open(self, url: str) -> Page:
        """The browser's first tab, navigated to *url*."""
        deadline = time.monotonic() + self.start_timeout
        while True:
            pages = [t for t in self._targets() if t.get("type") == "page"]
            if pages:
                break
            if time.monotonic() > deadline:
                raise BrowserError("the browser has no page")
            time.sleep(0.05)
        page = Page(pages[0]["webSocketDebuggerUrl"])
        self._pages.append(page)
        page.navigate(url)
        return page

    def _stop(self) -> None:
        for page in self._pages:
            page.close()
        if self._process is not None and self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait(timeout=10)
        if self._profile is not None:
            shutil.rmtree(self._profile, ignore_errors=True)
            self._profile = None
