"""``workbench monitor --once`` over files whose every channel is faulty ends with exit 1
and one line naming the blocks, the files and the reason, as ``workbench identify`` does.

Before: ``identify`` over such a folder exited 1 ("no block identified: all 5 block(s)
skipped: all channels faulty (5)"), ``monitor --once`` exited 0 ("5 block(s) decided")
with the reason only in ``data_health.parquet``, and its log said "block 0: skipped"
without why. What is stored and written to ``data_health.parquet`` is unchanged.

The voyages are the small ones of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute): 6 files give blocks 0-4, block k holding files k and k + 1.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.cli import main, parse_arguments
from workbench.cli.monitoring import prepare_monitor

from .voyage import IDENTIFY_ARGS, write_voyage

MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous", "--quiet")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground"]


def _spoil(path: Path, how: str) -> None:
    """Every channel of *path* zero, or NaN, from start to end."""
    record = read_accelerations(path)
    values = record.acceleration
    spoiled = np.zeros_like(values) if how == "zero" else np.full_like(values, np.nan)
    write_accelerations(
        AccelerationRecord(spoiled, record.sampling_rate_hz, record.start_time, record.channels),
        path,
    )


def _monitor(capsys, watch: Path, state: Path) -> tuple[int, str, str]:
    argv = ["monitor", "--watch", watch, "--state", state, *MONITOR_ARGS, "--once"]
    status = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def _errors(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("error:")]


@pytest.mark.parametrize(
    ("how", "channel_reason"), [("zero", "flat (variance 0)"), ("NaN", "no data (all NaN)")]
)
def test_once_over_faulty_channels_only_exits_1_naming_blocks_files_and_why(
    tmp_path, capsys, caplog, how, channel_reason
):
    watch, state = tmp_path / "watch", tmp_path / "state"
    for path in write_voyage(watch, n_files=6):
        _spoil(path, how)
    with caplog.at_level(logging.INFO, logger="workbench"):
        status, out, err = _monitor(capsys, watch, state)
    assert status == 1
    assert "Traceback" not in err
    assert _errors(err) == [
        "error: no block identified: 5 block(s) decided (0-4; files acc_000.npz ... "
        f"acc_005.npz, 6 in all) were all skipped: all channels faulty: {channel_reason} "
        f"(5 block(s)); each block's reason is in {state / 'data_health.parquet'}"
    ]
    assert "block(s) decided, tracked" not in out  # not the summary of a pass that worked
    # the log says why, once per block
    logged = caplog.text
    for block in range(5):
        assert logged.count(f"block {block}: skipped (all channels faulty),") == 1
    # the state is written as before: every block decided, skipped, with its reason
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["block"].tolist() == [0, 1, 2, 3, 4]
    assert (health["status"] == "skipped").all()
    assert (health["reason"] == "all channels faulty").all()
    assert (health["dropped_channels"] == "acc01,acc02,acc03,acc04").all()
    assert (health["n_channels"] == 0).all()
    # identify over the same folder refuses it too
    assert main(["identify", str(watch), "--out", str(tmp_path / "id"), *IDENTIFY_ARGS]) == 1
    assert _errors(capsys.readouterr().err) == [
        "error: no block identified: all 5 block(s) skipped: all channels faulty (5)"
    ]


def test_a_rerun_over_the_decided_state_says_it_again(tmp_path, capsys):
    """Nothing new to decide, and no block of the state identified: exit 1 again, from the
    stored reasons (as a rerun of identify), nothing decided again."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    for path in write_voyage(watch, n_files=6):
        _spoil(path, "zero")
    assert _monitor(capsys, watch, state)[0] == 1
    before = pd.read_parquet(state / "data_health.parquet")
    status, _, err = _monitor(capsys, watch, state)
    assert status == 1
    assert _errors(err) == [
        "error: no block identified: 5 block(s) decided by an earlier run (0-4) were all "
        "skipped: all channels faulty (5 block(s)); each block's reason is in "
        f"{state / 'data_health.parquet'}"
    ]
    pd.testing.assert_frame_equal(pd.read_parquet(state / "data_health.parquet"), before)


def test_a_pass_over_new_faulty_files_only_exits_1_after_good_ones(tmp_path, capsys):
    """The first pass identifies blocks 0-3 and skips block 4 (file 4, good, and file 5,
    flat: every channel repeats one value for its last minute, a flat run); the files
    landing after them are all faulty: the second pass identifies nothing and says so,
    naming only its own blocks and files; the earlier blocks stay as they were."""
    source, watch, state = tmp_path / "source", tmp_path / "watch", tmp_path / "state"
    paths = write_voyage(source, n_files=10)
    for path in paths[5:]:
        _spoil(path, "zero")
    watch.mkdir()
    for path in paths[:6]:
        (watch / path.name).write_bytes(path.read_bytes())
    status, out, err = _monitor(capsys, watch, state)
    assert status == 0, err
    assert "5 block(s) decided, tracked up to block 4" in out
    first = pd.read_parquet(state / "data_health.parquet")
    assert first["status"].tolist() == ["ok"] * 4 + ["skipped"]
    for path in paths[6:]:
        (watch / path.name).write_bytes(path.read_bytes())
    status, _, err = _monitor(capsys, watch, state)
    assert status == 1
    assert _errors(err) == [
        "error: no block identified: 4 block(s) decided (5-8; files acc_005.npz ... "
        "acc_009.npz, 5 in all) were all skipped: all channels faulty: flat (variance 0) "
        f"(4 block(s)); each block's reason is in {state / 'data_health.parquet'}"
    ]
    health = pd.read_parquet(state / "data_health.parquet")
    pd.testing.assert_frame_equal(health.iloc[:5], first)
    assert health["status"].tolist() == ["ok"] * 4 + ["skipped"] * 5


def test_some_good_blocks_are_a_success(tmp_path, capsys):
    """Faulty files among good ones: their blocks are skipped, the others identified, exit 0."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    paths = write_voyage(watch, n_files=8)
    for path in paths[:3]:  # blocks 0-2 need one of files 0-2 at least (a flat minute)
        _spoil(path, "zero")
    status, out, err = _monitor(capsys, watch, state)
    assert status == 0, err
    assert _errors(err) == []
    assert "7 block(s) decided, tracked up to block 6" in out
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["status"].tolist() == ["skipped"] * 3 + ["ok"] * 4


def test_the_live_monitor_goes_on_and_logs_why_once_per_block(tmp_path, caplog):
    """Without --once the monitor keeps polling (no error), its log naming each skipped
    block once with the reason."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    for path in write_voyage(watch, n_files=6):
        _spoil(path, "zero")
    argv = ["monitor", "--watch", watch, "--state", state, *MONITOR_ARGS]
    monitor = prepare_monitor(parse_arguments([str(a) for a in argv]))
    try:
        with caplog.at_level(logging.INFO, logger="workbench"):
            assert monitor.step() == 5
            assert monitor.step() == 0  # polling on, nothing decided twice
    finally:
        monitor.close()
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith("block ")]
    assert [line.split(",")[0] for line in lines] == [
        f"block {block}: skipped (all channels faulty)" for block in range(5)
    ]
    assert monitor.nothing_identified().startswith("no block identified: 5 block(s)")
