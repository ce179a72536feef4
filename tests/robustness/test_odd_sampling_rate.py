"""A lone file at another sampling rate than the voyage's is left out, its span a gap.

Before, identify refused the whole voyage for it ("acc_003.npz: sampling rate 64 Hz
differs from 32 Hz of 4 of the 5 files", exit 1), while the monitor left such a file out
with a note -- but took the *first* file's rate as the voyage's, so an odd first file made
it refuse every good file and decide no block (exit 0). Now both take the rate more than
half of the files have, leave a file at another rate out with a note naming it, and
identify the rest: the blocks and modes of the voyage without that file. Files split
between rates with no majority stay an error naming them (which recording is meant?).
"""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.cli import main
from workbench.store import BlockStore

from .voyage import IDENTIFY_ARGS, identify_run, selected_modes, write_voyage

ARGS = [a for a in IDENTIFY_ARGS if a != "--quiet"]
MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


def _at_twice_the_rate(path) -> None:
    """The file as a recorder set to twice the rate writes it (each sample repeated)."""
    record = read_accelerations(path)
    twice = AccelerationRecord(
        np.repeat(record.acceleration, 2, axis=0),
        2 * record.sampling_rate_hz,
        record.start_time,
        record.channels,
    )
    write_accelerations(twice, path)


def _identify(capsys, folder, out, extra=()):
    return identify_run(capsys, folder, out, [*ARGS, *extra])


_modes = selected_modes


@pytest.mark.parametrize("odd", [0, 3], ids=["first file", "later file"])
def test_a_file_at_another_rate_is_left_out_and_the_rest_identified(tmp_path, capsys, odd):
    files = write_voyage(tmp_path / "acc", n_files=6)
    shutil.copytree(tmp_path / "acc", tmp_path / "without")
    (tmp_path / "without" / files[odd].name).unlink()
    _at_twice_the_rate(files[odd])
    code, out, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 0, err  # main: exit 1, "sampling rate 64 Hz differs from 32 Hz of 5 ..."
    note = (
        f"{files[odd].name}: not used: sampling rate 64 Hz, not 32 Hz (that of 5 of the 6 "
        "files); its span is a gap"
    )
    assert note in out.splitlines()
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    if odd == 0:  # the grid starts at the first file used: four whole blocks
        assert blocks["status"].tolist() == ["ok"] * 4
    else:  # 2-min blocks every minute: blocks 2 and 3 over the minute of acc_003
        assert blocks["status"].tolist() == ["ok", "ok", "skipped", "skipped", "ok"]
        assert blocks["reason"][2] == "gap of 60.0 s between acc_002.npz and acc_004.npz"
    # nothing else changes: the voyage without the file, to the last bit
    code, _, err = _identify(capsys, tmp_path / "without", tmp_path / "without_out")
    assert code == 0, err
    modes, without = _modes(tmp_path / "out"), _modes(tmp_path / "without_out")
    assert len(modes) == 2 * (blocks["status"] == "ok").sum()
    assert modes["block"].tolist() == without["block"].tolist()
    np.testing.assert_allclose(modes["frequency_hz"], without["frequency_hz"], rtol=0, atol=1e-12)


def test_the_monitor_takes_the_rate_of_most_files_not_the_first(tmp_path, capsys):
    files = write_voyage(tmp_path / "watch", n_files=6)
    _at_twice_the_rate(files[0])
    state = tmp_path / "state"
    code = main(
        ["monitor", "--watch", str(tmp_path / "watch"), "--state", str(state), *MONITOR_ARGS]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    health = pd.read_parquet(state / "data_health.parquet").sort_values("block")
    # main: the voyage at 64 Hz, every good file "not used: sampling rate 32 Hz, not 64 Hz"
    assert health["status"].tolist() == ["ok"] * 4
    notes = (state / "notes.txt").read_text(encoding="utf-8")
    assert (
        "acc_000.npz: not used: sampling rate 64 Hz, not 32 Hz (the voyage's: that of most "
        "files); its span is a gap"
    ) in notes
    assert "acc_001.npz: not used" not in notes
    code, _, err = _identify(capsys, tmp_path / "watch", tmp_path / "batch")
    assert code == 0, err
    batch = _modes(tmp_path / "batch")
    stored = BlockStore(state / "store").read("selected")
    monitor = stored.sort_values(["block", "frequency_hz"])[["block", "frequency_hz"]]
    assert monitor["block"].tolist() == batch["block"].tolist()
    np.testing.assert_allclose(monitor["frequency_hz"], batch["frequency_hz"], rtol=0, atol=1e-12)


def test_files_split_between_rates_are_an_error_naming_them(tmp_path, capsys):
    files = write_voyage(tmp_path / "acc", n_files=4)
    for path in files[:2]:
        _at_twice_the_rate(path)
    code, _, err = _identify(capsys, tmp_path / "acc", tmp_path / "out")
    assert code == 1
    assert err.strip().splitlines() == [
        f"error: {files[0]}: no sampling rate is shared by more than half of the 4 files "
        "(64 Hz: acc_000.npz, acc_001.npz; 32 Hz: acc_002.npz, acc_003.npz); give the files "
        "of one recording"
    ]
    assert not (tmp_path / "out" / "selected.parquet").exists()
