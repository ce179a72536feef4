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

from data_contracts import PREDICTOR_KEYS, ContractError, read_accelerations
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


# ------------------------------------------------------------ times as other tools print them
#: First block of the voyage tables: 1 May (day and month both <= 12: ambiguous slash dates).
VOYAGE_T0 = pd.Timestamp("2024-05-01T08:00:00Z")
N_BLOCKS = 60


def _voyage_tables(folder: Path, time_format: str, *, modal_format: str | None = None):
    """A wide modal table (time, f1..f3, d1..d3 [%]; 20-min blocks every 5 min) and a
    DSHIP log at 1 min with the canonical channels plus position and water depth, their
    times printed with *time_format* (the modal table's with *modal_format* if given).

    Frequencies follow speed and water temperature: f = f0 + 0.02 speed + 0.01 water.
    """
    rng = np.random.default_rng(30)
    folder.mkdir(parents=True, exist_ok=True)
    minutes = np.arange(0, 5 * N_BLOCKS + 25)
    times = VOYAGE_T0 + pd.to_timedelta(minutes, unit="min")
    speed = 8 + 4 * np.sin(2 * np.pi * minutes / 140)
    water = 6 + 2 * np.cos(2 * np.pi * minutes / 230)
    log = pd.DataFrame(
        {
            "Date/Time": times.strftime(time_format),
            "SYS.STR.SOG [kn]": speed + 0.05 * rng.standard_normal(len(minutes)),
            "Temp [°C]": water,
            "TTT [°C]": 12 + 3 * np.sin(2 * np.pi * minutes / 410),
            "ff [m/s]": 7 + 2 * np.sin(2 * np.pi * minutes / 95),
            "RelWindDir [deg]": 40 + 30 * np.sin(2 * np.pi * minutes / 170),
            "Latitude [deg]": 54.0 + 0.002 * minutes,
            "Longitude [deg]": 7.5 + 0.003 * minutes,
            "Water depth [m]": 30 + 10 * np.sin(2 * np.pi * minutes / 300),
        }
    )
    log.to_csv(folder / "dship.dat", sep="\t", index=False, float_format="%.5f")
    starts = VOYAGE_T0 + pd.to_timedelta(5 * np.arange(N_BLOCKS), unit="min")
    centre = 5 * np.arange(N_BLOCKS) + 10  # block centres [min]
    modal = pd.DataFrame({"time": starts.strftime(modal_format or time_format)})
    for m, f0 in enumerate((2.1, 4.3, 6.8), start=1):
        modal[f"f{m}"] = (
            f0
            + 0.02 * np.interp(centre, minutes, speed)
            + 0.01 * np.interp(centre, minutes, water)
            + 0.002 * rng.standard_normal(N_BLOCKS)
        )
    for m in (1, 2, 3):
        modal[f"d{m} [%]"] = 1.5 + 0.1 * rng.standard_normal(N_BLOCKS)
    modal.to_csv(folder / "modal.csv", index=False, float_format="%.6f")
    return folder / "modal.csv", folder / "dship.dat"


def _fit_argv(modal: Path, dship: Path, out: Path, *extra) -> list:
    return ["fit", "--modal", modal, "--dship", dship, "--out", out, *extra]


def test_day_first_modal_table_is_read_when_a_day_above_12_says_so(tmp_path):
    """Before: ``'14/05/2024 08:10:00', '14/05/2024 08:10:00', ... not a time`` with no flag
    to give."""
    from data_contracts.modal_layout import read_modal_table

    modal, _ = _voyage_tables(tmp_path, "%d/%m/%Y %H:%M:%S")
    text = modal.read_text().replace("01/05/2024", "14/05/2024")
    modal.write_text(text)
    with pytest.warns(UserWarning, match="taken as the start"):
        table = read_modal_table(modal, time_zone="UTC")
    assert table["block_start"].min() == pd.Timestamp("2024-05-14T08:00:00Z")
    assert table["block_start"].max() == pd.Timestamp("2024-05-14T12:55:00Z")
    assert table["block"].nunique() == N_BLOCKS


