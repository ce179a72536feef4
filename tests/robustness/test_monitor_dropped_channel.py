"""A file lacking a channel (a recorder that dropped it for a while) is used by the monitor
as by ``workbench identify``: read with the channel NaN, which the blocks holding it drop.

Before: the monitor refused the whole file ("acc_002.npz: not used: other channels than
the voyage's"), so the blocks over it were skipped (no data) where identify identifies
them without the channel: the monitor's tracked table lost blocks 1-2 of the batch's.
A file lacking more than half of the channels is still refused (not the same recorder's),
now naming them; one with a channel the voyage does not have is used without it, and
says so.

The voyages are the small ones of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute): 6 files give blocks 0-4, block k holding files k and k + 1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from workbench.cli import main

from .voyage import CHANNELS, IDENTIFY_ARGS, write_voyage

MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


def _keep_channels(path: Path, keep: list[str]) -> None:
    """Rewrite the .npz *path* with only the channels *keep* (in that order)."""
    with np.load(path, allow_pickle=False) as archive:
        record = dict(archive)
    columns = [list(CHANNELS).index(c) if c in CHANNELS else 0 for c in keep]
    with open(path, "wb") as handle:
        np.savez(
            handle,
            acceleration=record["acceleration"][:, columns],
            sampling_rate_hz=record["sampling_rate_hz"],
            start_time=record["start_time"],
            channels=np.array(keep),
        )


def _monitor(capsys, watch: Path, state: Path) -> tuple[int, str, str]:
    status = main([str(a) for a in ["monitor", "--watch", watch, "--state", state, *MONITOR_ARGS]])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_a_file_lacking_a_channel_gives_the_blocks_identify_gives(tmp_path, capsys):
    watch, state = tmp_path / "watch", tmp_path / "state"
    paths = write_voyage(watch, n_files=6)
    _keep_channels(paths[2], ["acc01", "acc02", "acc04"])
    status, out, err = _monitor(capsys, watch, state)
    assert status == 0, err
    assert (
        "note: acc_002.npz: channel(s) acc03 missing; NaN there, dropped as faulty in the "
        "blocks holding it"
    ) in out.splitlines()
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["status"].tolist() == ["ok"] * 5
    assert health["dropped_channels"].tolist() == ["", "acc03", "acc03", "", ""]
    # the batch commands over the same files
    batch = tmp_path / "batch"
    argv = ["identify", str(watch), "--out", str(batch), *IDENTIFY_ARGS]
    assert main(argv) == 0
    assert main(["track", str(batch / "selected.parquet"), "--out", str(batch / "t.parquet")]) == 0
    capsys.readouterr()
    monitored = pd.read_parquet(state / "tracked.parquet")
    tracked = pd.read_parquet(batch / "t.parquet")[list(monitored.columns)]
    assert sorted(monitored["block"].unique()) == [0, 1, 2, 3, 4]
    pd.testing.assert_frame_equal(
        monitored.reset_index(drop=True), tracked.reset_index(drop=True), check_dtype=False
    )


def test_a_channel_missing_from_the_first_file_only_is_kept_as_identify_keeps_it(tmp_path, capsys):
    """The first file lacks acc03, the others carry it: identify takes the channels most
    files carry (acc01-acc04), the first file's acc03 NaN. Before: the monitor took the
    first file's (acc01, acc02, acc04) and left acc03 out of every block of the voyage,
    its tracked table lacking acc03's shape columns."""
    watch, state = tmp_path / "watch", tmp_path / "state"
    paths = write_voyage(watch, n_files=6)
    _keep_channels(paths[0], ["acc01", "acc02", "acc04"])
    status, out, err = _monitor(capsys, watch, state)
    assert status == 0, err
    assert "not among the voyage's" not in out
    assert "note: acc_000.npz: channel(s) acc03 missing" in out
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["n_channels"].tolist() == [3, 4, 4, 4, 4]
    assert health["dropped_channels"].tolist() == ["acc03", "", "", "", ""]
    batch = tmp_path / "batch"
    argv = ["identify", str(watch), "--out", str(batch), *IDENTIFY_ARGS]
    assert main(argv) == 0
    assert main(["track", str(batch / "selected.parquet"), "--out", str(batch / "t.parquet")]) == 0
    capsys.readouterr()
    monitored = pd.read_parquet(state / "tracked.parquet")
    tracked = pd.read_parquet(batch / "t.parquet")
    assert "shape_re_acc03" in monitored.columns
    assert sorted(monitored.columns) == sorted(tracked.columns)
    pd.testing.assert_frame_equal(
        monitored.reset_index(drop=True),
        tracked[list(monitored.columns)].reset_index(drop=True),
        check_dtype=False,
    )


def test_a_file_of_other_channels_is_refused_naming_them_or_used_without_the_extra_one(
    tmp_path, capsys
):
    watch, state = tmp_path / "watch", tmp_path / "state"
    paths = write_voyage(watch, n_files=6)
    _keep_channels(paths[2], ["acc01", "x1", "x2", "x3"])
    _keep_channels(paths[4], [*CHANNELS, "acc05"])
    status, out, err = _monitor(capsys, watch, state)
    assert status == 0, err
    lines = out.splitlines()
    assert (
        "note: acc_002.npz: not used: channels differ from the voyage's (missing acc02, "
        "acc03, acc04; extra x1, x2, x3)"
    ) in lines
    assert (
        "note: acc_004.npz: channel(s) acc05 not among the voyage's (those most files "
        "carried when the monitor started); left out"
    ) in lines
    health = pd.read_parquet(state / "data_health.parquet")
    assert health["status"].tolist() == ["ok", "skipped", "skipped", "ok", "ok"]
