"""Input files as other tools write them (issue 30): the header row below a DAQ export's
metadata, times as other tools print them, the same defaults in the API and the CLI.

Every file here is written by the test the way the acquisition system or tool writes it
(NI/LabVIEW, Dewesoft and HBM catman CSV exports, a spreadsheet re-save), never by the
project's own writers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import ContractError, read_accelerations
from data_contracts.formats import STANDARD_GRAVITY_MS2, acceleration_files
from workbench.cli import main

from .voyage import CHANNELS, FILE_S, IDENTIFY_ARGS, RATE_HZ, response

#: Start of the first exported file. [UTC]
T0 = pd.Timestamp("2024-05-14T08:00:00Z")
N_FILE = int(FILE_S * RATE_HZ)


def _run(argv) -> int:
    return main([str(a) for a in argv])


def _ni_export(path: Path, data: np.ndarray, start: pd.Timestamp, *, pad: bool = False) -> None:
    """An NI DAQ CSV export: 8 ``key,value`` metadata lines, the header on line 9, relative
    times in s and accelerations in g. *pad*: every row padded with empty fields to the
    table's width, as a spreadsheet re-saves it."""
    width = 1 + data.shape[1]
    metadata = [
        ("Device", "NI cDAQ-9189 (1A2B3C4)"),
        ("Task", "HullVibration"),
        ("Start Time", start.strftime("%Y-%m-%d %H:%M:%S")),
        ("Sample Rate", f"{RATE_HZ:g} Hz"),
        ("Samples per Channel", str(len(data))),
        ("Number of Channels", str(data.shape[1])),
        ("Operator", "J. Hansen"),
        ("Comment", "frames 40-180 port side"),
    ]
    lines = [f"{k},{v}" + ("," * (width - 2) if pad else "") for k, v in metadata]
    lines.append("Time [s]," + ",".join(f"AI{j} [g]" for j in range(data.shape[1])))
    for k, row in enumerate(data / STANDARD_GRAVITY_MS2):
        lines.append(f"{k / RATE_HZ:.6f}," + ",".join(f"{v:.10g}" for v in row))
    path.write_text("\r\n".join(lines) + "\r\n", encoding="utf-8")