def test_ambiguous_day_first_times_name_each_value_once_and_one_flag_reads_every_input(
    tmp_path, capsys
):
    """``01/05/2024`` is 1 May or 5 January: the error shows each distinct value once
    (the wide table repeats it per mode) and says how to state the format; one
    ``--time-format`` then applies to the modal table and the ship log alike."""
    modal, dship = _voyage_tables(tmp_path, "%d/%m/%Y %H:%M:%S")
    assert _run(_fit_argv(modal, dship, tmp_path / "fit")) == 1
    err = capsys.readouterr().err
    assert "'01/05/2024 08:00:00'" in err and err.count("'01/05/2024 08:00:00'") == 1
    assert "no day above 12" in err and "--time-format" in err
    errors = [line for line in err.splitlines() if not line.startswith("warning:")]
    assert len(errors) == 1 and "Traceback" not in err
    for fmt in ("%d/%m/%Y %H:%M:%S", "dd/mm/yyyy HH:MM:SS"):  # strptime or MATLAB symbols
        out = tmp_path / f"fit {fmt.count('%')}"
        code = _run([*_fit_argv(modal, dship, out), "--time-format", fmt])
        captured = capsys.readouterr()
        assert code == 0, captured.err
        coefficients = pd.read_csv(out / "coefficients.csv")
        assert set(coefficients["mode"]) == {1, 2, 3}
        # the voyage's slope, 0.02 Hz/kn, within the noise of 60 overlapping blocks
        np.testing.assert_allclose(coefficients["speed_kn"], 0.02, atol=0.004)


def test_time_format_from_the_config(tmp_path, capsys):
    modal, dship = _voyage_tables(tmp_path, "%d/%m/%Y %H:%M:%S")
    config = tmp_path / "ship.toml"
    config.write_text('[times]\nformat = "%d/%m/%Y %H:%M:%S"\n', encoding="utf-8")
    code = _run([*_fit_argv(modal, dship, tmp_path / "fit"), "--config", config])
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "fit" / "coefficients.csv").is_file()


def test_time_format_seconds_is_refused_for_modal_tables(tmp_path, capsys):
    modal, dship = _voyage_tables(tmp_path, "%Y-%m-%dT%H:%M:%SZ")
    code = _run([*_fit_argv(modal, dship, tmp_path / "fit"), "--time-format", "seconds"])
    assert code == 2
    assert "--time-format seconds is for acceleration files" in capsys.readouterr().err


def test_matlab_datestr_times_need_no_flag(tmp_path, capsys):
    """MATLAB's ``datestr`` form (``01-May-2024 08:00:00``) names the month."""
    modal, dship = _voyage_tables(tmp_path, "%d-%b-%Y %H:%M:%S")
    code = _run(_fit_argv(modal, dship, tmp_path / "fit"))
    assert code == 0, capsys.readouterr().err


def _mat73(path: Path, data: np.ndarray, t0: str) -> None:
    """A MATLAB v7.3 file as MATLAB writes it: HDF5 with a 512-byte header, the matrix
    column-major, text as uint16 characters, ``t0`` from ``datestr``."""
    import h5py

    with h5py.File(path, "w", userblock_size=512) as mat:
        mat["data"] = data.T
        mat["fs"] = np.array([[RATE_HZ]])
        mat["t0"] = np.array([[ord(c)] for c in t0], dtype=np.uint16)
        refs = []
        for j, name in enumerate(CHANNELS):
            mat[f"#refs#/{j}"] = np.array([ord(c) for c in name], dtype=np.uint16)
            refs.append(mat[f"#refs#/{j}"].ref)
        import h5py as _h5

        mat.create_dataset("chanNames", data=np.array(refs, dtype=_h5.ref_dtype))
    with open(path, "r+b") as handle:
        handle.write(b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(128, b" "))


def test_matlab_v73_t0_in_datestr_form(tmp_path):
    """Before: ``start_time: not an ISO-8601 time: '14-May-2024 08:00:00'``."""
    data = response(256, 7)
    path = tmp_path / "rec.mat"
    _mat73(path, data, "14-May-2024 08:00:00")
    record = read_accelerations(path)
    assert record.start_time == T0 and record.channels == CHANNELS
    np.testing.assert_array_equal(record.acceleration, data)
    # an ambiguous slash date needs the format, then reads
    _mat73(path, data, "05/06/2024 08:00:00")
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    assert "'05/06/2024 08:00:00'" in str(caught.value) and "--time-format" in str(caught.value)
    record = read_accelerations(path, layout={"time_format": "%d/%m/%Y %H:%M:%S"})
    assert record.start_time == pd.Timestamp("2024-06-05T08:00:00Z")


