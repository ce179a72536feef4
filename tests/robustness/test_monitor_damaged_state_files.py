"""A monitor state folder whose ``state_format.json`` or ``labels.json`` cannot be read is
resumed when its other files prove what the damaged one said, else refused in one line
naming the recovery; nothing computed is lost either way.

Before: either file cut short (a crash, a full disk) stopped every later ``workbench
monitor`` on the folder with "unreadable; use another --state": the blocks computed so far
were only to be had by starting again elsewhere. Now:

* ``state_format.json`` is written again when the folder's growing tables are parted
  tables of this workbench's format (a format-1 table is one file: refused);
* ``labels.json`` is written again when tracking the stored blocks again gives the modes
  of the tracked table the earlier run wrote (same modes at the same blocks and
  frequencies); other tracking options give other modes: refused, the files kept.

The voyage is the small one of :mod:`tests.robustness.voyage` (12 files, blocks 0-10).
"""

from __future__ import annotations

import json
import shutil

import pandas as pd

from workbench.cli import main
from workbench.monitor.state_format import STATE_FORMAT

from .test_monitor_damaged_store import MONITOR_ARGS, _first_run, _moved_aside, _stored


def _again(argv, capsys, args=MONITOR_ARGS) -> tuple[int, str, list[str]]:
    status = main([*argv, *args])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return status, captured.out, [line for line in captured.err.splitlines() if line.strip()]


def test_an_unreadable_format_file_of_parted_tables_is_written_again(tmp_path, capsys):
    state, argv = _first_run(tmp_path, capsys)
    tracked = pd.read_parquet(state / "tracked.parquet")
    stored = _stored(state)
    (state / "state_format.json").write_text('{"sche', encoding="utf-8")
    status, out, err = _again(argv, capsys)
    assert status == 0, err
    assert f"{state / 'state_format.json'}: unreadable" in out and "written again" in out
    assert json.loads((state / "state_format.json").read_text()) == {"schema": STATE_FORMAT}
    assert "block 0:" not in out and _stored(state) == stored
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), tracked)


def test_an_unreadable_format_file_of_whole_tables_is_refused(tmp_path, capsys):
    """A growing table that is one file is of format 1 (or of none this workbench
    knows): the format is not proven, and nothing is written or removed."""
    state, argv = _first_run(tmp_path, capsys)
    shutil.rmtree(state / "health.parquet")
    (state / "health.parquet").write_bytes(b"PAR1")
    (state / "state_format.json").write_text("", encoding="utf-8")
    stored = _stored(state)
    status, _, err = _again(argv, capsys)
    assert status == 1 and len(err) == 1
    assert "state_format.json: unreadable" in err[0] and "does not show its format" in err[0]
    assert "health.parquet: one file, not parted" in err[0]
    assert (state / "state_format.json").read_text() == ""
    assert (state / "health.parquet").read_bytes() == b"PAR1" and _stored(state) == stored


def test_unreadable_labels_are_given_again_when_the_replay_gives_the_same_modes(tmp_path, capsys):
    state, argv = _first_run(tmp_path, capsys)
    tracked = pd.read_parquet(state / "tracked.parquet")
    labels = json.loads((state / "labels.json").read_text(encoding="utf-8"))
    assert len(labels["labels"]) == 2
    stored = _stored(state)
    (state / "labels.json").write_text('{"schema": "workbench.mon', encoding="utf-8")
    status, out, err = _again(argv, capsys)
    assert status == 0, err
    assert f"{state / 'labels.json'}: unreadable" in out
    assert "written again: tracking the stored blocks again gives the modes" in out
    assert "(22 rows, blocks 0-10)" in out
    assert json.loads((state / "labels.json").read_text(encoding="utf-8")) == labels
    assert "block 0:" not in out and _stored(state) == stored
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), tracked)


def test_unreadable_labels_with_other_tracking_options_are_refused(tmp_path, capsys):
    """A frequency tolerance of 0.01 % splits the modes otherwise: the labels shown
    before would not come back. Refused; the tables and the damaged file are kept."""
    state, argv = _first_run(tmp_path, capsys)
    tracked = pd.read_parquet(state / "tracked.parquet")
    (state / "labels.json").write_text("{", encoding="utf-8")
    status, _, err = _again(argv, capsys, [*MONITOR_ARGS, "--frequency-tol", "0.0001"])
    assert status == 1 and len(err) == 1
    assert "labels.json: unreadable" in err[0] and "other modes than" in err[0]
    assert "use them, or another --state" in err[0]
    assert (state / "labels.json").read_text() == "{"
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), tracked)


def test_unreadable_labels_without_a_tracked_table_name_the_move_that_resumes(tmp_path, capsys):
    state, argv = _first_run(tmp_path, capsys)
    labels = json.loads((state / "labels.json").read_text(encoding="utf-8"))
    tracked = pd.read_parquet(state / "tracked.parquet")
    shutil.rmtree(state / "tracked.parquet")
    (state / "labels.json").write_text("{", encoding="utf-8")
    status, _, err = _again(argv, capsys)
    assert status == 1 and len(err) == 1 and "no tracked table" in err[0]
    _moved_aside(err[0], state / "labels.json")
    status, out, err = _again(argv, capsys)
    assert status == 0, err
    assert "block 0:" not in out
    assert json.loads((state / "labels.json").read_text(encoding="utf-8")) == labels
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), tracked)
