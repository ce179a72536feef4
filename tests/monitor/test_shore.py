"""What the monitor hands on (issue 29 item 5): the ``--on-alarm`` hook, the daily key
indicators for the shore, and the tracked lines that are shaft harmonics."""

from __future__ import annotations

import json
import sys
import time

import numpy as np
import pandas as pd
import pytest

from data_contracts import ALARMS, MODAL, write_table
from workbench.monitor import Monitor, MonitorOptions
from workbench.monitor.outlook import OutlookReport
from workbench.monitor.shore import (
    INDICATOR_COLUMNS,
    AlarmHook,
    parse_command,
    write_daily_indicators,
)

#: A hook that appends what it got on stdin (one JSON per line) to the file in argv[1].
RECORDER = (
    "import sys, json; message = json.load(sys.stdin); "
    "open(sys.argv[1], 'a').write(json.dumps(message) + '\\n')"
)


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The dashboard's 24-h demo voyage (alarm on mode 3 from block 265), moved 12 h later
    so that it spans two UTC days."""
    from workbench.dashboard import demo_state

    voyage = demo_state(tmp_path_factory.mktemp("demo"), blocks=0, seed=0)
    shift = pd.Timedelta(hours=12)
    tracked = voyage.tracked.assign(
        block_start=voyage.tracked["block_start"] + shift,
        block_end=voyage.tracked["block_end"] + shift,
    )
    forecast = voyage.forecast.assign(block_start=voyage.forecast["block_start"] + shift)
    alarms = voyage.alarms.assign(
        start_time=voyage.alarms["start_time"] + shift, end_time=voyage.alarms["end_time"] + shift
    )
    return tracked, forecast, alarms


def _episode(alarm: int, start_block: int, end_block: int) -> dict:
    start = pd.Timestamp("2024-03-02T10:00:00Z")
    return {
        "alarm": alarm,
        "start_block": start_block,
        "end_block": end_block,
        "start_time": start + pd.Timedelta(minutes=5 * start_block),
        "end_time": start + pd.Timedelta(minutes=5 * end_block),
        "peak_block": end_block,
        "peak_statistic": 3.5 + alarm,
        "limit": 1.0,
        "modes": "3 (91 %); 5 (6 %)",
        "top_mode": 3,
        "top_mode_shift_percent": -0.62,
    }


def _alarms(*episodes: dict) -> pd.DataFrame:
    return ALARMS.validate(pd.DataFrame(list(episodes)))


def _wait_lines(path, count: int, timeout: float = 20.0) -> list[dict]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.is_file():
            lines = path.read_text(encoding="utf-8").splitlines()
            if len(lines) >= count:
                return [json.loads(line) for line in lines]
        time.sleep(0.02)
    raise AssertionError(f"{path}: fewer than {count} messages after {timeout} s")


def test_on_alarm_command_gets_each_new_episode_once_as_json(tmp_path):
    """The monitor runs the command once per new episode (not again as the episode grows,
    nor after a restart), the alarm's fields as JSON on its stdin."""
    watch, state, received = tmp_path / "watch", tmp_path / "state", tmp_path / "received.jsonl"
    watch.mkdir()
    options = MonitorOptions(on_alarm=(sys.executable, "-c", RECORDER, str(received)))
    first = _episode(1, 40, 42)
    state.mkdir()
    write_table(_alarms(first), state / "alarms.parquet", ALARMS)
    with Monitor(watch, state, options=options) as monitor:
        # what the monitor does with each forecast/health update it collects
        monitor._collect(OutlookReport())
        monitor.alarm_hook.wait()
        got = _wait_lines(received, 1)
        # the episode grows and a second one starts: only the second is new
        grown, second = _episode(1, 40, 47), _episode(2, 60, 61)
        write_table(_alarms(grown, second), state / "alarms.parquet", ALARMS)
        monitor.hand_on()
        monitor.hand_on()
        monitor.alarm_hook.wait()
        got = _wait_lines(received, 2)
    assert [m["alarm"] for m in got] == [1, 2]
    message = got[0]
    assert message["event"] == "alarm"
    assert (message["start_block"], message["end_block"], message["peak_block"]) == (40, 42, 42)
    assert message["start_time"] == "2024-03-02T13:20:00Z"
    assert message["end_time"] == "2024-03-02T13:30:00Z"
    assert message["peak_statistic"] == 4.5 and message["limit"] == 1.0
    assert message["modes"] == "3 (91 %); 5 (6 %)" and message["top_mode"] == 3
    assert message["top_mode_shift_percent"] == -0.62
    assert message["state"] == str(state) and message["host"]
    assert got[1]["start_block"] == 60 and got[1]["peak_statistic"] == 5.5
    # a restarted monitor remembers what it handed on
    with Monitor(watch, state, options=options) as monitor:
        monitor.hand_on()
        monitor.alarm_hook.wait()
    time.sleep(0.2)
    assert len(received.read_text(encoding="utf-8").splitlines()) == 2
    assert json.loads((state / "alarm_hook.json").read_text())["start_blocks"] == [40, 60]


