"""A late file among the first files of a drifting record is used, not refused by the store.

The recorder of :mod:`tests.robustness.test_clock_drift` runs 100 ppm fast (each 5-min file
lasts 30 ms less than its 38 400 samples at 128 Hz say) and its stamps jitter by 10 ms
(+10, -10, ... ms on files 1-6). acc_004.npz lands late, after acc_006.npz. Before it, the
four files of the first run cannot carry the record's time over the 300-s hole (their line
is too uncertain), so acc_005.npz starts at its stamp, 140 ms before where the record's
sample count puts it (the placement of all the files, identify's). When acc_004.npz lands
the files are placed again from the first: acc_005.npz moves +140 ms. The store had
recorded acc_005.npz's span as placed when it was taken, which acc_004.npz now overlaps by
140 ms (beyond the 100-ms rounding and jitter): main refused acc_004.npz ("input changed
since the store was made (other content than acc_005.npz ...); ... use another --store or
delete this one"), skipped blocks 1-3 for the gap and gave blocks 3-10 from files placed
140 ms off identify's. Now a recorded file still given, only placed elsewhere, is no
changed input: its recorded span moves, and the monitor gives identify's blocks.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from workbench.cli import main, parse_arguments
from workbench.cli.monitoring import prepare_monitor

from .test_clock_drift import FILE_S, MONITOR_ARGS, N_FILES, PATHS, _identify, _write
from .voyage import assert_store_equals_identify

#: The stamps' jitter, file by file. [ms]
JITTER_MS = np.array([0, 10, -10, 10, -10, 10, -10] + [0] * (N_FILES - 7))
#: The monitor waiting for late data (its default --late, 900 s), files landing one by one.
_AT = MONITOR_ARGS.index("--late")
LIVE_ARGS = [a for a in MONITOR_ARGS[:_AT] + MONITOR_ARGS[_AT + 2 :] if a != "--once"]


def _stamps() -> np.ndarray:
    return np.arange(N_FILES) * FILE_S / (1 + 100e-6) + JITTER_MS / 1e3


def _replay(files, watch, state, argv=(), *, flush=True) -> list[str]:
    """The monitor taking *files* one by one, then flushed (*flush*); its messages."""
    watch.mkdir(exist_ok=True)
    argv = ["monitor", "--watch", str(watch), "--state", str(state), *LIVE_ARGS, *argv]
    monitor = prepare_monitor(parse_arguments(argv))
    try:
        for path in files:
            shutil.copy(path, watch / path.name)
            monitor.step()
        if flush:
            monitor.step(flush=True)
    finally:
        monitor.close()
    return list(monitor.messages)


def _health(state):
    import pandas as pd

    return pd.read_parquet(state / "data_health.parquet").sort_values("block")


def test_a_late_file_among_a_drifting_records_first_files_is_used(tmp_path, capsys):
    files = _write(tmp_path / "source", _stamps())
    order = files[:4] + files[5:7] + [files[4]] + files[7:]
    state = tmp_path / "state"
    messages = _replay(order, tmp_path / "watch", state, PATHS["per-block"])
    assert not [m for m in messages if "not used" in m]  # main: acc_004.npz refused
    health = _health(state)
    # block 10's UTC span ends about 720 ms after the record's last sample (100 ppm fast):
    # cut at that sample (EDGE_SHIFT_S)
    assert health["block"].tolist() == list(range(11))
    assert (health["status"] == "ok").all()  # main: blocks 1-3 skipped (gap)
    code, _, err = _identify(capsys, tmp_path / "source", tmp_path / "batch", PATHS["per-block"])
    assert code == 0, err
    assert_store_equals_identify(state, tmp_path / "batch")  # main: blocks 1-10 differ
    # no decided block used acc_005.npz where it lay before: nothing to say of it
    assert not [m for m in messages if "are kept as decided" in m]
    # acc_002.npz: its stamp 70 ms after acc_001.npz's placed end, 10 ms before the line of
    # the three stamps (main: "a stamp within 50 ms of that end or of the line ...")
    retimed = next(m for m in messages if m.startswith("acc_002.npz: start re-timed"))
    assert retimed == (
        "acc_002.npz: start re-timed by +70.0 ms to the previous file's end (its stamp more "
        "than 50 ms from that end but within 50 ms of the line of the run's stamps on its "
        "sample count, a sample clock off its rate: taken as contiguous)"
    )
    assert [m for m in messages if m.startswith("acc_001.npz")] == [
        "acc_001.npz: start re-timed by +20.0 ms to the previous file's end (a stamp within "
        "50 ms of that end is taken as contiguous)"
    ]


def test_a_late_file_landing_while_the_monitor_was_down_is_used(tmp_path, capsys):
    """The monitor stopped after acc_006.npz (its store as a kill -9 leaves it: every file
    is recorded when taken); acc_004.npz and the rest land before the restart, which takes
    the files again from the first (main: acc_004.npz refused again)."""
    files = _write(tmp_path / "source", _stamps())
    watch, state = tmp_path / "watch", tmp_path / "state"
    _replay(files[:4] + files[5:7], watch, state, PATHS["per-block"], flush=False)
    for path in [files[4], *files[7:]]:
        shutil.copy(path, watch / path.name)
    argv = ["monitor", "--watch", str(watch), "--state", str(state), *LIVE_ARGS, "--once"]
    assert main([*argv, *PATHS["per-block"]]) == 0
    captured = capsys.readouterr()
    assert "not used" not in captured.err
    health = _health(state)
    assert health["block"].tolist() == list(range(11))
    assert (health["status"] == "ok").all()
    code, _, err = _identify(capsys, tmp_path / "source", tmp_path / "batch", PATHS["per-block"])
    assert code == 0, err
    assert_store_equals_identify(state, tmp_path / "batch")


def test_a_decided_block_that_used_a_moved_file_is_said_and_kept(tmp_path):
    """acc_004.npz lands after acc_010.npz: blocks 4-6 (2400-3600 s .. 3600-4800 s at 10-min
    steps hold acc_008.npz - acc_015.npz) are not decided yet, but block 3 (1800-3000 s)
    was decided from acc_006.npz - acc_009.npz placed 140 ms before where they lie now.
    Block 3 is kept (a stored block is never redone) and that is said, naming the moved file
    and the blocks; main refused acc_004.npz."""
    files = _write(tmp_path / "source", _stamps())
    order = files[:4] + files[5:11] + [files[4]] + files[11:]
    state = tmp_path / "state"
    messages = _replay(order, tmp_path / "watch", state, ["--late", "1200", *PATHS["per-block"]])
    assert not [m for m in messages if "not used" in m]
    said = [m for m in messages if "are kept as decided" in m]
    assert said == [
        "acc_004.npz: landed late: the record's files placed again from the first, as identify "
        "places them, move 6 file(s) (acc_005.npz .. acc_010.npz) by up to +140.0 ms; "
        "block(s) 3, decided from them as placed before, are kept as decided"
    ]


@pytest.mark.parametrize("what", ["content", "gone"])
def test_the_store_still_refuses_other_data_for_a_recorded_span(tmp_path, what):
    """The store's purpose kept: a new file over a recorded span is refused when the
    recorded file is not among the run's files as the same content."""
    from workbench.errors import WorkbenchError
    from workbench.store import BlockStore

    def fingerprint(name, start_s, sha):
        start = np.datetime64("2026-03-01T00:00:00") + np.timedelta64(int(start_s * 1e9), "ns")
        end = start + np.timedelta64(300, "s")
        return {
            "path": str(tmp_path / name),
            "start": f"{start}Z",
            "end": f"{end}Z",
            "size": 1,
            "mtime_ns": 0,
            "sha256": sha,
        }

    store = BlockStore.open(tmp_path / "store", {"grid_t0": "2026-03-01T00:00:00Z"})
    try:
        store.check_inputs([fingerprint("acc_005.npz", 1499.86, "5" * 64)])
        late = fingerprint("acc_004.npz", 1200.0, "4" * 64)
        now = None if what == "gone" else fingerprint("acc_005.npz", 1500.0, "e" * 64)
        with pytest.raises(WorkbenchError, match="input changed since the store"):
            store.check_inputs([late], placed_now=lambda recorded: now)
        # the same content placed 140 ms later: its span moves, the late file is recorded
        moved = store.check_inputs(
            [late], placed_now=lambda recorded: fingerprint("acc_005.npz", 1500.0, "5" * 64)
        )
        assert [(m["start"], m["now_start"]) for m in moved] == [
            ("2026-03-01T00:24:59.860000000Z", "2026-03-01T00:25:00.000000000Z")
        ]
        spans = {r["sha256"][0]: r["start"] for r in store.recorded_inputs()}
        assert spans == {"5": "2026-03-01T00:25:00.000000000Z", "4": late["start"]}
    finally:
        store.close()