def _dewesoft_export(path: Path, data: np.ndarray, start: pd.Timestamp) -> None:
    """A Dewesoft-style export: ``;``-separated, decimal commas, a start time written
    ``dd.mm.yyyy``, the rate as ``Sampling Rate (Hz)``, a blank line above the header."""
    lines = [
        "Dewesoft X3 SP5 export",
        "File;hull_2024_05_14.dxd",
        f"Start Time;{start.strftime('%d.%m.%Y %H:%M:%S')}",
        f"Sampling Rate (Hz);{RATE_HZ:g}",
        "Channels;" + str(data.shape[1]),
        "",
        "Time [s];" + ";".join(f"Acc {j + 1} [m/s^2]" for j in range(data.shape[1])),
    ]
    for k, row in enumerate(data):
        cells = [f"{k / RATE_HZ:.6f}", *(f"{v:.10g}" for v in row)]
        lines.append(";".join(c.replace(".", ",") for c in cells))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _catman_export(path: Path, data: np.ndarray, start: pd.Timestamp) -> None:
    """An HBM catman-style ASCII export: quoted fields, the interval as ``dt`` and a row of
    units below the channel names (time channel ``Time  1 - default sample rate``)."""
    lines = [
        '"catman 5.5 ASCII export"',
        '"File";"C:\\data\\hull.BIN"',
        '"Comment";"sea trial, ballast"',
        f'"T0";"{start.strftime("%Y-%m-%d %H:%M:%S")}"',
        f'"dt";"{1 / RATE_HZ:g} s"',
        '"Time  1 - default sample rate";' + ";".join(f'"MX840_{j}"' for j in range(data.shape[1])),
        '"s";' + ";".join('"mm/s^2"' for _ in range(data.shape[1])),
    ]
    for k, row in enumerate(data * 1000):
        lines.append(";".join([f"{k / RATE_HZ:.6f}", *(f"{v:.10g}" for v in row)]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


WRITERS = {
    "NI (8 metadata lines)": (_ni_export, [f"AI{j}" for j in range(4)]),
    "NI re-saved by a spreadsheet": (
        lambda p, d, s: _ni_export(p, d, s, pad=True),
        [f"AI{j}" for j in range(4)],
    ),
    "Dewesoft": (_dewesoft_export, [f"Acc {j + 1}" for j in range(4)]),
    "catman": (_catman_export, [f"MX840_{j}" for j in range(4)]),
}


# ------------------------------------------------------------ header row below metadata
@pytest.mark.parametrize("kind", list(WRITERS))
def test_header_row_below_metadata_is_found_with_the_stated_start_and_rate(tmp_path, kind):
    """Before: ``cannot read file: Error tokenizing data. C error: Expected 2 fields in
    line 9, saw 7`` (the ``key,value`` lines were taken for the header)."""
    write, channels = WRITERS[kind]
    data = response(N_FILE, 3)
    path = tmp_path / "export.csv"
    write(path, data, T0)
    record = read_accelerations(path)
    assert record.channels == tuple(channels)
    assert record.start_time == T0
    assert record.sampling_rate_hz == RATE_HZ
    assert record.acceleration.shape == data.shape
    # 10 significant digits written: the values agree to that (after the unit conversion)
    np.testing.assert_allclose(record.acceleration, data, rtol=1e-9, atol=1e-12)


def test_metadata_start_is_used_with_relative_times_and_the_layout_still_wins(tmp_path):
    data = response(N_FILE, 4)
    path = tmp_path / "export.csv"
    _ni_export(path, data, T0 + pd.Timedelta(minutes=7))
    assert read_accelerations(path).start_time == T0 + pd.Timedelta(minutes=7)
    given = read_accelerations(path, layout={"start_time": "2024-06-01T00:00:00Z"})
    assert given.start_time == pd.Timestamp("2024-06-01T00:00:00Z")


def test_rate_in_the_metadata_that_contradicts_the_times_is_refused(tmp_path):
    path = tmp_path / "export.csv"
    _ni_export(path, response(N_FILE, 5), T0)
    text = path.read_text().replace(f"Sample Rate,{RATE_HZ:g} Hz", "Sample Rate,100 Hz")
    path.write_text(text)
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    message = str(caught.value)
    assert "contradicts the sampling rate 100 Hz" in message and "Time [s]" in message


def test_identify_reads_a_folder_of_daq_exports(tmp_path, capsys):
    """Before: ``3 text file(s) without an acceleration header left out`` and no file."""
    folder = tmp_path / "daq"
    folder.mkdir()
    data = response(3 * N_FILE, 6)
    for k in range(3):
        start = T0 + pd.Timedelta(seconds=k * FILE_S)
        _ni_export(folder / f"daq_{k:03d}.csv", data[k * N_FILE : (k + 1) * N_FILE], start)
    (folder / "notes.txt").write_text("operator notes, nothing tabular\n")
    found = [p.name for p in acceleration_files([folder])]
    assert found == ["daq_000.csv", "daq_001.csv", "daq_002.csv"]
    out = tmp_path / "out"
    code = _run(["identify", folder, "--out", out, *IDENTIFY_ARGS])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "without an acceleration header" not in err
    selected = pd.read_parquet(out / "selected.parquet")
    assert selected["block"].nunique() == 2  # 3 minutes: 2-minute blocks every minute
    # both modes of the voyage (3.1 and 5.7 Hz) are found in the exported files
    for f_hz in (3.1, 5.7):
        assert np.min(np.abs(selected["frequency_hz"].to_numpy() - f_hz)) < 0.1