@pytest.mark.parametrize(
    ("program", "timeout_s", "said"),
    [
        (
            "import sys; sys.stdin.read(); print('no route to shore', file=sys.stderr); "
            "sys.exit(3)",
            20.0,
            "failed with exit status 3: no route to shore",
        ),
        ("import time; time.sleep(30)", 0.5, "timed out after 0.5 s and was stopped"),
    ],
)
def test_a_failing_or_hanging_command_is_reported_and_the_monitor_goes_on(
    tmp_path, program, timeout_s, said
):
    reported: list[str] = []
    hook = AlarmHook(
        (sys.executable, "-c", program), tmp_path, timeout_s=timeout_s, report=reported.append
    )
    started = time.monotonic()
    sent = hook.notify(_alarms(_episode(1, 40, 42)))
    assert time.monotonic() - started < 0.5 * timeout_s + 0.5  # never waited for
    hook.wait()
    assert [m["alarm"] for m in sent] == [1]
    assert len(reported) == 1
    assert reported[0].startswith("on-alarm: `") and "for alarm 1 (block 40)" in reported[0]
    assert reported[0].endswith(said)
    # handed on once: not run again for the same episode
    assert hook.notify(_alarms(_episode(1, 40, 44))) == []


def test_a_missing_program_is_reported(tmp_path):
    reported: list[str] = []
    hook = AlarmHook([str(tmp_path / "no-such-program")], tmp_path, report=reported.append)
    hook.notify(_alarms(_episode(1, 5, 5)))
    hook.wait()
    assert len(reported) == 1 and "could not be started" in reported[0]


