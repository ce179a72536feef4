"""A ship log with no readings (a header and no rows, rows of times with every other cell
empty, a blank file) is named as such by every command that reads it.

Before: ``read_dship`` returned an empty log ("valid dship file (0 records ...)"), and
each command said something else: ``forecast --dship`` "no predictor value on any block of
the modal table (...): the ship log or predictor table does not overlap the blocks" (it
did overlap: it held nothing), ``identify --dship`` "harmonics (no shaft speed or speed in
the ship log: none marked)" for a log whose header has both, and ``monitor --dship``
"forecast: the modal table holds only 3 block(s) in the span to forecast, each with
predictors" (none had one). Now the log is refused naming the file: "no readings: the
file has a header and no data rows". A log whose predictor columns are empty throughout
while another column has values (the position) is named so by ``forecast``, and a
predictor table of rows without any value by ``forecast --predictors``.

Inputs: a 1-h simulated voyage's tracked table (no accelerations) and the tiny voyage of
:mod:`tests.robustness.voyage` for identify and monitor.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from data_contracts import ContractError, read_dship
from workbench.cli import main

from .voyage import IDENTIFY_ARGS, write_voyage

HEADER = "Date/Time\tSpeed [kn]\tTemp [°C]\tTTT [°C]\tff [m/s]\tRelWindDir [deg]\tShaft [rpm]\n"
BLANK_ROWS = "".join(f"2026-03-01T00:00:{s:02d}\t\t\t\t\t\t\n" for s in range(10))
LOGS = {
    "header only": (HEADER, "no readings: the file has a header and no data rows"),
    "blank rows": (
        HEADER + BLANK_ROWS,
        "no readings: its 10 data row(s) (lines 2-11) hold no value besides the time",
    ),
    "blank file": ("\n  \n", "no readings: the file is empty (no header line, no data)"),
}
MONITOR_ARGS = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous")]
MONITOR_ARGS += ["--late", "0", "--settle", "0", "--poll", "0.05", "--foreground", "--once"]


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("no_readings") / "sim"
    simulate_voyage(folder, seed=0, hours=1, accelerations=False)
    return folder


def _log(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "dship.tsv"
    path.write_text(text, encoding="utf-8")
    return path


def _run(capsys, argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return status, captured.out, captured.err


@pytest.mark.parametrize("kind", list(LOGS))
def test_read_dship_names_a_log_without_readings(tmp_path, kind):
    text, reason = LOGS[kind]
    path = _log(tmp_path, text)
    with pytest.raises(ContractError) as caught:
        read_dship(path)
    assert str(caught.value) == f"{path}: {reason}"


@pytest.mark.parametrize("kind", list(LOGS))
def test_forecast_says_the_log_has_no_readings_not_that_it_misses_the_blocks(
    sim, tmp_path, capsys, kind
):
    text, reason = LOGS[kind]
    path = _log(tmp_path, text)
    argv = ["forecast", "--modal", sim / "tracked_modal.csv", "--dship", path]
    status, _, err = _run(capsys, [*argv, "--out", tmp_path / "forecast.csv"])
    assert status == 1
    assert err.strip().splitlines() == [f"{path}: {reason}"]
    assert not (tmp_path / "forecast.csv").exists()


def test_forecast_names_a_log_whose_predictor_columns_are_empty(sim, tmp_path, capsys):
    rows = "".join(f"2024-03-01T00:00:{s:02d}\t78.0\t\t\t\t\t\n" for s in range(10))
    path = _log(tmp_path, "Date/Time\tLatitude\t" + HEADER.split("\t", 1)[1] + rows)
    argv = ["forecast", "--modal", sim / "tracked_modal.csv", "--dship", path]
    status, _, err = _run(capsys, [*argv, "--out", tmp_path / "forecast.csv"])
    assert status == 1
    assert err.strip().splitlines()[-1] == (
        f"{path}: no reading of any predictor in its 10 rows (speed_kn, water_temp_c, "
        "air_temp_c, wind_speed_ms, wind_dir_rel_deg empty throughout)"
    )


def test_forecast_names_a_predictor_table_without_any_value(sim, tmp_path, capsys):
    table = pd.read_csv(sim / "truth_predictors.csv")
    keys = ["block", "block_start", "block_end"]
    table[[c for c in table.columns if c not in keys]] = float("nan")
    path = tmp_path / "predictors.csv"
    table.to_csv(path, index=False)
    argv = ["forecast", "--modal", sim / "tracked_modal.csv", "--predictors", path]
    status, _, err = _run(capsys, [*argv, "--out", tmp_path / "forecast.csv"])
    assert status == 1
    line = err.strip().splitlines()[-1]
    assert line.startswith(f"error: {path}: no predictor value in any of its {len(table)} rows")
    assert "does not overlap" not in line


def test_identify_and_monitor_name_the_log_without_readings(tmp_path, capsys):
    watch = tmp_path / "watch"
    write_voyage(watch, n_files=4)
    path = _log(tmp_path, HEADER)
    reason = LOGS["header only"][1]
    argv = ["identify", watch, "--out", tmp_path / "batch", "--dship", path, *IDENTIFY_ARGS]
    status, out, err = _run(capsys, argv)
    assert status == 1
    assert err.strip().splitlines() == [f"{path}: {reason}"]
    assert "harmonics" not in out
    argv = ["monitor", "--watch", watch, "--state", tmp_path / "state", "--dship", path]
    status, out, err = _run(capsys, [*argv, *MONITOR_ARGS])
    assert status == 0, err
    notes = [line for line in out.splitlines() if line.startswith("note: forecast")]
    assert notes == [f"note: forecast: {path}: {reason}"]


def test_rows_of_a_time_alone_are_a_log_without_readings(tmp_path):
    """Rows holding the time and no separator after it (before: each missing cell
    "not a number")."""
    path = _log(tmp_path, HEADER + "".join(f"2026-03-01T00:00:{s:02d}\n" for s in range(10)))
    with pytest.raises(ContractError) as caught:
        read_dship(path)
    assert str(caught.value) == f"{path}: {LOGS['blank rows'][1]}"
