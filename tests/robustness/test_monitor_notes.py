"""Every note of the monitor reaches the user.

Before: ``workbench monitor`` ended with its last 10 notes only (``messages[-10:]``), and
a long run kept its last 200 in memory: a voyage whose first files were refused (other
channels) ended naming the last ten of them, the others lost without a count. Now every
note goes, with its UTC time, to ``<state>/notes.txt`` as it is made (kept over restarts),
and when more notes were made than are printed, the printed lines say how many and name
that file.

The voyage is the small one of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from workbench.cli import main

from .voyage import IDENTIFY_ARGS, write_voyage

MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


def _other_channels(path: Path) -> None:
    """Rewrite the .npz *path* as a recorder of other channels would have written it (each
    file's channels its own, so the voyage's remain those of the untouched files)."""
    with np.load(path, allow_pickle=False) as archive:
        record = dict(archive)
    with open(path, "wb") as handle:
        np.savez(
            handle,
            acceleration=record["acceleration"],
            sampling_rate_hz=record["sampling_rate_hz"],
            start_time=record["start_time"],
            channels=np.array([f"x{k}_{path.stem}" for k in range(1, 5)]),
        )


def _monitor(capsys, watch: Path, state: Path) -> list[str]:
    argv = ["monitor", "--watch", watch, "--state", state, *MONITOR_ARGS]
    status = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert status == 0, captured.err
    return captured.out.splitlines()


def test_more_than_ten_notes_are_all_kept_and_the_printed_lines_say_where(tmp_path, capsys):
    watch, state = tmp_path / "watch", tmp_path / "state"
    paths = write_voyage(watch, n_files=15)
    for path in paths[2:14]:  # 12 files of another recorder
        _other_channels(path)
    lines = _monitor(capsys, watch, state)
    refused = [f"{p.name}: not used: channels differ" for p in paths[2:14]]
    printed = [line for line in lines if line.startswith("note: ")]
    assert len(printed) <= 11
    notes_file = state / "notes.txt"
    pointer = [line for line in printed if str(notes_file) in line]
    assert len(pointer) == 1, lines
    written = notes_file.read_text(encoding="utf-8").splitlines()
    for expected in refused:  # every one of them, each once
        assert sum(expected in line for line in written) == 1, expected
    # each written line: UTC time, then the note as printed
    assert all(re.match(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ \S", line) for line in written)
    n_notes = len(written)
    assert f"{n_notes} notes" in pointer[0]
    # a restart appends, losing nothing
    _monitor(capsys, watch, state)
    again = notes_file.read_text(encoding="utf-8").splitlines()
    assert again[:n_notes] == written


def test_a_few_notes_are_all_printed(tmp_path, capsys):
    watch, state = tmp_path / "watch", tmp_path / "state"
    paths = write_voyage(watch, n_files=5)
    _other_channels(paths[3])
    lines = _monitor(capsys, watch, state)
    assert any("acc_003.npz: not used: channels differ" in line for line in lines)
    assert not any("notes.txt" in line for line in lines)
