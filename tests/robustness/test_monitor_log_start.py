"""A ship log that starts after the first blocks is named in the monitor's notes; a log cut
at its start (or replaced by a newer file) while the monitor was down is refused at the
restart, the state folder untouched.

Before: the monitor recomputed the forecast of every block from the log as it found it, so
after a restart with a log whose first two hours were gone every forecast row of the 3-h
voyage changed, the early blocks now without predictors, and nothing said so. Later (session
54) the state folder records the bytes of the log it read (``ship_log.json``): its health
chart came from them, so another log is refused (exit 1) rather than mixed in; a new state
folder over the cut log names the blocks without predictors.

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


def _monitor(tmp_path, capsys, state="state", code=0) -> list[str]:
    argv = ["monitor", "--watch", tmp_path / "voyage", "--state", tmp_path / state]
    argv += ["--dship", tmp_path / "dship.tsv", *MONITOR_ARGS]
    assert main([str(a) for a in argv]) == code
    captured = capsys.readouterr()
    if code:
        return captured.err.strip().splitlines()
    return [line for line in captured.out.splitlines() if line.startswith("note: ship log: starts")]


def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_log_cut_at_its_start_is_refused_at_a_restart_and_named_in_a_new_state(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=6)
    _log(tmp_path / "dship.tsv", 0)
    assert _monitor(tmp_path, capsys) == []
    before = _snapshot(tmp_path / "state")
    _log(tmp_path / "dship.tsv", 200)  # the log's first 200 s gone
    [line] = _monitor(tmp_path, capsys, code=1)
    assert "dship.tsv: changed since the state folder" in line
    assert "cut short or replaced" in line
    assert _snapshot(tmp_path / "state") == before
    assert _monitor(tmp_path, capsys, state="state2") == [
        "note: ship log: starts at 2026-03-01T00:03:20Z, after block(s) 0-1 (from "
        "2026-03-01T00:00:00Z): they have no predictors (a log cut at its start, or another "
        "file?)"
    ]
    status = json.loads((tmp_path / "state2" / "status.json").read_text(encoding="utf-8"))
    assert status["state"] == "stopped"
