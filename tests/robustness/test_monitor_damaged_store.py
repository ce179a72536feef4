"""``monitor --once`` over a state folder whose store index cannot be read says so and
exits 1, instead of exit 0 ("11 block(s) decided") with every file refused in notes.

Before: with ``store/inputs.json`` cut short, each file of the watched folder was "not
used: ... the store is damaged", the run added nothing, and the command printed the
blocks an earlier run had decided and exited 0. The tables the earlier run wrote are kept.
"""

from __future__ import annotations

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
    (state / "store" / "inputs.json").write_text('{"cut', encoding="utf-8")
    assert main([*argv, *MONITOR_ARGS]) == 1
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    error = [line for line in captured.err.splitlines() if line.startswith("error:")]
    assert len(error) == 1
    assert "inputs.json is unreadable" in error[0] and str(state / "store") in error[0]
    assert "block(s) decided" not in captured.out
    pd.testing.assert_frame_equal(pd.read_parquet(state / "tracked.parquet"), tracked)
