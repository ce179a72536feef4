"""The monitor names the blocks it gave up (issue 28, item 4).

A file landing after the monitor's late window does not make it redo the blocks decided
without it (skipped: gap); a batch ``identify`` over the same folder identifies them, so
the monitor ended with fewer tracked rows than batch (224 vs 256) without saying which
blocks. Now ``status.json`` lists them with their span, the command's last lines and the
dashboard say so, and the list equals the difference from batch exactly.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.cli import main, parse_arguments
from workbench.cli.monitoring import prepare_monitor
from workbench.dashboard.server import make_server

from .voyage import IDENTIFY_ARGS, T0, write_voyage

#: The monitor with the batch settings of the tiny voyage, no patience for late files.
MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous", "--quiet")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground"]
LATE = 3  # acc_003.npz, 180-240 s: blocks 2 (120-240 s) and 3 (180-300 s) lie over it


def _status(state: Path) -> dict:
    return json.loads((state / "status.json").read_text(encoding="utf-8"))


def _give_up(tmp_path: Path, late_start_s: float = 0.0) -> tuple[Path, Path]:
    """A monitor that decided the blocks over acc_003.npz without it, which landed
    afterwards; acc_000.npz starts *late_start_s* after the minute (its first samples cut
    off), so the grid, anchored at it, lies that far from the files after it."""
    source, watch, state = tmp_path / "source", tmp_path / "watch", tmp_path / "state"
    files = write_voyage(source, n_files=8)
    if late_start_s:
        record = read_accelerations(files[0])
        cut = int(round(late_start_s * record.sampling_rate_hz))
        start = record.start_time + pd.Timedelta(seconds=late_start_s)
        first = AccelerationRecord(
            record.acceleration[cut:], record.sampling_rate_hz, start, record.channels
        )
        write_accelerations(first, files[0])
    watch.mkdir()
    argv = ["monitor", "--watch", watch, "--state", state, *MONITOR_ARGS]
    monitor = prepare_monitor(parse_arguments([str(a) for a in argv]))
    try:
        for path in files[:LATE] + files[LATE + 1 :]:
            shutil.copy(path, watch / path.name)
        monitor.step()
        assert monitor.given_up() == []  # the hole is still a hole: nothing given up
        shutil.copy(files[LATE], watch / files[LATE].name)
        assert monitor.step() == 0  # nothing redone
    finally:
        monitor.close()
    return watch, state


@pytest.fixture
def gave_up(tmp_path):
    """A monitor that decided blocks 2-3 without acc_003.npz, which landed afterwards."""
    return _give_up(tmp_path)


def test_the_state_names_the_given_up_blocks_with_their_span(gave_up):
    watch, state = gave_up
    status = _status(state)
    step = pd.Timedelta(minutes=1)
    assert status["given_up"] == [
        {
            "first_block": 2,
            "last_block": 3,
            "start": (T0 + 2 * step).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "end": (T0 + 5 * step).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "reason": status["given_up"][0]["reason"],
        }
    ]
    assert status["given_up"][0]["reason"] == (
        "acc_003.npz (2026-03-01T00:03:00Z to 2026-03-01T00:04:00Z, 60.0 s between "
        "acc_002.npz and acc_004.npz) landed after the late window: blocks 2-3 "
        "(2026-03-01T00:02:00Z to 2026-03-01T00:05:00Z) were decided without it and given up"
    )
    note = status["given_up_note"]
    assert note.startswith("2 block(s) given up, their files landed after the late window: 2-3")
    assert f"workbench identify {watch} --out DIR" in note


def test_the_reason_names_the_missing_file_not_the_first_blocks_share_of_it(tmp_path):
    """The grid anchored 0.5 s after the minute (acc_000.npz starts late): the hole of
    acc_003.npz, 00:03:00 to 00:04:00, reaches 0.5 s into block 1 (00:01:00.5 to
    00:03:00.5). Before, the reason was block 1's skip reason, "gap of 0.5 s between
    acc_002.npz and acc_004.npz", for a hole of a whole file under blocks 1-3."""
    _, state = _give_up(tmp_path, late_start_s=0.5)
    (span,) = _status(state)["given_up"]
    assert (span["first_block"], span["last_block"]) == (1, 3)
    assert span["reason"] == (
        "acc_003.npz (2026-03-01T00:03:00Z to 2026-03-01T00:04:00Z, 60.0 s between "
        "acc_002.npz and acc_004.npz) landed after the late window: blocks 1-3 "
        "(2026-03-01T00:01:00Z to 2026-03-01T00:05:00Z) were decided without it and given up"
    )


