"""Files whose start stamps jitter by milliseconds are one continuous record.

A recorder stamps each file from its PC clock (NTP steps, write buffering): the boundary
between consecutive files misses by milliseconds while the samples run on. Before, a file
stamped more than half a sample early (here 25 ms at 32 Hz, 0.8 samples; 10 ms at 64 Hz
is the same) made identify exit 1 for the whole voyage ("starts 0.025 s before the end of
acc_002.npz (overlapping or duplicate files)"), and one stamped as late was a gap: the
blocks over it were skipped. Now a mismatch up to ``CLOCK_JITTER_S`` (50 ms) re-times the
later file to the previous file's end, the run summary says so, and the modes are those
of the same samples stamped without jitter, to the last bit (the samples of every block
are the same ones). Beyond 50 ms an overlap is still an error and a gap a gap.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.cli import main

from .voyage import (
    IDENTIFY_ARGS,
    assert_store_equals_identify,
    identify_run,
    selected_modes,
    write_voyage,
)

EARLY, LATE = 3, 6  # acc_003.npz stamped early, acc_006.npz late
#: Identify without --quiet (it silences nothing but the progress bar; kept explicit).
ARGS = [a for a in IDENTIFY_ARGS if a != "--quiet"]
#: The per-block builder (native 32 Hz) and the file conditioner (decimated to 16 Hz).
PATHS = {"native": ["--rate", "native"], "decimated": ["--rate", "16", "--band", "1", "6.3"]}
MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


def _restamp(path: Path, shift_ms: float) -> None:
    """*path* with its start stamp moved by *shift_ms*, samples unchanged."""
    record = read_accelerations(path)
    moved = record.start_time + pd.Timedelta(milliseconds=shift_ms)
    write_accelerations(
        AccelerationRecord(record.acceleration, record.sampling_rate_hz, moved, record.channels),
        path,
    )


@pytest.fixture(scope="module")
def voyages(tmp_path_factory) -> dict[str, Path]:
    """The same 8 one-minute files: as recorded, and with acc_003 stamped 25 ms early and
    acc_006 25 ms late."""
    root = tmp_path_factory.mktemp("jitter")
    write_voyage(root / "clean", n_files=8)
    shutil.copytree(root / "clean", root / "jitter")
    _restamp(root / "jitter" / "acc_003.npz", -25.0)
    _restamp(root / "jitter" / "acc_006.npz", +25.0)
    return {"clean": root / "clean", "jitter": root / "jitter"}


def _identify(capsys, folder, out, extra=()):
    return identify_run(capsys, folder, out, [*ARGS, *extra])


_modes = selected_modes


@pytest.mark.parametrize("path", list(PATHS))
def test_jittered_stamps_give_the_modes_of_the_clean_voyage(voyages, tmp_path, capsys, path):
    code, out, err = _identify(capsys, voyages["clean"], tmp_path / "clean", PATHS[path])
    assert code == 0, err
    code, out, err = _identify(capsys, voyages["jitter"], tmp_path / "jitter", PATHS[path])
    assert code == 0, err  # main: exit 1, acc_003.npz "overlapping or duplicate files"
    blocks = pd.read_csv(tmp_path / "jitter" / "blocks.csv")
    assert blocks["block"].tolist() == list(range(7))
    assert (blocks["status"] == "ok").all()  # no block lost to the 25-ms "gap" at acc_006
    clean, jitter = _modes(tmp_path / "clean"), _modes(tmp_path / "jitter")
    assert len(clean) == 14  # two modes in each of the 7 blocks
    assert jitter["block"].tolist() == clean["block"].tolist()
    # the same samples in every block: the same numbers (1e-12 Hz: rounding only)
    np.testing.assert_allclose(jitter["frequency_hz"], clean["frequency_hz"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(jitter["damping_ratio"], clean["damping_ratio"], rtol=0, atol=1e-12)
    notes = [line for line in out.splitlines() if line.startswith("clock jitter")]
    assert len(notes) == 1
    assert notes[0].startswith("clock jitter: 2 file start(s) re-timed to the previous file's")
    assert notes[0].endswith(
        "; a stamp within 50 ms of that end or of the line of the run's stamps on its sample "
        "count is taken as contiguous)"
    )
    largest_ms = float(notes[0].split("largest ")[1].split(" ms")[0])
    assert abs(largest_ms) == pytest.approx(25.0, abs=0.05)


def test_a_clean_voyage_has_no_jitter_note(voyages, tmp_path, capsys):
    code, out, err = _identify(capsys, voyages["clean"], tmp_path / "clean")
    assert code == 0, err
    assert not [line for line in out.splitlines() if line.startswith("clock jitter")]


def test_an_overlap_beyond_the_jitter_is_still_an_error_naming_the_file(tmp_path, capsys):
    files = write_voyage(tmp_path / "acc", n_files=5)
    _restamp(files[2], -60.0)  # 60 ms early: beyond 50 ms of clock jitter
    code, _, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 1
    assert err.strip().splitlines() == [
        f"error: {files[2]}: starts 0.06 s before the end of acc_001.npz "
        "(overlapping or duplicate files)"
    ]


def test_a_gap_beyond_the_jitter_is_still_a_gap(tmp_path, capsys):
    files = write_voyage(tmp_path / "acc", n_files=5)
    for path in files[2:]:  # acc_002 on 60 ms late: a gap, as before
        _restamp(path, +60.0)
    code, out, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 0, err
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    # the gap 120.00-120.06 s lies in blocks 1 (60-180 s) and 2 (120-240 s)
    assert blocks["status"].tolist() == ["ok", "skipped", "skipped", "ok"]
    assert blocks["reason"][1] == "gap of 0.1 s between acc_001.npz and acc_002.npz"
    assert blocks["reason"][2] == "gap of 0.1 s between acc_001.npz and acc_002.npz"
    assert "clock jitter" not in out


@pytest.mark.parametrize("path", list(PATHS))
def test_a_record_after_a_gap_stamped_early_keeps_its_last_block(tmp_path, capsys, path):
    """acc_003.npz lost; the files after it stamped 30 ms early (within the clock jitter;
    one sample at 32 Hz): the record after the gap ends 30 ms before the last block's end
    (480 s). Before, that block was neither identified nor said (blocks 0-5); the stamps
    place the record only to the jitter, so the block is the record's, its last 30 ms
    NaN-padded and bridged."""
    files = write_voyage(tmp_path / "acc", n_files=8)
    files[3].unlink()
    for path_ in files[4:]:
        _restamp(path_, -30.0)
    code, out, err = _identify(capsys, tmp_path / "acc", tmp_path / "out", PATHS[path])
    assert code == 0, err
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv", keep_default_na=False)
    assert blocks["block"].tolist() == list(range(7))  # main: 0-5
    assert blocks["status"].tolist() == ["ok", "ok", "skipped", "skipped", "ok", "ok", "ok"]
    assert blocks["reason"][2] == "gap of 60.0 s between acc_002.npz and acc_004.npz"
    assert blocks["reason"][3] == "gap of 60.0 s between acc_002.npz and acc_004.npz"
    assert 6 in set(_modes(tmp_path / "out")["block"])
    state = tmp_path / "state"
    argv = ["monitor", "--watch", str(tmp_path / "acc"), "--state", str(state)]
    assert main([*argv, *MONITOR_ARGS, *PATHS[path]]) == 0
    capsys.readouterr()
    health = pd.read_parquet(state / "data_health.parquet").sort_values("block")
    assert health["block"].tolist() == list(range(7))  # main: 0-5
    assert_store_equals_identify(state, tmp_path / "out")


def test_the_monitor_gives_the_blocks_identify_gives(voyages, tmp_path, capsys):
    watch, state = tmp_path / "watch", tmp_path / "state"
    shutil.copytree(voyages["jitter"], watch)
    code = main(["monitor", "--watch", str(watch), "--state", str(state), *MONITOR_ARGS])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "Traceback" not in captured.err
    health = pd.read_parquet(state / "data_health.parquet").sort_values("block")
    assert health["block"].tolist() == list(range(7))
    # main: acc_003.npz not used (overlaps acc_002.npz), blocks 2-3 skipped, 4-6 not planned
    assert (health["status"] == "ok").all()
    assert (health["gap_seconds"] == 0).all()  # the health row sees the placed files
    notes = (state / "notes.txt").read_text(encoding="utf-8")
    assert "acc_003.npz: start re-timed by +25.0 ms to the previous file's end" in notes
    # said once (main: twice, the files taken before the grid was fixed taken again)
    assert notes.count("acc_003.npz: start re-timed") == 1
    assert notes.count("acc_006.npz: start re-timed") == 1
    code, _, err = _identify(capsys, voyages["jitter"], tmp_path / "batch")
    assert code == 0, err
    assert_store_equals_identify(state, tmp_path / "batch")


def test_a_late_stamp_within_the_jitter_loses_no_block(voyages, tmp_path, capsys):
    files = write_voyage(tmp_path / "acc", n_files=5)
    for path in files[2:]:  # acc_002 on 25 ms late: clock jitter, not a gap
        _restamp(path, +25.0)
    code, out, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 0, err
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks["status"].tolist() == ["ok"] * 4  # main: blocks 1 and 2 skipped (gap)
    # acc_002 to its predecessor's end, and acc_003, acc_004 with it (each 25 ms from its stamp)
    assert "clock jitter: 3 file start(s) re-timed" in out
