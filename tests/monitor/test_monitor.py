"""End-to-end tests of ``workbench monitor``: files fed into a folder at an accelerated
pace, the monitor's state tables compared with a batch run over the same files."""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.cli import parse_arguments
from workbench.cli.monitoring import prepare_monitor
from workbench.monitor import DATA_HEALTH_COLUMNS, FolderWatcher

from .conftest import (
    FORECAST,
    IDENTIFY,
    MONITOR_FAST,
    ShipLog,
    assert_same_tables,
    batch_run,
    cli,
    file_end,
    land,
    land_slowly,
    write_voyage,
)


def _monitor(watch: Path, state: Path, dship: Path, *extra):
    argv = ["monitor", "--watch", watch, "--state", state, "--dship", dship]
    argv += [*IDENTIFY, *FORECAST, *MONITOR_FAST, "--foreground", *extra]
    return prepare_monitor(parse_arguments([str(a) for a in argv]))


def _monitor_once(watch: Path, state: Path, dship: Path) -> int:
    """``workbench monitor --once`` over what is in *watch* (the CLI, as a restart would)."""
    return cli(
        "monitor", "--watch", watch, "--state", state, "--dship", dship,
        *IDENTIFY, *FORECAST, *MONITOR_FAST, "--once",
    )  # fmt: skip


def _wait(condition, timeout_s: float = 300.0) -> None:  # a bound, for busy machines
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            if condition():
                return
        except OSError:  # a state file renamed over while this test read it: read again
            pass
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting for the monitor")
        time.sleep(0.02)


class _Running:
    """The monitor's loop in a thread (the test thread feeds the folder)."""

    def __init__(self, monitor):
        self.monitor = monitor
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        try:
            self.monitor.run()
        except BaseException as error:  # noqa: BLE001 - re-raised in the test thread
            self.error = error

    def stop(self):
        self.monitor.stop_event.set()
        self.thread.join(timeout=300)
        self.monitor.close()
        if self.error is not None:
            raise self.error


def _status(state: Path) -> dict:
    return json.loads((state / "status.json").read_text(encoding="utf-8"))


