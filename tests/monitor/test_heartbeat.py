"""The monitor's heartbeat (issue 29, liveness): written every poll interval by a thread
of its own, naming the last file taken, and reporting a background worker that died.

The tiny voyage of the robustness tests (four channels, 60-s files, 2-minute blocks)
keeps each block to a fraction of a second.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import parse_arguments
from workbench.cli.monitoring import prepare_monitor
from workbench.dashboard.state import read_heartbeat
from workbench.monitor import Monitor


def _tiny_voyage():
    """``write_voyage`` of tests/robustness/voyage.py (that folder is another package)."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "robustness" / "voyage.py"
    spec = importlib.util.spec_from_file_location("robustness_voyage", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.write_voyage


write_voyage = _tiny_voyage()

POLL_S = 0.1
MONITOR_ARGS = [
    "--block-minutes", "2", "--step-minutes", "1", "--block-rows", "10",
    "--min-order", "4", "--max-order", "16", "--poll", str(POLL_S), "--settle", "0.1",
]  # fmt: skip


def _monitor(watch: Path, state: Path, *extra) -> Monitor:
    argv = ["monitor", "--watch", watch, "--state", state, *MONITOR_ARGS, *extra]
    return prepare_monitor(parse_arguments([str(a) for a in argv]))


def _beat(state: Path) -> dict:
    return read_heartbeat(state / "heartbeat.json")


def _wait(condition, timeout_s: float = 120.0):  # a bound for a busy machine
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            found = condition()
            if found:
                return found
        except (OSError, ValueError):  # renamed over while read: read again
            pass
        assert time.monotonic() < deadline, "timed out waiting for the monitor"
        time.sleep(0.02)


class _Running:
    """The monitor's loop in a thread."""

    def __init__(self, monitor: Monitor):
        self.monitor = monitor
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            self.monitor.run()
        except BaseException as error:  # noqa: BLE001 - re-raised in the test thread
            self.error = error

    def stop(self) -> None:
        self.monitor.stop_event.set()
        self.thread.join(timeout=120)
        self.monitor.close()
        if self.error is not None:
            raise self.error


def test_heartbeat_is_written_advances_during_a_block_and_names_the_last_file(
    tmp_path, monkeypatch
):
    watch, state = tmp_path / "watch", tmp_path / "state"
    files = write_voyage(watch, n_files=3)
    # each block takes 1.5 s (10 poll intervals) more: the heartbeat must not wait for it
    original = Monitor._process
    in_block = threading.Event()

    def slow_process(self, planned):
        in_block.set()
        time.sleep(1.5)
        original(self, planned)
        in_block.clear()

    monkeypatch.setattr(Monitor, "_process", slow_process)
    monitor = _monitor(watch, state, "--foreground")
    before = pd.Timestamp.now(tz="UTC")
    running = _Running(monitor)
    try:
        assert in_block.wait(60)
        time.sleep(2 * POLL_S)  # a heartbeat after the files were taken
        first = _beat(state)
        times = [pd.Timestamp(first["time"])]
        for _ in range(3):  # inside one 1.5-s block
            time.sleep(2 * POLL_S)
            times.append(pd.Timestamp(_beat(state)["time"]))
        assert in_block.is_set()  # still the same block
        gaps = pd.Series(times).diff().dropna().dt.total_seconds()
        assert (gaps > 0).all(), times  # it advances while the block runs
        assert gaps.max() < 2 * 2 * POLL_S + 0.5, gaps  # every poll interval (loose bound)
        assert first["pid"] == os.getpid() and first["host"]
        assert first["poll_s"] == POLL_S and first["state"] == "running"
        # the last file taken is the newest of the folder, taken after the start
        assert first["last_file"] == files[-1].name
        assert pd.Timestamp(first["last_file_taken_at"]) >= before.floor("s")
        assert first["worker"] == {"state": "none", "pid": None, "message": ""}
        # the main loop's activity: inside the block, named, since before this beat
        assert first["doing"].startswith("identifying block "), first["doing"]
        busy = (pd.Timestamp(first["time"]) - pd.Timestamp(first["doing_since"])).total_seconds()
        assert 0.0 <= busy < 60.0, busy
        assert first["stall_s"] == 300.0
    finally:
        running.stop()
    # a clean stop says so: a reader does not take it for a dead monitor
    last = _beat(state)
    assert last["state"] == "stopped" and last["last_file"] == files[-1].name
    assert json.loads((state / "status.json").read_text())["state"] == "stopped"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals as on Linux")
def test_a_killed_background_worker_is_reported_and_replaced(tmp_path):
    watch, state = tmp_path / "watch", tmp_path / "state"
    files = write_voyage(watch, n_files=6)
    write_voyage(tmp_path / "later", n_files=8)  # the same voyage, two files more
    running = _Running(_monitor(watch, state))  # background worker
    try:
        beat = _wait(lambda: (b := _beat(state))["worker"]["state"] == "alive" and b)
        worker = beat["worker"]["pid"]
        assert worker != os.getpid()
        os.kill(worker, signal.SIGKILL)
        # noticed: killed idle, the heartbeat says "stopped" until the next update;
        # killed at work, a new worker redoes the work at once, and the message stays
        stopped = _wait(lambda: f"pid {worker}" in (b := _beat(state))["worker"]["message"] and b)
        message = stopped["worker"]["message"]
        assert "killed by signal 9" in message and "stopped at" in message, message
        assert stopped["worker"]["state"] in ("stopped", "alive")
        assert (stopped["worker"]["state"] == "stopped") == (stopped["worker"]["pid"] == worker)
        # and the monitor's messages (status.json, the command's last lines) say it too
        assert message.split("; replaced")[0] in running.monitor.messages
        # new data: a new worker serves it, and the heartbeat says which one it replaced
        for name in ("acc_006.npz", "acc_007.npz"):
            os.replace(tmp_path / "later" / name, watch / name)
        again = _wait(
            lambda: (
                (b := _beat(state))["worker"]["state"] == "alive"
                and b["worker"]["pid"] != worker
                and b["last_file"] == "acc_007.npz"
                and b
            )
        )
        assert f"pid {worker}" in again["worker"]["message"]
        assert f"replaced by pid {again['worker']['pid']}" in again["worker"]["message"]
        assert files[-1].name == "acc_005.npz"
    finally:
        running.stop()
    status = json.loads((state / "status.json").read_text())
    assert status["state"] == "stopped"
