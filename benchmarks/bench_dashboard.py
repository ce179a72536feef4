"""Benchmark: from a block published into the state folder to the browser showing it.

A simulated voyage (:func:`workbench.dashboard.demo_state`: block-level voyage, frozen
stepwise forecast with Kalman blending, health chart) is published into a state folder up
to a start block; a dashboard server runs in this process and a headless chromium
(Debian's, driven over the DevTools protocol) keeps its page open. Then, block after
block, at a random phase of the page's polling, the next block is published (all six
state files, atomically, as the monitor does) and the time is taken until the page has
drawn that block in the mode cards, the tracked-frequency plot, the health chart and the
data-health panel. The clock starts before the first file is written and stops at the
page's own render timestamp (``Date.now()`` in the page, the same wall clock).

Printed per polling interval: median, 90th percentile and worst latency over the blocks,
the time to write the state files, and the server's time to build the panels' JSON.

Run: ``python benchmarks/bench_dashboard.py --blocks 30 --poll 1.0 0.25``
(``--hours 168`` for a week-long state folder: larger tables to read per block).
"""

from __future__ import annotations

import argparse
import dataclasses
import random
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

from workbench.dashboard import DashboardOptions, demo_state, make_server
from workbench.dashboard.browser import HeadlessChromium, find_chromium
from workbench.dashboard.server import PANELS

SHOWN = ("modes", "tracked", "health", "data_health")


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def run(voyage, folder: Path, *, poll: float, blocks: int, start: int, seed: int) -> dict:
    state = dataclasses.replace(voyage, folder=folder, written_block=None)
    state.write(start)
    server = make_server(folder, port=0, options=DashboardOptions(poll_seconds=poll))
    thread = threading.Thread(
        target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
    )
    thread.start()
    rng = random.Random(seed)
    latency, writes, builds = [], [], []
    try:
        with HeadlessChromium() as browser:
            page = browser.open(server.url)
            page.wait_for(f"document.getElementById('modes').dataset.block === '{start}'")
            for _ in range(blocks):
                time.sleep(rng.uniform(0.0, poll))  # a random phase of the polling
                t0 = time.time()
                block = state.append()
                writes.append(time.time() - t0)
                condition = " && ".join(
                    f"document.getElementById('{p}').dataset.block === '{block}'" for p in SHOWN
                )
                page.wait_for(condition, timeout=60, interval=0.02)
                drawn = page.evaluate(
                    "Math.max("
                    + ", ".join(f"window.dashboard.rendered.{p}.at" for p in SHOWN)
                    + ")"
                )
                latency.append(drawn / 1000.0 - t0)
                # server side: build every panel again from the files (cache bypassed)
                fresh = make_server(folder, port=0)
                t1 = time.perf_counter()
                for name in PANELS:
                    fresh.answer(name)
                builds.append(time.perf_counter() - t1)
                fresh.server_close()
    finally:
        server.shutdown()
        server.server_close()
    return {"latency": latency, "write": writes, "build": builds}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=30, help="blocks published (>= 20)")
    parser.add_argument("--poll", type=float, nargs="+", default=[1.0], help="page polling [s]")
    parser.add_argument("--hours", type=float, default=24.0, help="voyage length [h]")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if find_chromium() is None:
        print("chromium not found (apt-get install chromium)", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        voyage = demo_state(Path(tmp) / "voyage", hours=args.hours, blocks=0, seed=args.seed)
        start = voyage.last_block - args.blocks
        n_rows = len(voyage.tracked[voyage.tracked["block"] <= voyage.last_block])
        print(
            f"voyage {args.hours:g} h, blocks {start + 1}-{voyage.last_block} published one by "
            f"one; tracked table up to {n_rows} rows"
        )
        print(
            f"{'poll [s]':>8}  {'median [s]':>10}  {'p90 [s]':>8}  {'worst [s]':>9}  "
            f"{'write [s]':>9}  {'build [s]':>9}"
        )
        for poll in args.poll:
            result = run(
                voyage,
                Path(tmp) / f"state-{poll:g}",
                poll=poll,
                blocks=args.blocks,
                start=start,
                seed=args.seed,
            )
            lat = result["latency"]
            print(
                f"{poll:8.2f}  {statistics.median(lat):10.3f}  {_percentile(lat, 0.9):8.3f}  "
                f"{max(lat):9.3f}  {statistics.median(result['write']):9.3f}  "
                f"{statistics.median(result['build']):9.3f}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