def test_on_alarm_arguments(tmp_path, capsys):
    from workbench.cli import main

    assert parse_command("notify --to 'bridge officer' -v") == (
        "notify",
        "--to",
        "bridge officer",
        "-v",
    )
    with pytest.raises(ValueError, match="--on-alarm") as error:
        parse_command("notify 'unbalanced")
    assert "quotation" in str(error.value)
    with pytest.raises(ValueError, match="on_alarm_timeout_s"):
        MonitorOptions(on_alarm=("true",), on_alarm_timeout_s=0)
    watch = tmp_path / "watch"
    watch.mkdir()
    base = ["monitor", "--watch", str(watch), "--state", str(tmp_path / "s"), "--once"]
    assert main([*base, "--on-alarm", "notify 'unbalanced"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--on-alarm" in err[0]
    assert main([*base, "--on-alarm", "true", "--on-alarm-timeout", "-1"]) == 2
    assert "--on-alarm-timeout -1.0 must be" in capsys.readouterr().err


def test_daily_key_indicators_match_the_tracked_table(tmp_path, demo):
    tracked, forecast, alarms = demo
    written = write_daily_indicators(tmp_path, tracked, forecast, alarms)
    assert [p.name for p in written] == [
        "key_indicators_2024-03-01.json",
        "key_indicators_2024-03-02.json",
    ]
    residual = forecast[forecast["option"] == "A"].assign(
        residual=lambda f: f["ssi_frequency_hz"] - f["model_frequency_hz"]
    )
    for path in written:
        day = path.stem[-10:]
        summary = json.loads(path.read_text(encoding="utf-8"))
        table = pd.read_csv(path.with_suffix(".csv"))
        assert tuple(table.columns) == INDICATOR_COLUMNS
        start = pd.Timestamp(day, tz="UTC")
        rows = tracked[
            (tracked["block_start"] >= start)
            & (tracked["block_start"] < start + pd.Timedelta(days=1))
        ]
        # day 1: 12:00-23:55 (144 blocks); day 2: 00:00-11:40 (the voyage's last 141)
        assert summary["blocks"] == rows["block"].nunique() == (144 if day.endswith("01") else 141)
        assert summary["first_block"] == rows["block"].min()
        assert summary["last_block"] == rows["block"].max()
        expected = rows.groupby("mode").agg(
            blocks=("block", "nunique"),
            frequency=("frequency_hz", "median"),
            damping=("damping_ratio", "median"),
        )
        assert table["mode"].tolist() == expected.index.tolist() == list(range(1, 8))
        np.testing.assert_array_equal(table["blocks"], expected["blocks"])
        np.testing.assert_allclose(table["median_frequency_hz"], expected["frequency"], rtol=1e-15)
        np.testing.assert_allclose(table["median_damping_ratio"], expected["damping"], rtol=1e-15)
        on_day = residual[residual["block"].between(rows["block"].min(), rows["block"].max())]
        medians = on_day.dropna(subset=["residual"]).groupby("mode")["residual"].median()
        np.testing.assert_allclose(
            table["median_model_residual_hz"], medians.reindex(expected.index), rtol=1e-12
        )
        # the JSON holds the same numbers as the CSV
        for mode, row in zip(summary["modes"], table.itertuples(index=False), strict=True):
            assert mode["mode"] == row.mode and mode["blocks"] == row.blocks
            assert mode["median_frequency_hz"] == row.median_frequency_hz
    # the alarm (22:05 -> 10:05 the next day) is on day 2 only, counted on its top mode
    day1 = json.loads(written[0].read_text())
    day2 = json.loads(written[1].read_text())
    assert day1["alarms"] == [] and [a["alarm"] for a in day2["alarms"]] == [1]
    assert day2["alarms"][0]["start_time"] == "2024-03-02T10:05:00Z"
    assert day2["alarms"][0]["top_mode"] == 3
    assert [m["alarms"] for m in day2["modes"]] == [0, 0, 1, 0, 0, 0, 0]
    # blocks outside the model's 95 % band, counted independently
    rows = residual[residual["block"].between(day2["first_block"], day2["last_block"])]
    rows = rows.dropna(subset=["residual"])
    outside = (rows["ssi_frequency_hz"] < rows["model_lower_hz"]) | (
        rows["ssi_frequency_hz"] > rows["model_upper_hz"]
    )
    counts = outside.groupby(rows["mode"]).sum()
    assert [m["blocks_outside_band"] for m in day2["modes"]] == counts.tolist()
    assert counts.sum() > 0
    # small enough for a satellite link
    assert all(p.stat().st_size < 8000 for p in written)


def test_the_monitor_writes_the_tracked_harmonic_lines(tmp_path, monkeypatch):
    """A tracked line that is a shaft harmonic (order 1 sweeping 1.5-3 Hz with the speed)
    is left out of tracked.parquet and written to harmonic_tracks.parquet, with its order
    per block; the mode it crosses stays in the tracked table."""
    from data_contracts import shape_columns
    from workbench.dashboard.state import HARMONIC_TRACKS
    from workbench.sid.tracking import TrackingOptions

    channels = [f"c{j}" for j in range(6)]
    mode_shape = np.array([1.0, 0.8, 0.3, -0.3, -0.8, -1.0])
    forced_shape = np.array([1.0, 0.6, 0.35, 0.2, 0.1, 0.05])
    speeds = np.linspace(5.0, 10.0, 12)
    start = pd.Timestamp("2024-03-01T00:00:00Z")
    watch = tmp_path / "watch"
    watch.mkdir()
    options = MonitorOptions(tracking=TrackingOptions(frequency_tol=0.5))
    monitor = Monitor(watch, tmp_path / "state", options=options)

    def marks(frame: pd.DataFrame) -> np.ndarray:  # the logged shaft speed's marks
        order1 = 0.3 * speeds[frame["block"].to_numpy()]
        on = np.isclose(frame["frequency_hz"].to_numpy(), order1)
        # per row: the order, its frequency, checked (Monitor._mark_harmonics)
        return np.column_stack(
            [np.where(on, 1.0, np.nan), np.where(on, order1, np.nan), np.ones(len(frame))]
        )

    monkeypatch.setattr(monitor, "_mark_harmonics", marks)
    for block, speed in enumerate(speeds):
        part = pd.DataFrame(
            {
                "block": block,
                "block_start": start + pd.Timedelta(minutes=20 * block),
                "block_end": start + pd.Timedelta(minutes=20 * block + 20),
                "frequency_hz": [0.3 * speed, 2.9],
                "damping_ratio": 0.01,
            }
        )
        shapes = np.array([s / np.linalg.norm(s) for s in (forced_shape, mode_shape)])
        names = shape_columns(channels)
        for j in range(6):
            part[names[j]] = shapes[:, j]
            part[names[6 + j]] = 0.0
        monitor.tracking.add(block, part)
        monitor.done.add(block)
    monitor._advance_tracking()
    monitor.close()
    tracked = pd.read_parquet(tmp_path / "state" / "tracked.parquet")
    lines = pd.read_parquet(tmp_path / "state" / "harmonic_tracks.parquet")
    HARMONIC_TRACKS.validate(lines)
    assert tracked["frequency_hz"].eq(2.9).all() and len(tracked) == 12
    assert lines["track"].eq(1).all() and lines["block"].tolist() == list(range(12))
    np.testing.assert_allclose(lines["frequency_hz"], 0.3 * speeds)
    assert lines["order"].eq(1.0).all()
    MODAL.validate(tracked)
