"""The dashboard under hostile or heavy use: security headers on every answer, a bounded
pool of threads, slow clients cut, a full queue answered 503 (issue 34, item 6).

Before: no CSP, frame or referrer policy; a thread per connection (60 slow clients, 67
threads) and a listen backlog of 5 (200 concurrent requests: slowest 27.9 s).
"""

from __future__ import annotations

import http.client
import socket
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from workbench.dashboard import DashboardOptions
from workbench.dashboard.server import SECURITY_HEADERS

from .conftest import publish
from .test_server import get


def _pool_threads() -> int:
    return sum(t.name.startswith("dashboard-") for t in threading.enumerate())


def _slow_clients(served, n: int, pause_s: float = 0.0) -> list[socket.socket]:
    """*n* connections that send half a request line and then nothing, *pause_s* apart."""
    host, port = served.server.server_address[:2]
    clients = []
    for _ in range(n):
        client = socket.create_connection((host, port), timeout=10)
        client.sendall(b"GET / HT")
        clients.append(client)
        time.sleep(pause_s)
    return clients


def _request(served, path: str = "api/status", timeout: float = 30.0):
    host, port = served.server.server_address[:2]
    connection = http.client.HTTPConnection(host, port, timeout=timeout)
    try:
        connection.request("GET", "/" + path)
        response = connection.getresponse()
        return response.status, dict(response.getheaders()), response.read()
    finally:
        connection.close()


@pytest.mark.parametrize("path", ["", "static/dashboard.js", "api/versions", "api/modes", "nope"])
def test_every_answer_carries_the_security_headers(tmp_path, voyage, serve, path):
    publish(voyage, tmp_path, 100)
    status, headers, _ = get(serve(tmp_path).url + path)
    assert status in (200, 404)
    for name, value in SECURITY_HEADERS.items():
        assert headers[name] == value, name
    policy = headers["Content-Security-Policy"]
    assert "default-src 'none'" in policy and "frame-ancestors 'none'" in policy
    assert "unsafe-inline" not in policy and "unsafe-eval" not in policy
    assert headers["X-Frame-Options"] == "DENY" and headers["Referrer-Policy"] == "no-referrer"


def test_a_not_modified_answer_carries_them_too(tmp_path, voyage, serve):
    publish(voyage, tmp_path, 100)
    served = serve(tmp_path)
    _, headers, _ = get(served.url + "api/modes")
    status, again, _ = get(served.url + "api/modes", {"If-None-Match": headers["ETag"]})
    assert status == 304
    assert all(again[name] == value for name, value in SECURITY_HEADERS.items())


def test_slow_clients_neither_add_threads_nor_hold_them(tmp_path, serve):
    options = DashboardOptions(threads=4, queued=8, request_seconds=1.0)
    served = serve(tmp_path, options)
    before = threading.active_count()
    clients = _slow_clients(served, 30)
    try:
        time.sleep(0.3)
        assert _pool_threads() == 4  # the pool, whatever the number of connections
        assert threading.active_count() == before
        # up to 4 taken and 8 waiting (fewer taken when they came faster than the threads
        # took them); the others refused at once with 503 and Retry-After
        refused = 0
        for client in clients:
            client.settimeout(5)
            head = client.recv(4096).decode("latin-1") if _readable(client) else ""
            if head.startswith("HTTP/1.1 503"):
                refused += 1
                assert "Retry-After: 1\r\n" in head
        assert 30 - 4 - 8 <= refused <= 30 - 8
        assert served.server.refused == refused
        # the slow ones are cut after request_seconds: a client that retries as told
        # (Retry-After) is served
        for _ in range(10):
            status, headers, body = _request(served)
            if status != 503:
                break
            time.sleep(float(headers["Retry-After"]))
        assert status == 200 and b"available" in body
        for client in clients:  # every slow connection was closed by the server
            client.settimeout(5)
            assert _drained(client)
    finally:
        for client in clients:
            client.close()


def _readable(client: socket.socket) -> bool:
    client.setblocking(False)
    try:
        return bool(client.recv(1, socket.MSG_PEEK))
    except BlockingIOError:
        return False
    finally:
        client.setblocking(True)


def _drained(client: socket.socket) -> bool:
    """True once the server has closed the connection (end of stream or reset)."""
    try:
        while client.recv(4096):
            pass
    except ConnectionResetError:
        pass
    except TimeoutError:
        return False
    return True


def test_a_full_queue_is_answered_503_with_retry_after(tmp_path, serve):
    served = serve(tmp_path, DashboardOptions(threads=1, queued=1, request_seconds=5.0))
    # one taken by the thread (which waits for its request), one queued
    clients = _slow_clients(served, 2, pause_s=0.2)
    try:
        time.sleep(0.2)
        status, headers, body = _request(served)
        assert status == 503 and headers["Retry-After"] == "1"
        assert headers["Content-Security-Policy"] == SECURITY_HEADERS["Content-Security-Policy"]
        assert b"busy" in body
    finally:
        for client in clients:
            client.close()


def test_two_hundred_concurrent_requests_are_all_answered(tmp_path, voyage, serve):
    """More connections at once than the default pool and queue hold: with the listen
    backlog of 128 every one is answered, none refused or dropped."""
    publish(voyage, tmp_path, 100)
    served = serve(tmp_path)
    assert served.server.request_queue_size >= 128
    with ThreadPoolExecutor(200) as pool:
        statuses = list(pool.map(lambda _: _request(served, "api/versions")[0], range(200)))
    # a 503 only when the queue was full (a busy machine), never a dropped connection
    assert sorted(set(statuses)) <= [200, 503]
    assert statuses.count(503) == served.server.refused
    assert statuses.count(200) > 100


@pytest.mark.parametrize(
    "field, value",
    [("threads", 0), ("threads", 2.5), ("queued", 0), ("request_seconds", 0.0)],
)
def test_limits_are_checked(field, value):
    with pytest.raises(ValueError, match=field) as caught:
        DashboardOptions(**{field: value})
    assert repr(value) in str(caught.value)


def test_closing_the_server_ends_connections_held_by_slow_clients(tmp_path):
    """server_close neither waits for the slow clients' requests nor leaves a thread."""
    from workbench.dashboard import make_server

    options = DashboardOptions(threads=2, queued=2, request_seconds=600.0)
    server = make_server(tmp_path, port=0, options=options)
    loop = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05})
    loop.start()

    class Held:  # what _slow_clients needs of a served dashboard
        pass

    held = Held()
    held.server = server
    clients = _slow_clients(held, 4, pause_s=0.05)  # two taken, two waiting
    try:
        time.sleep(0.2)
        server.shutdown()
        closing = threading.Thread(target=server.server_close)
        closing.start()
        closing.join(timeout=30)  # a bound for a busy machine; it takes milliseconds
        assert not closing.is_alive()
        assert not any(thread.is_alive() for thread in server._pool)
        for client in clients:
            client.settimeout(5)
            assert _drained(client)
    finally:
        for client in clients:
            client.close()
        loop.join(timeout=10)