def test_daq_metadata_start_in_a_given_format(tmp_path):
    data = response(N_FILE, 8)
    path = tmp_path / "export.csv"
    _ni_export(path, data, T0)
    text = path.read_text().replace("Start Time,2024-05-14 08:00:00", "Start Time,05/06/2024 08:00")
    path.write_text(text)
    # ambiguous in the metadata and relative times: the message says why and what to do
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    message = str(caught.value)
    assert "holds relative times" in message and "'05/06/2024 08:00' above the header" in message
    assert "no day above 12" in message and "--time-format" in message
    for fmt in ("%d/%m/%Y %H:%M", "dd/mm/yyyy HH:MM"):
        record = read_accelerations(path, layout={"time_format": fmt})
        assert record.start_time == pd.Timestamp("2024-06-05T08:00:00Z")


# ------------------------------------------------------------ one start time, several files
def _relative_files(folder: Path, n_files: int, *, continuing: bool = False, seed: int = 9):
    """*n_files* 60-s CSV files with relative times (restarting at 0, or continuing)."""
    folder.mkdir(parents=True, exist_ok=True)
    data = response(n_files * N_FILE, seed)
    for k in range(n_files):
        first = k * N_FILE if continuing else 0
        lines = ["Time [s];" + ";".join(CHANNELS)]
        for i, row in enumerate(data[k * N_FILE : (k + 1) * N_FILE]):
            lines.append(";".join([f"{(first + i) / RATE_HZ:.6f}", *(f"{v:.9g}" for v in row)]))
        (folder / f"rec_{k}.csv").write_text("\n".join(lines) + "\n")
    return data


@pytest.mark.parametrize("continuing", [False, True], ids=["restarting", "continuing"])
def test_start_time_for_a_folder_of_consecutive_files(tmp_path, capsys, continuing):
    """Before: ``rec_1.csv: starts 60 s before the end of rec_0.csv (overlapping or
    duplicate files)``. The start time is the first file's; the others follow on."""
    folder = tmp_path / "rel"
    _relative_files(folder, 3, continuing=continuing)
    out = tmp_path / "out"
    start = "2024-05-14T08:00:00Z"
    code = _run(["identify", folder, "--out", out, "--start-time", start, *IDENTIFY_ARGS])
    err = capsys.readouterr().err
    assert code == 0, err
    blocks = pd.read_csv(out / "blocks.csv")
    # 3 minutes without a gap: 2-minute blocks at 0 and 1 min, both identified
    assert list(blocks["status"]) == ["ok", "ok"]
    assert pd.Timestamp(blocks["block_start"].iat[0]) == pd.Timestamp(start)


def test_start_time_keeps_a_gap_that_continuing_times_state(tmp_path):
    from workbench.identification.options import IdentifyOptions
    from workbench.identification.planning import follow_on_starts

    folder = tmp_path / "rel"
    _relative_files(folder, 2, continuing=True)
    # the second file's times say it starts 90 s after the first: a 30-s gap
    second = folder / "rec_1.csv"
    lines = second.read_text().splitlines()
    shifted = [lines[0]]
    for line in lines[1:]:
        time, rest = line.split(";", 1)
        shifted.append(f"{float(time) + 30:.6f};{rest}")
    second.write_text("\n".join(shifted) + "\n")
    options = IdentifyOptions(acceleration_layout={"start_time": "2024-05-14T08:00:00Z"})
    files = sorted(folder.glob("*.csv"))
    layout = follow_on_starts(files, options).acceleration_layout
    starts = [read_accelerations(f, layout=layout).start_time for f in files]
    assert starts == [T0, T0 + pd.Timedelta(seconds=90)]


