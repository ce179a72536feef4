"""The monitor fixes its block grid and channels only once the data landed reach the end of
the first block (or ``--late`` past the earliest file), not at the first file it sees.

Before: a live monitor anchored the grid and took the channels from the first complete
file. The voyage's first file landing after its second (copied late, a slow share) was
refused ("starts before the monitor's first block"), so the monitor lost block 0 and
numbered every block one less than ``workbench identify`` over the same folder; and a
first file lacking a channel the next files carry made the monitor leave that channel out
of the whole voyage. No block can be decided before its data have landed, so waiting
delays none; ``--once`` and a restart on a stored grid do not wait.

The voyage is the small one of :mod:`tests.robustness.voyage` (60-s files at 32 Hz); the
files are copied into the watched folder one at a time, a monitor step after each.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd

from workbench.cli import main, parse_arguments
from workbench.cli.monitoring import prepare_monitor

from .test_monitor_dropped_channel import _keep_channels
from .voyage import IDENTIFY_ARGS, write_voyage


def _arguments(blocks: list[str]) -> list[str]:
    args = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
    return [*args, *blocks]


def _live(tmp_path: Path, files: list[Path], order: list[int], blocks: list[str]) -> list[str]:
    watch, state = tmp_path / "watch", tmp_path / "state"
    watch.mkdir()
    argv = ["monitor", "--watch", watch, "--state", state, *_arguments(blocks)]
    argv += ["--late", "180", "--settle", "0", "--poll", "0.05", "--foreground"]
    monitor = prepare_monitor(parse_arguments([str(a) for a in argv]))
    try:
        for k in order:
            shutil.copy(files[k], watch / files[k].name)
            monitor.step()
        monitor.step(flush=True)
    finally:
        monitor.close()
    return list(monitor.messages)


def _batch(capsys, tmp_path: Path, source: Path, blocks: list[str]) -> pd.DataFrame:
    batch = tmp_path / "batch"
    argv = ["identify", str(source), "--out", str(batch), *IDENTIFY_ARGS, *blocks]
    assert main(argv) == 0
    assert main(["track", str(batch / "selected.parquet"), "--out", str(batch / "t.parquet")]) == 0
    capsys.readouterr()
    return pd.read_parquet(batch / "t.parquet")


def _assert_same(state: Path, tracked: pd.DataFrame) -> None:
    monitored = pd.read_parquet(state / "tracked.parquet")
    assert sorted(monitored.columns) == sorted(tracked.columns)
    pd.testing.assert_frame_equal(
        monitored.reset_index(drop=True),
        tracked[list(monitored.columns)].reset_index(drop=True),
        check_dtype=False,
    )


def test_a_first_file_landing_after_the_second_anchors_the_grid(tmp_path, capsys):
    files = write_voyage(tmp_path / "source", n_files=7)
    notes = _live(tmp_path, files, [1, 0, 2, 3, 4, 5, 6], [])
    assert not [n for n in notes if "not used" in n], notes
    _assert_same(tmp_path / "state", _batch(capsys, tmp_path, tmp_path / "source", []))


def test_a_channel_the_first_file_lacks_is_kept_when_files_land_one_by_one(tmp_path, capsys):
    blocks = ["--block-minutes", "3"]  # block k: files k, k + 1, k + 2
    files = write_voyage(tmp_path / "source", n_files=7)
    _keep_channels(files[0], ["acc01", "acc02", "acc04"])
    notes = _live(tmp_path, files, list(range(7)), blocks)
    assert not [n for n in notes if "not among the voyage's" in n], notes
    health = pd.read_parquet(tmp_path / "state" / "data_health.parquet")
    assert health["dropped_channels"].tolist()[:2] == ["acc03", ""]
    _assert_same(tmp_path / "state", _batch(capsys, tmp_path, tmp_path / "source", blocks))