def test_the_given_up_times_are_rounded_to_the_second(tmp_path):
    """The grid anchored 31/32 s after the minute (as a first stamp jittered a few ms
    early anchors it just before a second): blocks 1-3 span 00:01:00.969 to 00:05:00.969,
    said to the nearest second, 00:01:01Z to 00:05:01Z. Before, the seconds were cut off:
    00:01:00Z to 00:05:00Z, nearly a second early (a block starting 01:49:59.995 was said
    to start at 01:49:59Z)."""
    _, state = _give_up(tmp_path, late_start_s=31 / 32)
    (span,) = _status(state)["given_up"]
    assert (span["first_block"], span["last_block"]) == (1, 3)
    assert (span["start"], span["end"]) == ("2026-03-01T00:01:01Z", "2026-03-01T00:05:01Z")
    assert span["reason"].endswith(
        "blocks 1-3 (2026-03-01T00:01:01Z to 2026-03-01T00:05:01Z) were decided without it "
        "and given up"
    )


def test_the_given_up_blocks_are_exactly_what_batch_adds(gave_up, tmp_path):
    watch, state = gave_up
    out = tmp_path / "batch"
    assert main(["identify", str(watch), "--out", str(out), *IDENTIFY_ARGS]) == 0
    batch = pd.read_csv(out / "blocks.csv")
    monitor = pd.read_parquet(state / "data_health.parquet")
    batch_ok = set(batch.loc[batch["status"] == "ok", "block"])
    monitor_ok = set(monitor.loc[monitor["status"] == "ok", "block"])
    assert monitor_ok < batch_ok
    named = {
        block
        for span in _status(state)["given_up"]
        for block in range(span["first_block"], span["last_block"] + 1)
    }
    assert batch_ok - monitor_ok == named == {2, 3}


def test_a_restart_still_names_them_and_says_so_at_the_end(gave_up, capsys):
    watch, state = gave_up
    argv = ["monitor", "--watch", watch, "--state", state, *MONITOR_ARGS, "--once"]
    assert main([str(a) for a in argv]) == 0
    out = capsys.readouterr().out
    assert "note: 2 block(s) given up, their files landed after the late window: 2-3" in out
    assert _status(state)["given_up"][0]["first_block"] == 2


def test_the_dashboard_shows_them(gave_up):
    _, state = gave_up
    server = make_server(state, port=0)
    try:
        status = server.answer("status")[1]
    finally:
        server.server_close()
    data = json.loads(status)
    assert [(s["first_block"], s["last_block"]) for s in data["given_up"]] == [(2, 3)]
    assert "workbench identify" in data["given_up_note"]


@pytest.mark.parametrize(
    "given_up, fragment",
    [
        ("blocks 2-3", "key 'given_up' has type str"),
        ([{"first_block": 2}], "key 'given_up' item 0: missing or wrong last_block, start"),
        ([{"first_block": True, "last_block": 3, "start": "", "end": "", "reason": ""}],
         "missing or wrong first_block"),
    ],
)  # fmt: skip
def test_a_malformed_given_up_list_is_named(tmp_path, given_up, fragment):
    from workbench.dashboard.state import read_status

    status = {
        "updated_at": "2026-03-01T00:00:00Z", "last_block": 3, "blocks_done": 4,
        "state": "running", "pid": 1, "watch": "/data", "message": "",
        "given_up": given_up,
    }  # fmt: skip
    path = tmp_path / "status.json"
    path.write_text(json.dumps(status), encoding="utf-8")
    with pytest.raises(ValueError, match="status.json") as caught:
        read_status(path)
    assert fragment in str(caught.value)
