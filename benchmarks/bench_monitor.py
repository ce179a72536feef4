"""Benchmark: ``workbench monitor`` on the demo voyage replayed at 100x speed (issue 20).

1. The demo voyage (12 h, 144 five-minute files of 19 channels at 64 Hz, seed 0) is
   simulated (not timed) and run in batch the way a user does: ``identify --band 2 12``,
   ``track``, ``forecast`` with the demo's forecast settings (options A and B, method 2,
   20 training blocks, trust 0.65).
2. The files are replayed into a watched folder at ``--speed`` (100: a 5-min file every
   3 s), each landing as a recorder writes it (hidden temporary name, then rename) when
   its last sample is due, and the ship log grows with them. ``workbench monitor`` runs in
   its own process with the same settings.
3. A reader thread polls ``<state>/tracked.parquet`` (every 50 ms) and notes when each
   block first appears in it. Latency of a block = that moment minus the modification
   time of the block's last file (when it landed).
4. At the end the monitor gets SIGTERM (clean stop); its tracked and forecast tables are
   compared with the batch tables (``pandas.testing.assert_frame_equal``: equal or not).

Printed and written to ``benchmarks/results/monitor_replay.txt``: equality, latency
(median, 90th percentile, worst), the monitor's CPU per block (whole process tree, and the
identification alone), the cost of recomputing the forecast and health chart against the
number of blocks, and the machine's load (the machine is shared: latencies include
waiting for a core).

With ``--dashboard`` the whole bridge chain is measured end to end: a dashboard server
(:mod:`workbench.dashboard`) runs in this process on the monitor's state folder and a
headless chromium (Debian's, :mod:`workbench.dashboard.browser`) keeps its page open; a
second reader polls the page (every 50 ms) for what each panel has drawn and the page's
own render timestamp (``window.dashboard.rendered``, ``Date.now()``: the same wall clock).
A block is shown by a panel from the first render of that block or a later one. Latency =
that render time minus the landing time of the block's last file, per panel: mode cards
and tracked-frequency plot (from ``tracked.parquet``), health chart (from the background
forecast process), data health. Written to ``monitor_dashboard.txt`` and
``monitor_dashboard.latency.csv`` instead.

Run: ``python benchmarks/bench_monitor.py`` (``--data DIR`` keeps the voyage and batch
results between runs; ``--hours 2`` for a quick look; ``--dashboard`` end to end).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from child_library import pin_library  # noqa: E402

pin_library()  # child processes import this library, not the current folder's

FORECAST = ["--train-blocks", "20", "--trust", "0.65"]
IDENTIFY = ["--band", "2", "12"]
#: The health chart's operational model on the first 4 h, its reference on the next 3 h:
#: the chart starts 7 h into the 12-h demo (the defaults, 12 h + 6 h, suit real voyages)
HEALTH = ["--health-train-hours", "4", "--reference-hours", "3"]


def _cli(*argv) -> None:
    command = [sys.executable, "-m", "workbench.cli", *map(str, argv)]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr}")


def _prepare(root: Path, hours: float, option: str) -> tuple[Path, Path, float]:
    """Simulated voyage and its batch tables (reused when present)."""
    from workbench.simulate import simulate_voyage

    voyage = root / f"voyage_{hours:g}h"
    if not (voyage / "voyage.json").is_file():
        print(f"simulating a {hours:g}-h voyage into {voyage} (not timed) ...", flush=True)
        simulate_voyage(voyage, seed=0, hours=hours)
    batch = root / f"batch_{hours:g}h_{option}"
    started = time.perf_counter()
    if not (batch / "forecast.parquet").is_file():
        print("batch: identify + track + forecast ...", flush=True)
        _cli("identify", voyage / "accelerations", "--out", batch / "id", *IDENTIFY, "--quiet")
        _cli("track", batch / "id" / "selected.parquet", "--out", batch / "tracked.parquet")
        poles = ["--poles", batch / "id" / "poles.parquet"] if "B" in option else []
        _cli(
            "forecast", "--modal", batch / "tracked.parquet", "--dship", voyage / "dship.tsv",
            "--option", option, *poles, *FORECAST, "--out", batch / "forecast.parquet",
            "--quiet",
        )  # fmt: skip
    return voyage, batch, time.perf_counter() - started


class _ShipLog:
    """The ship log written as it grows (header, then rows up to a time)."""

    def __init__(self, source: Path, target: Path):
        lines = source.read_text(encoding="utf-8").splitlines(keepends=True)
        end = next(i for i, line in enumerate(lines) if line.startswith("*/"))
        self.rows = lines[end + 2 :]
        self.times = pd.to_datetime([r.split("\t", 1)[0] for r in self.rows], utc=True)
        self.target = target
        self.written = 0
        target.write_text("".join(lines[: end + 2]), encoding="utf-8")

    def until(self, time_: pd.Timestamp | None) -> None:
        stop = len(self.rows) if time_ is None else int(np.searchsorted(self.times, time_))
        if stop > self.written:
            with open(self.target, "a", encoding="utf-8") as handle:
                handle.writelines(self.rows[self.written : stop])
            self.written = stop


class _Reader(threading.Thread):
    """Notes when each block first appears in tracked.parquet."""

    def __init__(self, path: Path):
        super().__init__(daemon=True)
        self.path = path
        self.first_seen: dict[int, float] = {}
        self.stop = threading.Event()

    def run(self) -> None:
        last = None
        while not self.stop.is_set():
            try:
                key = self.path.stat().st_mtime_ns
                if key != last:
                    blocks = pd.read_parquet(self.path, columns=["block"])["block"].unique()
                    now = time.time()
                    last = key
                    for block in blocks:
                        self.first_seen.setdefault(int(block), now)
            except (OSError, ValueError):
                pass
            self.stop.wait(0.05)


#: Panels whose drawn block is followed with ``--dashboard`` (section ids of the page).
PANELS = ("modes", "tracked", "health", "data_health")


class _PageReader(threading.Thread):
    """A dashboard server on the state folder and a headless chromium page open on it;
    notes when the page first drew each block (or a later one) in each panel."""

    def __init__(self, state: Path, poll: float):
        super().__init__(daemon=True)
        self.state, self.poll = state, poll
        self.first_shown: dict[str, dict[int, float]] = {name: {} for name in PANELS}
        self.renders = 0
        self.error: BaseException | None = None
        self.ready = threading.Event()
        self.stop = threading.Event()

    def run(self) -> None:
        from workbench.dashboard import DashboardOptions, make_server
        from workbench.dashboard.browser import HeadlessChromium

        server = make_server(self.state, port=0, options=DashboardOptions(poll_seconds=self.poll))
        serving = threading.Thread(
            target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
        )
        serving.start()
        seen: dict[str, float] = {}
        try:
            with HeadlessChromium() as browser:
                page = browser.open(server.url)
                page.wait_for("window.dashboard && window.dashboard.polls > 0", timeout=60)
                self.ready.set()
                while not self.stop.is_set():
                    rendered = page.evaluate("JSON.stringify(window.dashboard.rendered)")
                    for name, drawn in json.loads(rendered or "{}").items():
                        if name not in self.first_shown or drawn["at"] == seen.get(name):
                            continue
                        seen[name] = drawn["at"]
                        self.renders += 1
                        if drawn["value"] is None:
                            continue
                        shown = self.first_shown[name]
                        for block in range(int(drawn["value"]) + 1):
                            shown.setdefault(block, drawn["at"] / 1000.0)
                    self.stop.wait(0.05)
        except BaseException as error:  # reported by the caller
            self.error = error
            self.ready.set()
        finally:
            server.shutdown()
            server.server_close()


def _replay(
    voyage: Path,
    batch: Path,
    work: Path,
    speed: float,
    option: str,
    poll: float,
    settle: float,
    dashboard: float | None = None,
):
    from workbench.signals.block_plan import read_file_info

    watch, state = work / "watch", work / "state"
    shutil.rmtree(work, ignore_errors=True)
    watch.mkdir(parents=True)
    log = _ShipLog(voyage / "dship.tsv", work / "dship.tsv")
    files = sorted((voyage / "accelerations").glob("*.npz"))
    ends = [read_file_info(p).end_time for p in files]
    starts = [read_file_info(p).start_time for p in files]
    command = [
        sys.executable, "-m", "workbench.cli", "monitor", "--watch", str(watch),
        "--state", str(state), "--dship", str(log.target), "--option", option,
        *IDENTIFY, *FORECAST, *HEALTH, "--poll", str(poll), "--settle", str(settle),
    ]  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    stderr = open(work / "monitor.log", "w", encoding="utf-8")  # noqa: SIM115
    process = subprocess.Popen(command, stderr=stderr, stdout=subprocess.DEVNULL)
    reader = _Reader(state / "tracked.parquet")
    reader.start()
    page = None
    if dashboard is not None:
        state.mkdir(parents=True, exist_ok=True)
        page = _PageReader(state, dashboard)
        page.start()
        page.ready.wait(90)
        if page.error is not None:
            raise SystemExit(f"dashboard page could not be followed: {page.error}")
    time.sleep(3.0)  # the monitor's start-up (imports) is not part of a block's latency
    origin = time.time()
    t0 = starts[0]
    print(f"replaying {len(files)} files at {speed:g}x ...", flush=True)
    for path, end in zip(files, ends, strict=True):
        due = origin + (end - t0).total_seconds() / speed
        time.sleep(max(0.0, due - time.time()))
        tmp = watch / f".{path.name}.part"
        shutil.copyfile(path, tmp)
        os.replace(tmp, watch / path.name)
        log.until(end)
    log.until(None)
    replay_s = time.time() - origin
    expected = len(pd.read_csv(batch / "id" / "blocks.csv"))
    deadline = time.time() + 600
    status = {}
    while time.time() < deadline:
        try:
            status = json.loads((state / "status.json").read_text())
        except (OSError, ValueError):
            status = {}
        if status.get("blocks_done") == expected:
            break
        time.sleep(0.2)
    drain_s = time.time() - origin - replay_s
    time.sleep(2.0 if page is None else 10.0)  # the page: one more poll, background forecast
    process.send_signal(signal.SIGTERM)
    code = process.wait(timeout=600)
    stderr.close()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    reader.stop.set()
    reader.join()
    if page is not None:
        page.stop.set()
        page.join(timeout=60)
        if page.error is not None:
            raise SystemExit(f"dashboard page failed during the replay: {page.error}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    status = json.loads((state / "status.json").read_text())
    shown = None if page is None else page.first_shown
    return state, reader.first_seen, shown, cpu, code, status, expected, replay_s, drain_s


def _equal(state: Path, batch: Path) -> dict[str, str]:
    out = {}
    for name in ("tracked", "forecast"):
        try:
            pd.testing.assert_frame_equal(
                pd.read_parquet(state / f"{name}.parquet"),
                pd.read_parquet(batch / f"{name}.parquet"),
            )
            out[name] = "yes"
        except AssertionError as error:
            out[name] = "NO (" + str(error).splitlines()[0] + ")"
    return out


def _page_latency(
    shown: dict[str, dict[int, float]], landed: pd.Series, blocks: pd.Index, poll: float
) -> tuple[pd.DataFrame, list[str]]:
    """Latency last file landed -> drawn on the page, per panel, and the report's lines."""
    columns = {}
    for name, first in shown.items():
        columns[f"page_{name}_s"] = pd.Series(
            {b: first[b] - landed[b].timestamp() for b in landed.index if b in first},
            dtype=float,
        )
    table = pd.DataFrame(columns).reindex(landed.index)
    # a block is on the bridge when both the mode cards and the tracked plot show it
    table.insert(0, "page_shown_s", table[["page_modes_s", "page_tracked_s"]].max(axis=1))

    def stats(values: pd.Series) -> str:
        values = values.dropna()
        if values.empty:
            return "never drawn (the panel was still waiting for data)"
        return (
            f"median {values.median():.2f} s, 90th percentile {values.quantile(0.9):.2f} s, "
            f"worst {values.max():.2f} s (block {int(values.idxmax())}; {len(values)} blocks)"
        )

    # the health chart starts when the reference period is learned: the blocks drawn in its
    # first render before the newest one waited for that, not for the display
    health = shown["health"]
    health_from = max((b for b, t in health.items() if t == min(health.values())), default=0)
    tracked = table["page_shown_s"].reindex(blocks)
    lines = [
        f"END TO END, last file landed -> dashboard page shows the block (mode cards and "
        f"tracked-frequency plot, headless chromium, page polling {poll:g} s): " + stats(tracked),
        f"  from block 3 on: {stats(tracked.loc[3:])}; blocks never shown: "
        f"{int(tracked.isna().sum())}",
        f"  per panel: mode cards {stats(table['page_modes_s'])}",
        f"             tracked plot {stats(table['page_tracked_s'])}",
        f"             health chart (background forecast + health), from block "
        f"{health_from} (the chart's first, once the reference period is learned; the blocks "
        f"before it appear all at once then): {stats(table['page_health_s'].loc[health_from:])}",
        f"             data health {stats(table['page_data_health_s'])}",
    ]
    return table, lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=12.0)
    parser.add_argument("--speed", type=float, default=100.0)
    parser.add_argument("--option", default="AB", choices=("A", "B", "AB"))
    parser.add_argument("--poll", type=float, default=0.25)
    parser.add_argument("--settle", type=float, default=0.5)
    parser.add_argument("--data", type=Path, help="folder to keep voyage and batch results in")
    parser.add_argument(
        "--dashboard",
        nargs="?",
        type=float,
        const=1.0,
        metavar="POLL_S",
        help="end to end: a dashboard on the state folder, followed in headless chromium "
        "(page polling every POLL_S seconds, default 1: the dashboard's default)",
    )
    parser.add_argument("--out", type=Path, help="report file (default in benchmarks/results)")
    args = parser.parse_args()
    results = Path(__file__).parent / "results"
    if args.out is None:
        name = "monitor_replay.txt" if args.dashboard is None else "monitor_dashboard.txt"
        args.out = results / name
    if args.dashboard is not None:
        from workbench.dashboard.browser import find_chromium

        if find_chromium() is None:
            print("chromium not found (apt-get install chromium)", file=sys.stderr)
            raise SystemExit(1)
    root = args.data or Path(tempfile.mkdtemp(prefix="bench_monitor_"))
    root.mkdir(parents=True, exist_ok=True)
    voyage, batch, batch_s = _prepare(root, args.hours, args.option)
    state, first_seen, shown, cpu, code, status, expected, replay_s, drain_s = _replay(
        voyage,
        batch,
        root / "replay",
        args.speed,
        args.option,
        args.poll,
        args.settle,
        args.dashboard,
    )
    health = pd.read_parquet(state / "data_health.parquet")
    landed = health.set_index("block")["last_file_landed"]
    latency = pd.Series(
        {b: first_seen[b] - landed[b].timestamp() for b in landed.index if b in first_seen}
    ).sort_index()
    equal = _equal(state, batch)
    text = (state.parent / "monitor.log").read_text(encoding="utf-8")
    ident = np.array([float(m) for m in re.findall(r"identification CPU ([\d.]+) s", text)])
    outlook = [
        (int(n), float(s), float(c))
        for n, s, c in re.findall(r"outlook: (\d+) blocks, \d+ forecast rows, ([\d.]+) s "
                                  r"\(CPU ([\d.]+) s\)", text)
    ]  # fmt: skip
    lines = [
        f"workbench monitor: {args.hours:g}-h demo voyage replayed at {args.speed:g}x "
        f"(option {args.option}, poll {args.poll:g} s, settle {args.settle:g} s)",
        f"machine: {os.cpu_count()} cores, load average at the end "
        + " ".join(f"{v:.1f}" for v in os.getloadavg()),
        f"blocks: {expected} in the batch run; monitor decided {status['blocks_done']}, "
        f"state '{status['state']}', exit status {code}",
        f"replay {replay_s:.1f} s; last block stored {drain_s:.1f} s after the last file",
        f"tables equal to batch (identify + track + forecast): tracked {equal['tracked']}, "
        f"forecast {equal['forecast']}",
        f"latency, last file landed -> block in tracked.parquet ({len(latency)} blocks with "
        f"tracked modes): median {latency.median():.2f} s, 90th percentile "
        f"{latency.quantile(0.9):.2f} s, worst {latency.max():.2f} s (block "
        f"{int(latency.idxmax())})",
        f"  from block 3 on (a new mode enters the tracked table once seen in 3 blocks, "
        f"so blocks 0-2 wait for block 2): median {latency.loc[3:].median():.2f} s, worst "
        f"{latency.loc[3:].max():.2f} s",
        f"latency, last file landed -> identified (data_health.latency_s): median "
        f"{health['latency_s'].median():.2f} s, worst {health['latency_s'].max():.2f} s",
        f"CPU of the monitor's process tree: {cpu:.1f} s = {cpu / max(expected, 1):.2f} s per "
        f"block (with start-up, the background forecast process, the final outlook)",
    ]
    if ident.size:
        lines.append(
            f"identification CPU per block: median {np.median(ident):.3f} s, worst "
            f"{ident.max():.3f} s"
        )
    if outlook:
        n, s, c = zip(*outlook, strict=True)
        lines.append(
            f"forecast + health recomputed {len(outlook)} times (background process, "
            f"coalesced): at {n[0]} blocks {s[0]:.2f} s (CPU {c[0]:.2f}), at {n[len(n) // 2]} "
            f"blocks {s[len(s) // 2]:.2f} s (CPU {c[len(c) // 2]:.2f}), at {n[-1]} blocks "
            f"{s[-1]:.2f} s (CPU {c[-1]:.2f}); CPU per block of table "
            f"{c[-1] / max(n[-1], 1) * 1000:.1f} ms"
        )
    lines.append(f"batch reference computed in {batch_s:.1f} s (0 when reused)")
    if shown is not None:
        on_page, page_lines = _page_latency(shown, landed, latency.index, args.dashboard)
        lines[0] += f", dashboard page polling every {args.dashboard:g} s"
        lines[5:5] = page_lines
        latency = pd.concat([latency.rename("tracked_parquet_s"), on_page], axis=1)
    report = "\n".join(lines)
    print(report)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(report + "\n", encoding="utf-8")
    if isinstance(latency, pd.Series):
        latency = latency.rename("latency_s")
    latency.rename_axis("block").to_csv(args.out.with_suffix(".latency.csv"), header=True)


if __name__ == "__main__":
    main()