# ------------------------------------------------------------ the same defaults everywhere
def test_api_and_cli_choose_the_same_predictors_and_give_identical_fits(tmp_path, capsys):
    """Before: ``wb.fit(modal, wb.load_predictors(dship=..., onto=modal))`` regressed on
    latitude, longitude and water depth too (12 predictors) where ``workbench fit`` used
    the 5 canonical ones."""
    import workbench as wb
    from data_contracts.modal_layout import read_modal_table

    modal_path, dship = _voyage_tables(tmp_path, "%Y-%m-%dT%H:%M:%SZ")
    assert _run(_fit_argv(modal_path, dship, tmp_path / "cli", "--time-zone", "UTC")) == 0
    capsys.readouterr()
    with pytest.warns(UserWarning, match="taken as the start"):
        modal = read_modal_table(modal_path, time_zone="UTC")
    predictors = wb.load_predictors(dship=dship, onto=modal)
    names = [c for c in predictors.columns if c not in PREDICTOR_KEYS]
    assert names == [
        "speed_kn",
        "water_temp_c",
        "air_temp_c",
        "wind_speed_ms",
        "wind_dir_rel_deg",
    ]
    api = wb.fit(modal, predictors)
    api.save(tmp_path / "api", figures=False)
    for table in ("coefficients.csv", "fit_statistics.csv"):
        pd.testing.assert_frame_equal(
            pd.read_csv(tmp_path / "api" / table), pd.read_csv(tmp_path / "cli" / table)
        )
    # every column only on request, in both
    every = wb.load_predictors(dship=dship, onto=modal, all_predictors=True)
    assert {"latitude_deg", "longitude_deg"} <= set(every.columns)
    code = _run(_fit_argv(modal_path, dship, tmp_path / "cli_all", "--all-predictors"))
    assert code == 0, capsys.readouterr().err
    api_all = wb.fit(modal, every)
    api_all.save(tmp_path / "api_all", figures=False)
    pd.testing.assert_frame_equal(
        pd.read_csv(tmp_path / "api_all" / "coefficients.csv"),
        pd.read_csv(tmp_path / "cli_all" / "coefficients.csv"),
    )


def test_report_with_a_geometry_of_other_channel_names_is_one_line(tmp_path, capsys):
    """Before: ``attempt to get argmax of an empty sequence``."""
    from .voyage import write_voyage

    run = tmp_path / "run"
    write_voyage(tmp_path / "voyage", n_files=4)
    assert _run(["identify", tmp_path / "voyage", "--out", run / "identify", *IDENTIFY_ARGS]) == 0
    selected = run / "identify" / "selected.parquet"
    assert _run(["track", selected, "--out", run / "tracked_modal.csv"]) == 0
    capsys.readouterr()
    geometry = tmp_path / "geometry.csv"
    rows = [f"P{j + 1},N{j + 1},{10.0 * j},0,0,0,0,1" for j in range(len(CHANNELS))]
    geometry.write_text(
        "channel,node,x_m,y_m,z_m,direction_x,direction_y,direction_z\n" + "\n".join(rows) + "\n"
    )
    code = _run(["report", run, "--geometry", geometry])
    err = capsys.readouterr().err
    assert code == 1
    lines = [line for line in err.splitlines() if not line.startswith("warning:")]
    assert len(lines) == 1 and "Traceback" not in err and "argmax" not in err
    assert "P1, P2, P3, P4" in lines[0] and "acc01, acc02, acc03, acc04" in lines[0]
    assert not (run / "report.html").exists()


def test_one_config_time_format_reads_acceleration_metadata_too(tmp_path, capsys):
    """``[times] format`` reaches identify: DAQ exports whose metadata start is the
    ambiguous ``05/06/2024 08:00:00`` (5 June, day first)."""
    folder = tmp_path / "daq"
    folder.mkdir()
    data = response(3 * N_FILE, 11)
    june = pd.Timestamp("2024-06-05T08:00:00Z")
    for k in range(3):
        path = folder / f"daq_{k:03d}.csv"
        start = june + pd.Timedelta(seconds=k * FILE_S)
        _ni_export(path, data[k * N_FILE : (k + 1) * N_FILE], start)
        iso = start.strftime("%Y-%m-%d %H:%M:%S")
        path.write_text(path.read_text().replace(iso, start.strftime("%d/%m/%Y %H:%M:%S")))
    out = tmp_path / "out"
    assert _run(["identify", folder, "--out", out, *IDENTIFY_ARGS]) == 1
    assert "'05/06/2024 08:00:00' above the header" in capsys.readouterr().err
    config = tmp_path / "ship.toml"
    config.write_text('[times]\nformat = "dd/mm/yyyy HH:MM:SS"\n', encoding="utf-8")
    code = _run(["identify", folder, "--out", out, *IDENTIFY_ARGS, "--config", config])
    assert code == 0, capsys.readouterr().err
    blocks = pd.read_csv(out / "blocks.csv")
    assert pd.Timestamp(blocks["block_start"].iat[0]) == june


