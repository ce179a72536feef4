"""A ship log that starts after the first blocks (cut at its start, or replaced by a newer
file while the monitor was down) is named in the monitor's notes.

Before: the monitor recomputed the forecast of every block from the log as it found it
(by design: results equal the batch commands' over the same files), so after a restart
with a log whose first two hours were gone every forecast row of the 3-h voyage changed,
the early blocks now without predictors, and nothing said so; ``workbench forecast
--dship`` over the same log warns of the blocks without a predictor value.

The voyage is the small one of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute; 6 files give blocks 0-4); the log, one row a second.
"""

from __future__ import annotations

import json

import pandas as pd

from workbench.cli import main

from .voyage import IDENTIFY_ARGS, T0, write_voyage

MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


def _log(path, first_s: int, last_s: int = 360) -> None:
    times = pd.date_range(
        T0.tz_localize(None) + pd.Timedelta(seconds=first_s), periods=last_s - first_s, freq="1s"
    )
    rows = [f"{t:%Y-%m-%dT%H:%M:%S}\t10.0\t2.0" for t in times]
    path.write_text("\n".join(["Date/Time\tSpeed [kn]\tTemp [°C]", *rows]) + "\n")


def _monitor(tmp_path, capsys) -> list[str]:
    argv = ["monitor", "--watch", tmp_path / "voyage", "--state", tmp_path / "state"]
    assert main([str(a) for a in [*argv, "--dship", tmp_path / "dship.tsv", *MONITOR_ARGS]]) == 0
    out = capsys.readouterr().out
    return [line for line in out.splitlines() if line.startswith("note: ship log: starts")]


def test_a_log_starting_after_the_first_blocks_is_named_also_after_a_restart(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=6)
    _log(tmp_path / "dship.tsv", 0)
    assert _monitor(tmp_path, capsys) == []
    _log(tmp_path / "dship.tsv", 200)  # the log's first 200 s gone
    assert _monitor(tmp_path, capsys) == [
        "note: ship log: starts at 2026-03-01T00:03:20Z, after block(s) 0-1 (from "
        "2026-03-01T00:00:00Z): they have no predictors (a log cut at its start, or another "
        "file?)"
    ]
    status = json.loads((tmp_path / "state" / "status.json").read_text(encoding="utf-8"))
    assert status["state"] == "stopped"
