"""A file copied twice into the voyage's folder is left out; two different files for one
span stay an error.

Before, identify refused the whole voyage for an exact copy ("acc_002_copy.npz: starts 60
s before the end of acc_002.npz (overlapping or duplicate files)", exit 1), while the
monitor left it out as "overlaps acc_002.npz". Now both leave the copy out with a note
naming the file it duplicates and identify the voyage as without it; a file with other
data for the same span is still an error naming both files (which is the record?).
"""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.cli import main

from .voyage import IDENTIFY_ARGS, identify_run, selected_modes, write_voyage

ARGS = [a for a in IDENTIFY_ARGS if a != "--quiet"]
MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]
NOTE = "acc_002_copy.npz: not used: the same data as acc_002.npz (a duplicate)"


def _identify(capsys, folder, out, extra=()):
    return identify_run(capsys, folder, out, [*ARGS, *extra])


_modes = selected_modes


def test_an_exact_duplicate_is_left_out(tmp_path, capsys):
    files = write_voyage(tmp_path / "acc", n_files=5)
    code, _, err = _identify(capsys, tmp_path / "acc", tmp_path / "clean")
    assert code == 0, err
    shutil.copy(files[2], tmp_path / "acc" / "acc_002_copy.npz")
    code, out, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 0, err  # main: exit 1, "starts 60 s before the end of acc_002.npz"
    assert NOTE in out.splitlines()
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks["status"].tolist() == ["ok"] * 4  # its span is the original's: no gap
    modes, clean = _modes(tmp_path / "out"), _modes(tmp_path / "clean")
    assert len(modes) == 8
    assert modes["block"].tolist() == clean["block"].tolist()
    np.testing.assert_allclose(modes["frequency_hz"], clean["frequency_hz"], rtol=0, atol=1e-12)


def _monitor_notes(tmp_path, capsys) -> str:
    """``monitor --once`` over tmp_path/watch (4 blocks, all identified): its notes. On main
    the duplicate's note was "acc_002_copy.npz: not used: overlaps acc_002.npz"."""
    state = tmp_path / "state"
    code = main(
        ["monitor", "--watch", str(tmp_path / "watch"), "--state", str(state), *MONITOR_ARGS]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["status"].tolist() == ["ok"] * 4
    return (state / "notes.txt").read_text(encoding="utf-8")


def test_the_monitor_says_the_duplicate_as_identify_does(tmp_path, capsys):
    files = write_voyage(tmp_path / "watch", n_files=5)
    shutil.copy(files[2], tmp_path / "watch" / "acc_002_copy.npz")
    assert NOTE in _monitor_notes(tmp_path, capsys)


def test_two_different_files_for_one_span_are_an_error_naming_both(tmp_path, capsys):
    files = write_voyage(tmp_path / "acc", n_files=5)
    record = read_accelerations(files[2])
    other = AccelerationRecord(
        record.acceleration * 2.0, record.sampling_rate_hz, record.start_time, record.channels
    )
    write_accelerations(other, tmp_path / "acc" / "acc_002_other.npz")
    code, _, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 1
    assert err.strip().splitlines() == [
        f"error: {tmp_path / 'acc' / 'acc_002_other.npz'}: starts 60 s before the end of "
        "acc_002.npz (overlapping or duplicate files)"
    ]


def test_the_monitor_says_the_duplicate_of_a_re_timed_file_as_identify_does(tmp_path, capsys):
    """Stamps with a recorder's jitter: the original is re-timed onto the record (its
    placed start is not its stamp), and its copy is still said to be its duplicate. With
    these stamps the placed start less its shift in seconds is 1 ns off acc_002's stamp."""
    files = write_voyage(tmp_path / "watch", n_files=5)
    for path, jitter_ms in zip(files[1:], (2.827, 7.053, 1.859, -4.798), strict=True):
        record = read_accelerations(path)
        stamp = record.start_time + pd.Timedelta(milliseconds=jitter_ms)
        write_accelerations(
            AccelerationRecord(
                record.acceleration, record.sampling_rate_hz, stamp, record.channels
            ),
            path,
        )
    shutil.copy(files[2], tmp_path / "watch" / "acc_002_copy.npz")
    code, out, err = _identify(capsys, tmp_path / "watch", tmp_path / "out")
    assert code == 0, err
    assert NOTE in out.splitlines()
    assert NOTE in _monitor_notes(tmp_path, capsys)