def test_replayed_voyage_equals_batch(voyage, batch, tmp_path):
    """Files landing one by one (and a growing ship log) give the batch tables."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    log = ShipLog(voyage / "dship.tsv", tmp_path / "dship.tsv")
    files = sorted((voyage / "accelerations").glob("*.npz"))
    running = _Running(_monitor(watch, state, log.target))
    try:
        for path in files:
            land(path, watch)
            log.until(file_end(path))
            time.sleep(0.1)
        log.until(None)
        n_blocks = len(batch["blocks"])
        _wait(lambda: len(running.monitor.done) == n_blocks)
        # the newest predictors change while the log grows: the last outlook sees it whole
        _wait(lambda: not running.monitor._outlook_due)
    finally:
        running.stop()
    running.monitor.update_outlook()
    assert_same_tables(state, batch)
    # the shaft orders' lines for the dashboard: 1, 2, 3 x the logged shaft speed per block
    lines = pd.read_parquet(state / "harmonics.parquet")
    assert sorted(lines["order"].unique()) == [1.0, 2.0, 3.0]
    assert set(lines["block"]) == set(pd.read_parquet(state / "tracked.parquet")["block"])
    # the shore's key indicators of the day (the voyage is 1.5 h of one day): the tracked
    # table's medians per mode, and the forecast's residuals
    tracked = pd.read_parquet(state / "tracked.parquet")
    day = tracked["block_start"].iloc[0].strftime("%Y-%m-%d")
    assert sorted(p.name for p in (state / "shore").iterdir()) == [
        f"key_indicators_{day}.csv",
        f"key_indicators_{day}.json",
    ]
    indicators = pd.read_csv(state / "shore" / f"key_indicators_{day}.csv")
    medians = tracked.groupby("mode")["frequency_hz"].median()
    assert indicators["mode"].tolist() == medians.index.tolist()
    np.testing.assert_allclose(indicators["median_frequency_hz"], medians, rtol=1e-15)
    forecast = pd.read_parquet(state / "forecast.parquet")
    residual = (forecast["ssi_frequency_hz"] - forecast["model_frequency_hz"]).dropna()
    shown = indicators.set_index("mode")["median_model_residual_hz"].dropna()
    expected = residual.groupby(forecast["mode"]).median()
    assert len(shown) >= 1
    np.testing.assert_allclose(shown, expected.reindex(shown.index), rtol=1e-12)
    health = pd.read_parquet(state / "data_health.parquet")
    assert list(health.columns) == list(DATA_HEALTH_COLUMNS)
    assert health["block"].tolist() == list(range(n_blocks))
    assert (health["latency_s"] >= 0).all()
    assert (health["identified_at"] >= health["last_file_landed"]).all()
    # acc12 is dead for an hour from 40 % of the voyage: data health shows it
    assert health["dropped_channels"].str.contains("acc12").any()
    assert (health.loc[health["status"] == "ok", "n_channels"] >= 5).all()
    status = _status(state)
    assert status["state"] == "stopped" and status["blocks_done"] == n_blocks
    assert status["last_block"] == n_blocks - 1 and status["pid"] == os.getpid()
    for name in ("health.parquet", "alarms.parquet"):  # 1.5 h: no 6-h reference yet
        assert (state / name).exists() and pd.read_parquet(state / name).empty


def test_late_file_holds_its_blocks_and_partial_file_is_waited_for(voyage, batch, tmp_path):
    """A file landing after later ones is used as if in order; a file written in place is
    taken only once whole; tracking waits for the late blocks, identification does not."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    files = sorted((voyage / "accelerations").glob("*.npz"))
    running = _Running(_monitor(watch, state, voyage / "dship.tsv", "--late", "1800"))
    monitor = running.monitor
    try:
        for path in files[:6] + files[7:10]:  # file 6 is late
            land(path, watch)
        land_slowly(files[10], watch, pieces=5, pause_s=0.05)  # in place, in pieces
        # 5-min files, 20-min blocks: blocks 0-2 lie before the hole, 7 after it
        _wait(lambda: monitor.done >= {0, 1, 2, 7})
        time.sleep(0.3)
        assert monitor.done == {0, 1, 2, 7}
        assert monitor.tracked_through == 2
        assert pd.read_parquet(state / "tracked.parquet")["block"].max() <= 2
        land(files[6], watch)
        for path in files[11:]:
            land(path, watch)
        _wait(lambda: len(monitor.done) == len(batch["blocks"]))
    finally:
        running.stop()
    monitor.update_outlook()
    assert_same_tables(state, batch)
    assert not any("unreadable" in m for m in monitor.messages)