def test_identify_over_a_store_with_the_late_file_equals_a_fresh_run(tmp_path, capsys):
    """identify over the files without acc_004.npz, then again with it into the same
    output: main exited 1 (input changed since the store was made); now the blocks from
    the files it moved are computed again and the result is a fresh run's."""
    files = _write(tmp_path / "all", _stamps())
    part = tmp_path / "part"
    part.mkdir()
    for path in files[:4] + files[5:]:
        shutil.copy(path, part / path.name)
    code, _, err = _identify(capsys, part, tmp_path / "out")
    assert code == 0, err
    code, _, err = _identify(capsys, tmp_path / "all", tmp_path / "out")
    assert code == 0, err
    assert "input file(s) placed elsewhere than when the store's blocks were computed" in err
    code, _, err = _identify(capsys, tmp_path / "all", tmp_path / "fresh")
    assert code == 0, err
    from .voyage import selected_modes

    again, fresh = (
        selected_modes(folder).sort_values(["block", "frequency_hz"]).reset_index(drop=True)
        for folder in (tmp_path / "out", tmp_path / "fresh")
    )
    assert again["block"].tolist() == fresh["block"].tolist()
    assert fresh["block"].unique().tolist() == list(range(11))
    np.testing.assert_allclose(again["frequency_hz"], fresh["frequency_hz"], rtol=0, atol=1e-12)