# ------------------------------------------------------------ the monitor reads as identify does
def _european_export(path: Path, data: np.ndarray, start: pd.Timestamp) -> None:
    """A European spreadsheet export: ``;``-separated, decimal commas, channels in g, and
    day-first slash dates whose days (5 June) do not tell day and month apart."""
    times = start + pd.to_timedelta(np.arange(len(data)) / RATE_HZ, unit="s")
    lines = ["Zeit;" + ";".join(f"Beschl{j + 1} [g]" for j in range(data.shape[1]))]
    for time, row in zip(
        times.strftime("%d/%m/%Y %H:%M:%S.%f"), data / STANDARD_GRAVITY_MS2, strict=True
    ):
        lines.append(time + ";" + ";".join(f"{v:.9f}".replace(".", ",") for v in row))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_monitor_reads_what_identify_reads_and_names_a_file_it_cannot(tmp_path, capsys):
    """Before: ``no complete acceleration file to monitor`` without a reason, and no flag
    or config entry for the monitor (identify read the files with ``--time-format``)."""
    folder = tmp_path / "watch"
    folder.mkdir()
    data = response(4 * N_FILE, 12)
    june = pd.Timestamp("2024-06-05T08:00:00Z")
    for k in range(4):
        start = june + pd.Timedelta(seconds=k * FILE_S)
        _european_export(folder / f"mess_{k:03d}.csv", data[k * N_FILE : (k + 1) * N_FILE], start)
    block = [a for a in IDENTIFY_ARGS if a not in ("--scheduler", "synchronous", "--quiet")]
    monitor = ["monitor", "--watch", folder, "--once", "--settle", "0", *block]
    assert _run([*monitor, "--state", tmp_path / "refused"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert err.startswith(f"error: {folder / 'mess_000.csv'}: cannot be monitored")
    assert "--time-format" in err and "(3 more file(s) refused)" in err
    # one config entry reads them, in identify and in the monitor alike
    config = tmp_path / "ship.toml"
    config.write_text('[times]\nformat = "dd/mm/yyyy HH:MM:SS.FFF"\n', encoding="utf-8")
    out = tmp_path / "identify"
    assert _run(["identify", folder, "--out", out, *IDENTIFY_ARGS, "--config", config]) == 0
    state = tmp_path / "state"
    assert _run([*monitor, "--state", state, "--config", config]) == 0, capsys.readouterr().err
    batch = pd.read_parquet(out / "selected.parquet")
    live = pd.read_parquet(state / "tracked.parquet")
    assert pd.Timestamp(live["block_start"].min()) == june
    assert sorted(live["block"].unique()) == sorted(batch["block"].unique()) == [0, 1, 2]
    # the same files give the same modes (in m/s²: the headers' [g] applied by both)
    for f_hz in (3.1, 5.7):
        nearest = live["frequency_hz"].to_numpy()[np.argmin(np.abs(live["frequency_hz"] - f_hz))]
        assert abs(nearest - f_hz) < 0.1
        assert np.min(np.abs(batch["frequency_hz"].to_numpy() - nearest)) < 1e-9
    # one start time cannot place a growing folder's files
    code = _run([*monitor, "--state", tmp_path / "s", "--start-time", "2024-06-05T08:00Z"])
    assert code == 2 and "--start-time filename" in capsys.readouterr().err


# ------------------------------------------------------------ a run and its report
#: Ship-log columns under a ship's own names, given once in the configuration.
SHIP_COLUMNS = {
    "speed_kn": "SOG",
    "water_temp_c": "SST",
    "air_temp_c": "AirT",
    "wind_speed_ms": "WS_port",
    "wind_dir_rel_deg": "WD_port",
}


def _ship_run(folder: Path, n_files: int = 24) -> Path:
    """Recordings with relative times (``Time [s]`` from 0 in every file), a ship log
    under the ship's own column names with two water-temperature spikes, and the
    configuration that says how to read both; returns the configuration's path."""
    recordings = folder / "recordings"
    recordings.mkdir(parents=True)
    data = response(n_files * N_FILE, 5)
    for k in range(n_files):
        frame = pd.DataFrame(
            data[k * N_FILE : (k + 1) * N_FILE], columns=[f"{c} [m/s^2]" for c in CHANNELS]
        )
        frame.insert(0, "Time [s]", np.arange(N_FILE) / RATE_HZ)
        frame.to_csv(recordings / f"rec_{k:03d}.csv", index=False, float_format="%.8g")
    minutes = np.arange(n_files + 2)
    log = pd.DataFrame(
        {
            "Date/Time": (T0 + pd.to_timedelta(minutes, unit="min")).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "SOG": 8 + 3 * np.sin(minutes / 5),
            "SST": 6 + np.cos(minutes / 7),
            "AirT": 12 + np.sin(minutes / 9),
            "WS_port": 7 + 2 * np.sin(minutes / 4),
            "WD_port": 40 + 30 * np.sin(minutes / 6),
        }
    )
    log.loc[[7, 19], "SST"] = 25.0  # a faulty sensor's spikes: despiked, with a warning
    log.to_csv(folder / "log.dat", sep="\t", index=False, float_format="%.5f")
    columns = ", ".join(f'{k} = "{v}"' for k, v in SHIP_COLUMNS.items())
    config = folder / "ship.toml"
    config.write_text(
        f'[output]\ndir = "out"\n'
        f'[accelerations]\ninputs = ["recordings"]\nstart_time = "{T0.isoformat()}"\n'
        f'[dship]\nfile = "log.dat"\ncolumns = {{ {columns} }}\n'
        "[blocks]\nlength_minutes = 2\nstep_minutes = 1\n"
        "[identify]\nblock_rows = 10\nmin_order = 4\nmax_order = 16\n"
        "[forecast]\ntrain_blocks = 10\n",
        encoding="utf-8",
    )
    return config


def test_run_warns_once_and_ends_with_a_report_of_its_own_results(tmp_path, capsys, monkeypatch):
    """Before: each stage's warnings once per stage (3x), no report; ``workbench report``
    read the relative-time files without the configuration's start ("relative times",
    no spectra), read the ship log again without the configuration's column names (wind
    columns blank) and correlated again."""
    import workbench as wb
    import workbench.identification.voyage as voyage
    from data_contracts.modal_layout import read_modal_table

    run_blocks = voyage.run_blocks  # identify in this process: no local cluster to start
    monkeypatch.setattr(
        voyage, "run_blocks", lambda *a, **k: run_blocks(*a, **{**k, "scheduler": "synchronous"})
    )
    config = _ship_run(tmp_path)
    assert _run(["run", config]) == 0, capsys.readouterr().err
    out, err = capsys.readouterr()
    despiked = [line for line in err.splitlines() if "despiked" in line]
    assert len(despiked) == 1 and despiked[0].startswith("warning: ship log: despiked")
    assert "each shown once (2 repeat(s) by later stages left out)" in err
    assert out.rstrip().endswith(f"report: {tmp_path / 'out' / 'report.html'}")
    run = tmp_path / "out"
    page = (run / "report.html").read_text(encoding="utf-8")
    # the recordings read as identify read them: signal views, no file skipped
    assert (run / "report_files" / "spectra.png").is_file() and "could not be read" not in page
    span = f"{T0:%Y-%m-%d %H:%M} to {T0 + pd.Timedelta(minutes=24):%Y-%m-%d %H:%M} UTC"
    assert "24 (4 channels at 32 Hz)" in page and span in page  # the files follow on
    # the correlate stage's own pairs, wind columns included (the configuration's names)
    shown = pd.read_csv(run / "report_files" / "correlation_effective.csv")
    own = wb.read_correlation(run / "correlation").effective()
    assert len(shown) == len(own) == 4 * 5 + 10  # 4 mode quantities x 5 predictors + pairs
    np.testing.assert_allclose(shown["r"], own["r"], rtol=1e-5)
    wind = shown[shown["x"].str.startswith("wind") & shown["y"].str.startswith("mode")]
    assert len(wind) == 2 * 4 and wind["r"].notna().all() and (wind["n"] >= 23).all()
    # the API on the same files gives the CLI's fit
    with pytest.warns(UserWarning):
        modal = read_modal_table(run / "tracked_modal.csv")
        predictors = wb.load_predictors(
            dship=tmp_path / "log.dat", onto=modal, dship_mapping=SHIP_COLUMNS
        )
    wb.fit(modal, predictors).save(tmp_path / "api", figures=False)
    for table in ("coefficients.csv", "fit_statistics.csv"):
        pd.testing.assert_frame_equal(
            pd.read_csv(tmp_path / "api" / table), pd.read_csv(run / "fit" / table)
        )
    # the report alone takes the same settings from the configuration
    (run / "report.html").unlink()
    assert _run(["report", "--config", config]) == 0, capsys.readouterr().err
    assert span in (run / "report.html").read_text(encoding="utf-8")
    # and a start given on the command line places the files as identify places them
    later = T0 + pd.Timedelta(hours=1)
    code = _run(["report", "--config", config, "--start-time", later.isoformat()])
    assert code == 0, capsys.readouterr().err
    shifted = f"{later:%Y-%m-%d %H:%M} to {later + pd.Timedelta(minutes=24):%Y-%m-%d %H:%M} UTC"
    assert shifted in (run / "report.html").read_text(encoding="utf-8")
