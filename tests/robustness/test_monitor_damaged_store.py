"""``monitor --once`` over a state folder whose store index cannot be read says so and
exits 1, instead of exit 0 ("11 block(s) decided") with every file refused in notes.

Before: with ``store/inputs.json`` cut short, each file of the watched folder was "not
used: ... the store is damaged", the run added nothing, and the command printed the
blocks an earlier run had decided and exited 0. The tables the earlier run wrote are kept.
"""

from __future__ import annotations

import json

import pandas as pd

from workbench.cli import main

from .voyage import IDENTIFY_ARGS, write_voyage

MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


def test_once_over_a_damaged_store_is_an_error_and_keeps_the_tables(tmp_path, capsys):
    write_voyage(tmp_path / "watch", n_files=12)
    state = tmp_path / "state"
    argv = [str(a) for a in ["monitor", "--watch", tmp_path / "watch", "--state", state]]
    assert main([*argv, *MONITOR_ARGS]) == 0
    tracked = pd.read_parquet(state / "tracked.parquet")
    assert len(tracked)
    capsys.readouterr()
    (state / "store" / "inputs.jsonl").write_text('{"cut\n', encoding="utf-8")
    assert main([*argv, *MONITOR_ARGS]) == 1
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    error = [line for line in captured.err.splitlines() if line.startswith("error:")]
    assert len(error) == 1
    assert "inputs.jsonl is unreadable (line 1:" in error[0] and str(state / "store") in error[0]
    assert "block(s) decided" not in captured.out
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), tracked)


def _stored(state) -> dict[str, bytes]:
    """The store's block files and manifest, by relative path."""
    store = state / "store"
    files = [*store.glob("*/day=*/*.parquet"), store / "manifest.jsonl"]
    return {p.relative_to(store).as_posix(): p.read_bytes() for p in files}


def _recorded(index) -> list[dict]:
    """The fingerprints recorded in the store's inputs.jsonl."""
    lines = index.read_text(encoding="utf-8").splitlines()
    return [entry["file"] for entry in map(json.loads, lines) if "file" in entry]


def _moved_aside(error: str, path) -> None:
    """Follow the recovery the error names: ``mv PATH PATH.damaged``."""
    assert f"mv {path} {path}.damaged" in error, error
    path.rename(f"{path}.damaged")


def _first_run(tmp_path, capsys):
    write_voyage(tmp_path / "watch", n_files=12)
    state = tmp_path / "state"
    argv = [str(a) for a in ["monitor", "--watch", tmp_path / "watch", "--state", state]]
    assert main([*argv, *MONITOR_ARGS]) == 0
    capsys.readouterr()
    return state, argv


def test_a_damaged_input_index_moved_aside_keeps_every_computed_block(tmp_path, capsys):
    """Before: the message said "delete the folder (or use another --store)", which threw
    away the 11 computed blocks. Now it names the move that keeps them; after it the
    resumed run identifies nothing again (block files and manifest byte-identical), says
    the inputs are recorded unchecked, and fingerprints the 12 files as they were."""
    state, argv = _first_run(tmp_path, capsys)
    tracked = pd.read_parquet(state / "tracked.parquet")
    stored = _stored(state)
    index = state / "store" / "inputs.jsonl"
    before = _recorded(index)
    index.write_text('{"cut\n', encoding="utf-8")
    assert main([*argv, *MONITOR_ARGS]) == 1
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "delete" not in error[0] and "another --state" in error[0]
    _moved_aside(error[0], index)
    assert main([*argv, *MONITOR_ARGS]) == 0
    out = capsys.readouterr().out
    assert "inputs.jsonl was absent: the input files of the 11 stored block(s) 0-10" in out
    assert "block 0:" not in out  # nothing identified again
    assert _stored(state) == stored
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), tracked)
    after = _recorded(index)
    assert sorted(f["sha256"] for f in after) == sorted(f["sha256"] for f in before)
    assert len(after) == 12


def test_damaged_parameters_moved_aside_keep_the_blocks_of_the_same_options(tmp_path, capsys):
    """``store/store.json`` (the parameters and grid): before, "unreadable; use another
    --state". Now the move that keeps the blocks is named; the run with the same options
    resumes (nothing identified again, the parameters written as they were), and a run
    whose blocks fall elsewhere (another step) is refused, the blocks kept."""
    state, argv = _first_run(tmp_path, capsys)
    tracked = pd.read_parquet(state / "tracked.parquet")
    stored = _stored(state)
    config = state / "store" / "store.json"
    parameters = config.read_text(encoding="utf-8")
    config.write_text("{", encoding="utf-8")
    assert main([*argv, *MONITOR_ARGS]) == 1
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "delete" not in error[0]
    _moved_aside(error[0], config)
    other = [*MONITOR_ARGS]
    other[other.index("--step-minutes") + 1] = "2"
    assert main([*argv, *other]) == 1
    refused = capsys.readouterr().err.strip().splitlines()
    assert len(refused) == 1 and "block(s) 1-10 are not on this run's grid" in refused[0]
    assert not config.exists() and _stored(state) == stored
    assert main([*argv, *MONITOR_ARGS]) == 0
    out = capsys.readouterr().out
    assert "store.json was absent: the 11 stored block(s) 0-10 are taken as computed" in out
    assert "block 0:" not in out
    assert _stored(state) == stored
    assert json.loads(config.read_text(encoding="utf-8")) == json.loads(parameters)
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), tracked)