def test_identify_names_the_changed_file_not_the_late_one_beside_it(tmp_path, capsys):
    """identify over the files without acc_004.npz, then again with acc_004.npz landed and
    acc_005.npz rewritten with other data: still refused (exit 1, one line), naming
    acc_005.npz, the changed file. Before, the late acc_004.npz was named (its span
    overlaps acc_005.npz's recorded span, 140 ms before where the record puts it now),
    sending the user to a file that had not changed."""
    from data_contracts import AccelerationRecord, read_accelerations, write_accelerations

    files = _write(tmp_path / "all", _stamps())
    folder = tmp_path / "folder"
    folder.mkdir()
    for path in files[:4] + files[5:]:
        shutil.copy(path, folder / path.name)
    code, _, err = _identify(capsys, folder, tmp_path / "out")
    assert code == 0, err
    shutil.copy(files[4], folder / files[4].name)
    record = read_accelerations(files[5])
    other = AccelerationRecord(
        record.acceleration[::-1].copy(),
        record.sampling_rate_hz,
        record.start_time,
        record.channels,
    )
    write_accelerations(other, folder / files[5].name)
    code, _, err = _identify(capsys, folder, tmp_path / "out")
    assert code == 1
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err
    assert lines[0].startswith(
        f"error: {folder / 'acc_005.npz'}: input changed since the store {tmp_path / 'out'}"
    )  # main: f"error: {folder / 'acc_004.npz'}: input changed ..."
    assert f"(other content than {folder / 'acc_005.npz'} for " in lines[0]


def test_a_file_landing_after_one_block_was_decided_without_it_says_block_not_blocks(tmp_path):
    """acc_005.npz lands before acc_004.npz, both after acc_007.npz: acc_005.npz leaves a
    300-s hole (1200-1500 s) with data 900 s newer (the default --late) landed, so block 1
    (600-1800 s) is decided without acc_004.npz (skipped: gap) and acc_004.npz, landing
    next, is not used for it. One block: "block 1 was" (main: "blocks 1-1 were")."""
    files = _write(tmp_path / "source", _stamps())
    order = files[:4] + files[6:8] + [files[5], files[4]] + files[8:]
    state = tmp_path / "state"
    messages = _replay(order, tmp_path / "watch", state, PATHS["per-block"])
    health = _health(state)
    assert health.loc[health["status"] != "ok", "block"].tolist() == [1]
    assert [m for m in messages if "landed after" in m] == [
        "acc_004.npz: landed after block 1 was decided without it (skipped: gap); it is not redone"
    ]
