"""Benchmark: the dashboard server under slow clients and many concurrent requests.

A dashboard server over an empty state folder runs in this process. First *slow*
clients connect and send half a request line, then nothing (a stalled or hostile
client); the server's thread count is read. Then *requests* clients at once each open a
connection and ask for ``/api/status``, while the slow clients are still connected, and
again after they are gone. Printed: thread counts, each burst's median, 95th percentile
and slowest time to an answer, and the answers' status codes (a 503 carries
Retry-After: a polite refusal, not a failure).

Run: ``python benchmarks/bench_dashboard_load.py --slow 60 --requests 200``
"""

from __future__ import annotations

import argparse
import http.client
import socket
import tempfile
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor

from workbench.dashboard import make_server


def _one(address) -> tuple[float, object]:
    started = time.perf_counter()
    try:
        connection = http.client.HTTPConnection(*address, timeout=60)
        connection.request("GET", "/api/status")
        response = connection.getresponse()
        response.read()
        connection.close()
        return time.perf_counter() - started, response.status
    except OSError as error:
        return time.perf_counter() - started, type(error).__name__


def _burst(address, n: int) -> str:
    with ThreadPoolExecutor(n) as pool:
        results = list(pool.map(lambda _: _one(address), range(n)))
    seconds = sorted(r[0] for r in results)
    codes = dict(sorted(Counter(str(r[1]) for r in results).items()))
    return (
        f"median {seconds[n // 2]:.3f} s, p95 {seconds[int(0.95 * n) - 1]:.3f} s, "
        f"slowest {seconds[-1]:.3f} s, answers {codes}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--slow", type=int, default=60)
    parser.add_argument("--requests", type=int, default=200)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        server = make_server(folder, port=0)
        thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05})
        thread.start()
        address = server.server_address[:2]
        idle = threading.active_count()
        slow = []
        for _ in range(args.slow):
            client = socket.create_connection(address)
            client.sendall(b"GET / HT")
            slow.append(client)
        time.sleep(1.0)
        print(f"threads: {idle} idle, {threading.active_count()} with {args.slow} slow clients")
        print(f"{args.requests} concurrent requests beside the slow clients: ", end="")
        print(_burst(address, args.requests))
        for client in slow:
            client.close()
        time.sleep(0.5)
        print(f"{args.requests} concurrent requests alone: {_burst(address, args.requests)}")
        server.shutdown()
        server.server_close()
        thread.join()


if __name__ == "__main__":
    main()