def test_file_later_than_the_window_is_not_used_for_decided_blocks(voyage, tmp_path):
    """With no patience (late 0), the blocks over a hole are skipped as soon as later
    data lands; the file arriving afterwards is reported and those blocks are not redone."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    files = sorted((voyage / "accelerations").glob("*.npz"))[:9]
    monitor = _monitor(watch, state, voyage / "dship.tsv", "--late", "0", "--settle", "0")
    try:
        for path in files[:4] + files[5:]:
            land(path, watch)
        monitor.step()
        health = pd.read_parquet(state / "data_health.parquet").set_index("block")
        assert health.loc[[1, 2, 3, 4], "status"].eq("skipped").all()
        assert health.loc[[1, 2, 3, 4], "reason"].str.contains("gap").all()
        assert health.loc[4, "gap_seconds"] == pytest.approx(300.0)
        assert health.loc[[0, 5], "status"].eq("ok").all()
        land(files[4], watch)
        assert monitor.step() == 0
        assert any("not redone" in m for m in monitor.messages)
    finally:
        monitor.close()
    stored = pd.read_parquet(state / "data_health.parquet")
    assert stored["block"].is_unique and len(stored) == 6


def test_watcher_takes_a_file_only_when_complete(voyage, tmp_path):
    source = sorted((voyage / "accelerations").glob("*.npz"))[0]
    data = source.read_bytes()
    watcher = FolderWatcher(tmp_path, settle_s=0.5)
    (tmp_path / f".{source.name}.tmp").write_bytes(data)  # a hidden temporary file
    partial = tmp_path / source.name
    partial.write_bytes(data[: len(data) // 2])
    assert watcher.poll() == ([], [])  # modified just now: left alone
    assert watcher.pending == {partial}
    old = time.time() - 5
    os.utime(partial, (old, old))  # a writer pausing longer than settle_s
    landed, messages = watcher.poll()
    assert landed == [] and len(messages) == 1 and "unreadable" in messages[0]
    assert watcher.poll() == ([], [])  # reported once
    with open(partial, "ab") as handle:
        handle.write(data[len(data) // 2 :])
    os.utime(partial, (old, old))
    landed, messages = watcher.poll()
    assert [f.path for f in landed] == [partial] and messages == []
    assert landed[0].info.n_samples == 300 * 64
    assert landed[0].landed == pd.Timestamp(partial.stat().st_mtime_ns, unit="ns", tz="UTC")


def test_kill_9_and_restart_lose_and_repeat_nothing(voyage, batch, tmp_path):
    """SIGKILL of a monitor process mid-run, then a restart: every block once, tables
    equal to the batch run."""
    import signal
    import subprocess
    import sys

    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    files = sorted((voyage / "accelerations").glob("*.npz"))
    argv = ["monitor", "--watch", watch, "--state", state, "--dship", voyage / "dship.tsv"]
    argv += [*IDENTIFY, *FORECAST, *MONITOR_FAST, "--foreground"]
    code = "import sys; from workbench.cli import main; sys.exit(main(sys.argv[1:]))"
    process = subprocess.Popen([sys.executable, "-c", code, *map(str, argv)])
    fed = 9  # six blocks' worth; killed after the third is stored
    try:
        for path in files[:fed]:
            land(path, watch)
            time.sleep(0.05)
        rows = state / "data_health.parquet"
        _wait(lambda: rows.exists() and len(pd.read_parquet(rows)) >= 3)
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    before = pd.read_parquet(state / "data_health.parquet")
    assert 3 <= len(before) <= 6
    assert _status(state)["state"] == "running"  # it never got to say it stopped
    for path in files[fed:]:
        land(path, watch)
    assert _monitor_once(watch, state, voyage / "dship.tsv") == 0
    assert_same_tables(state, batch)
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["block"].tolist() == list(range(len(batch["blocks"])))
    # blocks identified before the kill kept their rows (not identified again)
    kept = health.set_index("block").loc[before["block"], "identified_at"]
    assert (kept.to_numpy() == before["identified_at"].to_numpy()).all()
    store_blocks = pd.concat(
        pd.read_parquet(p) for p in (state / "store" / "blocks").glob("day=*/*.parquet")
    )
    assert store_blocks["block"].is_unique
    assert _status(state)["state"] == "stopped"


def test_decimated_files_are_conditioned_once_and_equal_batch(tmp_path):
    """128-Hz files decimated to 64 Hz: each file conditioned once, although every file
    lies in four blocks; a block waits for the file after it (its filters' padding), and
    the tables equal the batch run's."""
    voyage = write_voyage(tmp_path / "v128", rate_hz=128.0, seed=4, hours=1.0)
    batch = batch_run(voyage, tmp_path / "batch")
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    files = sorted((voyage / "accelerations").glob("*.npz"))
    running = _Running(_monitor(watch, state, voyage / "dship.tsv"))
    monitor = running.monitor
    try:
        for path in files[:5]:
            land(path, watch)
        _wait(lambda: monitor.done == {0})  # block 1 (files 1-4) waits for file 5
        time.sleep(0.3)
        assert monitor.done == {0}
        for path in files[5:]:
            land(path, watch)
            time.sleep(0.05)
        _wait(lambda: len(monitor.done) == len(batch["blocks"]) - 1)
        assert max(monitor.done) == len(batch["blocks"]) - 2  # the last waits for more
    finally:
        running.stop()
    assert _monitor_once(watch, state, voyage / "dship.tsv") == 0
    assert_same_tables(state, batch, min_rows=10)
    # the live run conditioned every file but the last (its block waited) exactly once
    assert monitor.conditioned_files[0] == len(files) - 1


def test_sigterm_stops_cleanly(voyage, tmp_path):
    """SIGTERM mid-run: exit status 0, status.json says stopped, the blocks stored are
    exactly those data_health lists."""
    import signal
    import subprocess
    import sys

    state = tmp_path / "state"
    argv = ["monitor", "--watch", voyage / "accelerations", "--state", state]
    argv += ["--dship", voyage / "dship.tsv", *IDENTIFY, *FORECAST, *MONITOR_FAST]
    code = "import sys; from workbench.cli import main; sys.exit(main(sys.argv[1:]))"
    process = subprocess.Popen(
        [sys.executable, "-c", code, *map(str, argv)], stdout=subprocess.PIPE, text=True
    )
    try:
        rows = state / "data_health.parquet"
        _wait(lambda: rows.exists() and len(pd.read_parquet(rows)) >= 2)
        process.send_signal(signal.SIGTERM)
        out, _ = process.communicate(timeout=300)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0
    status = _status(state)
    assert status["state"] == "stopped" and status["pid"] == process.pid
    health = pd.read_parquet(state / "data_health.parquet")
    assert status["blocks_done"] == len(health) >= 2
    assert f"{len(health)} block(s) decided" in out


def test_settings_from_a_ship_configuration(voyage, tmp_path):
    """--config fills what flags do not give, from the sections the batch commands read;
    flags win."""
    from workbench.config import write_config

    config = write_config(
        tmp_path / "ship.toml",
        {
            "output": {"dir": "out"},
            "accelerations": {"inputs": [str(voyage / "accelerations")]},
            "dship": {"file": str(voyage / "dship.tsv")},
            "blocks": {"length_minutes": 20, "step_minutes": 5},
            "identify": {"band": [2.0, 12.0], "block_rows": 8, "max_order": 20, "blades": 5},
            "track": {"mac_min": 0.85},
            "forecast": {"option": "AB", "train_blocks": 6, "scheme": 2},
        },
    )
    argv = ["monitor", "--config", str(config), "--train-blocks", "7"]
    monitor = prepare_monitor(parse_arguments(argv))
    try:
        options = monitor.options
        assert monitor.watch == voyage / "accelerations"
        assert monitor.dship == voyage / "dship.tsv"
        assert monitor.state == tmp_path / "out" / "monitor"
        assert options.identify.band_hz == (2.0, 12.0) and options.identify.block_rows == 8
        assert max(options.identify.orders) == 20
        assert options.tracking.mac_min == 0.85
        # the blade pass is marked as identify --blades marks it (issue 29: the 12-h demo's
        # 10.58 Hz blade pass was a mode in the monitor's table, not in track's)
        assert options.harmonics.blades == 5 and options.harmonics.orders == (1.0, 2.0, 3.0)
        assert options.forecast.forecast.options == ("A", "B")
        assert options.forecast.forecast.train_blocks == 7
    finally:
        monitor.close()


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["monitor", "--state", "s"], "--watch"),
        (["monitor", "--watch", "nowhere", "--state", "s"], "no such folder"),
        (["monitor", "--watch", ".", "--state", "s", "--poll", "0"], "--poll 0.0"),
        # --block-minutes auto is monitored (test_adaptive_monitor.py); its bad values not
        (
            ["monitor", "--watch", ".", "--state", "s", "--once", "--block-minutes", "fast"],
            "--block-minutes 'fast' is not a number of minutes or 'auto'",
        ),
    ],
)
def test_usage_errors_exit_2(argv, needle, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli(*argv) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_once_on_a_folder_without_data_is_an_error(tmp_path, capsys):
    (tmp_path / "watch").mkdir()
    assert cli("monitor", "--watch", tmp_path / "watch", "--state", tmp_path / "s", "--once") == 1
    assert "no complete acceleration file" in capsys.readouterr().err
    assert _status(tmp_path / "s")["state"] == "stopped"
