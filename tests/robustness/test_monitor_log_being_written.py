"""An update of the monitor that cannot read the ship log (a line cut short in it) keeps
the forecast and health tables computed before; the line the data system is writing
(no line end yet) is left out until it is whole.

Before: the outlook wrote empty forecast, health and alarm tables whenever its update
failed, so a restart (or any update) that read the log in the middle of a line being
appended wiped the whole forecast: 22 rows before, 0 after, until an update read the log
whole again (with ``--once``: for good). Now the failure is said in a note and the tables
stay as they were.

The voyage is the small one of :mod:`tests.robustness.voyage` (12 files give blocks 0-10)
with a 1-s ship log and a training window of 5 blocks, as in
:mod:`tests.robustness.test_monitor_damaged_state`.
"""

from __future__ import annotations

import pandas as pd
import pytest

from data_contracts import ContractError, read_dship
from workbench.cli import main

from .test_monitor_damaged_state import MONITOR_ARGS, _log
from .voyage import write_voyage


def test_a_log_caught_mid_line_keeps_the_forecast(tmp_path, capsys):
    write_voyage(tmp_path / "watch", n_files=12)
    log = tmp_path / "dship.tsv"
    _log(log)
    argv = ["monitor", "--watch", tmp_path / "watch", "--state", tmp_path / "state"]
    argv = [str(a) for a in [*argv, "--dship", log, *MONITOR_ARGS]]
    assert main(argv) == 0
    capsys.readouterr()
    state = tmp_path / "state"
    before = {
        name: pd.read_parquet(state / name)
        for name in ("forecast.parquet", "health.parquet", "alarms.parquet")
    }
    assert len(before["forecast.parquet"]) > 0
    with open(log, "a", encoding="utf-8") as handle:
        handle.write("2026-03-01T0\n")  # a line cut short, then the next one begun
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert any(line.startswith(f"note: forecast: {log}") for line in out.splitlines()), out
    for name, table in before.items():
        pd.testing.assert_frame_equal(pd.read_parquet(state / name), table)


def test_the_line_being_written_is_left_out_until_it_is_whole(tmp_path, capsys):
    """Before: the whole log was refused for the cut time ("not an ISO-8601 time:
    '2026-03-01T0'"), and a cut time that reads as another one ("2026-03-01T01", an hour
    ahead) made the log seem to reach further than it does."""
    write_voyage(tmp_path / "watch", n_files=12)
    log = tmp_path / "dship.tsv"
    _log(log)
    with open(log, "a", encoding="utf-8") as handle:
        handle.write("2026-03-01T0")
    argv = ["monitor", "--watch", tmp_path / "watch", "--state", tmp_path / "state"]
    assert main([str(a) for a in [*argv, "--dship", log, *MONITOR_ARGS]]) == 0
    out = capsys.readouterr().out
    assert not [line for line in out.splitlines() if line.startswith(f"note: forecast: {log}")]
    assert len(pd.read_parquet(tmp_path / "state" / "forecast.parquet")) > 0
    for cut in ("2026-03-01T01", "2026-03-01T00:13", "2026-03-01T00:13:00\t9.5\t2.0\t-1"):
        path = tmp_path / "cut.tsv"
        path.write_text(log.read_text(encoding="utf-8")[: -len("2026-03-01T0")] + cut)
        if cut == "2026-03-01T01":  # no minutes: refused (test_time_digits)
            with pytest.raises(ContractError, match="'2026-03-01T01'"):
                read_dship(path)
        else:
            whole = read_dship(path)
            assert whole["time"].max() > pd.Timestamp("2026-03-01T00:12:59Z")
        kept = read_dship(path, complete_lines=True)
        assert kept["time"].max() == pd.Timestamp("2026-03-01T00:12:59Z")
