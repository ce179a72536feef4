"""An update of the monitor that cannot read the ship log (caught while its last line was
being written) keeps the forecast and health tables computed before.

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
        handle.write("2026-03-01T0")  # the data system writing its next line
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert any(line.startswith(f"note: forecast: {log}") for line in out.splitlines()), out
    for name, table in before.items():
        pd.testing.assert_frame_equal(pd.read_parquet(state / name), table)
