"""A monitor restarted on a state folder whose table parts a crash (or a full disk) cut
short writes those tables again instead of stopping with a traceback.

Before: a ``tracked.parquet``, ``data_health.parquet``, ``forecast.parquet`` or
``health.parquet`` part file cut in half ended the next ``workbench monitor`` with
"pyarrow.lib.ArrowInvalid: Parquet magic bytes not found in footer" and a traceback, so
the monitor could not be restarted on its state folder at all (the store, the truth, was
whole). Now the unreadable part is removed with one note naming it, and the table is
written again: the tracked and data-health tables from the store, the forecast from the
first block; the tables equal those before the damage.

The voyage is the small one of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute: 12 files give blocks 0-10), with a 1-s ship log and a
training window of 4 blocks so the forecast has rows.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main

from .voyage import IDENTIFY_ARGS, T0, write_voyage

MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]
MONITOR_ARGS += ["--train-blocks", "5", "--scheme", "single-window"]
TABLES = ("tracked.parquet", "data_health.parquet", "forecast.parquet", "health.parquet")


def _log(path: Path, seconds: int = 780) -> None:
    times = pd.date_range(T0.tz_localize(None), periods=seconds, freq="1s")
    rows = [
        f"{t:%Y-%m-%dT%H:%M:%S}\t{8 + 4 * (k % 120) / 120:.2f}\t2.0\t-1.0\t5.0\t90"
        for k, t in enumerate(times)
    ]
    header = "Date/Time\tSpeed [kn]\tTemp [°C]\tTTT [°C]\tff [m/s]\tRelWindDir [deg]"
    path.write_text("\n".join([header, *rows]) + "\n", encoding="utf-8")


def _monitor(capsys, folder: Path) -> list[str]:
    argv = ["monitor", "--watch", folder / "watch", "--state", folder / "state"]
    status = main([str(a) for a in [*argv, "--dship", folder / "dship.tsv", *MONITOR_ARGS]])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    assert status == 0, captured.err
    return captured.out.splitlines()


@pytest.fixture(scope="module")
def monitored(tmp_path_factory) -> tuple[Path, dict[str, pd.DataFrame]]:
    folder = tmp_path_factory.mktemp("damaged_state")
    write_voyage(folder / "watch", n_files=12)
    _log(folder / "dship.tsv")
    argv = ["monitor", "--watch", folder / "watch", "--state", folder / "state"]
    assert main([str(a) for a in [*argv, "--dship", folder / "dship.tsv", *MONITOR_ARGS]]) == 0
    tables = {name: pd.read_parquet(folder / "state" / name) for name in TABLES}
    assert len(tables["forecast.parquet"]) > 0
    return folder, tables


@pytest.mark.parametrize("name", TABLES)
def test_a_part_cut_short_is_written_again(monitored, capsys, name):
    folder, before = monitored
    part = folder / "state" / name / "part-000000.parquet"
    data = part.read_bytes()
    part.write_bytes(data[: len(data) // 2])
    lines = _monitor(capsys, folder)
    notes = [line for line in lines if line.startswith(f"note: {name}: part-000000.parquet")]
    assert len(notes) == 1, lines
    assert "unreadable" in notes[0] and "removed" in notes[0]
    for table, expected in before.items():
        pd.testing.assert_frame_equal(pd.read_parquet(folder / "state" / table), expected)
