"""Acceleration files as acquisition systems and other tools write them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io

from data_contracts import ContractError, read_accelerations
from data_contracts.formats import STANDARD_GRAVITY_MS2, AccelerationLayout
from workbench.cli import main
from workbench.identification import acceleration_files

START = pd.Timestamp("2026-03-01T12:05:00Z")
RATE = 64.0
CHANNELS = ("acc01", "acc02", "acc03")


def signals(n_samples: int = 256) -> np.ndarray:
    """Three channels of sines [m/s²] (exact in text at 17 significant digits)."""
    t = np.arange(n_samples) / RATE
    return np.column_stack(
        [0.1 * np.sin(2 * np.pi * f * t + k) for k, f in enumerate((2.9, 4.7, 7.1))]
    )


def iso_times(n: int) -> list[str]:
    times = START + pd.to_timedelta(np.arange(n) / RATE, unit="s")
    return list(times.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))


def test_timestamp_column_and_units_in_headers(tmp_path):
    data = signals()
    path = tmp_path / "rec.csv"
    frame = pd.DataFrame(
        {
            "Timestamp": iso_times(len(data)),
            "acc01 [m/s^2]": data[:, 0],
            "acc02 [g]": data[:, 1] / STANDARD_GRAVITY_MS2,
            "acc03 [mm/s²]": data[:, 2] * 1000,
        }
    )
    frame.to_csv(path, index=False, float_format="%.17g")
    record = read_accelerations(path)
    assert record.channels == CHANNELS
    assert record.sampling_rate_hz == RATE and record.start_time == START
    np.testing.assert_allclose(record.acceleration, data, rtol=1e-14, atol=1e-17)


def test_semicolons_decimal_commas_relative_time(tmp_path):
    data = signals()
    lines = ["Time [s];acc01;acc02;acc03"]
    for k, row in enumerate(data):
        cells = [f"{k / RATE:.6f}", *(f"{v:.17g}" for v in row)]
        lines.append(";".join(c.replace(".", ",") for c in cells))
    path = tmp_path / "rec_20260301T120500Z.txt"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    assert "column 'Time [s]': holds relative times (0 to 3.98438 s): give the start" in str(
        caught.value
    )
    for start in ("2026-03-01T12:05:00Z", "filename"):
        record = read_accelerations(path, layout={"start_time": start})
        assert record.start_time == START and record.sampling_rate_hz == RATE
        np.testing.assert_allclose(record.acceleration, data, rtol=1e-14)
    ms = path.with_name("ms.csv")
    ms.write_text(path.read_text().replace("Time [s]", "t [ms]"), encoding="utf-8")
    record = read_accelerations(ms, layout={"start_time": "2026-03-01T12:05:00Z"})
    assert record.sampling_rate_hz == pytest.approx(RATE * 1000)  # times taken as ms


def test_units_per_file_and_per_channel(tmp_path):
    data = signals()
    path = tmp_path / "g.csv"
    frame = pd.DataFrame(data / STANDARD_GRAVITY_MS2, columns=list(CHANNELS))
    frame.insert(0, "time", iso_times(len(data)))
    frame.to_csv(path, index=False, float_format="%.17g")
    record = read_accelerations(path, layout={"units": "g"})
    np.testing.assert_allclose(record.acceleration, data, rtol=1e-14)
    record = read_accelerations(path, layout={"units": {"acc02": "mg"}})
    np.testing.assert_allclose(record.acceleration[:, 1], data[:, 1] / 1000, rtol=1e-14)
    np.testing.assert_allclose(record.acceleration[:, 0], data[:, 0] / STANDARD_GRAVITY_MS2)
    with pytest.raises(ContractError, match="units given for channel.s. acc09 not in the file"):
        read_accelerations(path, layout={"units": {"acc09": "g"}})
    with pytest.raises(ValueError, match="'furlong' is not an acceleration unit"):
        AccelerationLayout(units="furlong")


def test_gravity_in_g_without_a_unit_warns(tmp_path):
    data = signals()
    data[:, 2] = 1.0 + data[:, 2] / STANDARD_GRAVITY_MS2  # vertical DC-coupled sensor in g
    path = tmp_path / "dc.csv"
    frame = pd.DataFrame(data, columns=list(CHANNELS))
    frame.insert(0, "time", iso_times(len(data)))
    frame.to_csv(path, index=False)
    with pytest.warns(UserWarning, match="acc03 have a mean of about 1 like gravity in g"):
        read_accelerations(path)


def test_missing_time_column_lists_the_columns(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("Zeitstempel,a,b\n2026-03-01T12:05:00Z,0.1,0.2\n2026-03-01T12:05:01Z,0.1,0.2\n")
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    assert "columns in the file: Zeitstempel, a, b" in str(caught.value)
    record = read_accelerations(path, layout={"time_column": "Zeitstempel"})
    assert record.channels == ("a", "b") and record.sampling_rate_hz == 1.0


def test_matlab_with_usual_names_and_datenum(tmp_path):
    data = signals()
    path = tmp_path / "rec.mat"
    # MATLAB datenum of START: days since 0000-01-00 (1970-01-01 is 719529)
    datenum = 719529 + (START - pd.Timestamp("1970-01-01T00:00Z")).total_seconds() / 86400
    scipy.io.savemat(
        path,
        {
            "data": data,
            "fs": RATE,
            "t0": datenum,
            "chanNames": np.array(CHANNELS, dtype=object),
        },
    )
    record = read_accelerations(path)
    assert record.channels == CHANNELS and record.sampling_rate_hz == RATE
    assert abs((record.start_time - START).total_seconds()) < 1e-5  # datenum: ~1 µs
    np.testing.assert_array_equal(record.acceleration, data)
    scipy.io.savemat(path, {"X": data, "Fs_Hz": RATE, "Zeit": "2026-03-01T12:05:00Z"})
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    (line,) = caught.value.lines()
    assert "variables in the file: X (256x3 double), Fs_Hz (1x1 double), Zeit (1 char)" in line
    assert "acceleration (tried acceleration, data" in line


def test_hdf5_matrix_with_attributes(tmp_path):
    h5py = pytest.importorskip("h5py")
    data = signals()
    path = tmp_path / "rec.h5"
    with h5py.File(path, "w") as handle:
        dataset = handle.create_dataset("measurement/data", data=data.T * 1000)  # channels first
        dataset.attrs["fs"] = RATE
        dataset.attrs["units"] = "mm/s^2"
        handle["measurement/channel_names"] = np.array(CHANNELS, dtype="S")
        handle.attrs["start_time"] = "2026-03-01T12:05:00Z"
    # the only 2-D dataset, its attributes and the names beside it are found unnamed
    record = read_accelerations(path)
    assert record.channels == CHANNELS and record.start_time == START
    np.testing.assert_allclose(record.acceleration, data, rtol=1e-14)
    record = read_accelerations(
        path,
        layout={
            "variables": {
                "acceleration": "measurement/data",
                "channels": "measurement/channel_names",
            }
        },
    )
    assert record.channels == CHANNELS and record.start_time == START
    np.testing.assert_allclose(record.acceleration, data, rtol=1e-14)


def test_hdf5_group_of_channels_and_listing(tmp_path):
    h5py = pytest.importorskip("h5py")
    data = signals()
    path = tmp_path / "rec.hdf5"
    with h5py.File(path, "w") as handle:
        for name, column in zip(CHANNELS, data.T, strict=True):
            handle[f"channels/{name}"] = column
            handle[f"channels/{name}"].attrs["units"] = "m/s^2"
        handle["fs"] = RATE
        handle["t0"] = (START - pd.Timestamp("1970-01-01T00:00Z")).total_seconds()  # POSIX
    with pytest.raises(ContractError) as caught:
        read_accelerations(path)
    assert "datasets in the file: /channels/acc01 (256 float64)" in str(caught.value)
    record = read_accelerations(path, layout={"variables": {"acceleration": "channels"}})
    assert record.channels == CHANNELS and record.start_time == START
    np.testing.assert_array_equal(record.acceleration, data)


def test_hdf5_external_links_are_not_followed(tmp_path):
    h5py = pytest.importorskip("h5py")
    with h5py.File(tmp_path / "other.h5", "w") as other:
        other["data"] = signals()
    path = tmp_path / "rec.h5"
    with h5py.File(path, "w") as handle:
        handle["data"] = h5py.ExternalLink("other.h5", "/data")
        handle["fs"] = RATE
    with pytest.raises(ContractError, match="/data.*HDF5 external link"):
        read_accelerations(path)


def write_uff(path: Path, data: np.ndarray, unit: str = "m/s^2", id4: str = "") -> None:
    pyuff = pytest.importorskip("pyuff")
    uff = pyuff.UFF(str(path))
    sets = [
        pyuff.prepare_58(
            binary=0,
            id1="Time response",
            id4=id4,
            func_type=1,
            rsp_node=101 + j,
            rsp_dir=3,
            ref_node=0,
            ref_dir=0,
            abscissa_spacing=1,
            abscissa_min=0.0,
            abscissa_inc=1.0 / RATE,
            ordinate_spec_data_type=12,
            ordinate_axis_units_lab=unit,
            ord_data_type=4,
            num_pts=len(data),
            ver_num=0,
            load_case_id=0,
            rsp_ent_name="pt",
            ref_ent_name="NONE",
            id2="",
            id3="",
            id5="",
            z_axis_value=0.0,
            abscissa_len_unit_exp=0,
            abscissa_force_unit_exp=0,
            abscissa_temp_unit_exp=0,
            ordinate_len_unit_exp=1,
            ordinate_force_unit_exp=0,
            ordinate_temp_unit_exp=0,
            orddenom_spec_data_type=0,
            orddenom_len_unit_exp=0,
            orddenom_force_unit_exp=0,
            orddenom_temp_unit_exp=0,
            orddenom_axis_units_lab="NONE",
            z_axis_spec_data_type=0,
            z_axis_len_unit_exp=0,
            z_axis_force_unit_exp=0,
            z_axis_temp_unit_exp=0,
            z_axis_axis_units_lab="NONE",
            abscissa_spec_data_type=17,
            abscissa_axis_units_lab="s",
            data=data[:, j],
            x=np.arange(len(data)) / RATE,
        )
        for j in range(data.shape[1])
    ]
    uff.write_sets(sets, mode="overwrite")


def test_uff58_time_responses(tmp_path):
    data = signals()
    path = tmp_path / "rec.uff"
    write_uff(path, data / STANDARD_GRAVITY_MS2, unit="g", id4="2026-03-01 12:05:00")
    record = read_accelerations(path)
    assert record.channels == ("101+Z", "102+Z", "103+Z")
    assert record.start_time == START and record.sampling_rate_hz == pytest.approx(RATE)
    # ASCII UFF keeps 6 significant digits (E13.5)
    np.testing.assert_allclose(record.acceleration, data, rtol=1e-5, atol=1e-9)
    undated = tmp_path / "undated.uff"
    write_uff(undated, data)
    with pytest.raises(ContractError, match=r"no date in the ID lines .*Time response"):
        read_accelerations(undated)
    record = read_accelerations(undated, layout={"start_time": "2026-03-01T12:05:00Z"})
    assert record.start_time == START


def test_folder_search_finds_every_format_and_skips_tables(tmp_path):
    h5py = pytest.importorskip("h5py")
    data = signals()
    frame = pd.DataFrame(data, columns=list(CHANNELS))
    frame.insert(0, "time", iso_times(len(data)))
    frame.to_csv(tmp_path / "a.csv", index=False)
    scipy.io.savemat(tmp_path / "b.mat", {"data": data, "fs": RATE, "t0": "x", "chanNames": "y"})
    with h5py.File(tmp_path / "c.h5", "w") as handle:
        handle["data"] = data
    (tmp_path / "sub").mkdir()
    write_uff(tmp_path / "sub" / "d.unv", data)
    (tmp_path / "tracked_modal.csv").write_text("block,block_start,block_end,mode\n")
    (tmp_path / "cases.csv").write_text("case,start,end\n")
    (tmp_path / "dship.tsv").write_text("/* DATA DESCRIPTION:\n*/\nDate/Time\tSpeed [kn]\n")
    (tmp_path / "log.csv").write_text("Date/Time,Speed [kn],TTT [°C]\n")
    (tmp_path / "raw.txt").write_text(
        "date time;Weatherstation.PEWDS.Air_temperature\n;°C\n01.03.2026 12:00:00;1,0\n"
    )
    (tmp_path / "export.txt").write_text("Start time: 2026-03-01T12:05Z\nfs = 64\na;b\n1;2\n3;4\n")
    names = [p.relative_to(tmp_path).as_posix() for p in acceleration_files([tmp_path])]
    assert names == ["a.csv", "b.mat", "c.h5", "export.txt", "sub/d.unv"]


def test_cli_validate_with_layout_flags(tmp_path, capsys):
    data = signals()
    lines = ["Time [s];acc01;acc02;acc03"] + [
        ";".join(f"{v:.10g}".replace(".", ",") for v in (k / RATE, *row))
        for k, row in enumerate(data)
    ]
    path = tmp_path / "rec.csv"
    path.write_text("\n".join(lines) + "\n")
    assert main(["validate", "accelerations", str(path)]) == 1
    assert "give the start time" in capsys.readouterr().err
    code = main(
        [
            "validate",
            "accelerations",
            str(path),
            "--start-time",
            "2026-03-01T12:05Z",
            "--units",
            "g",
        ]
    )
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "256 samples x 3 channels at 64 Hz from 2026-03-01T12:05:00+00:00" in out
    assert main(["validate", "accelerations", str(path), "--units", "furlong"]) == 2
    assert "not an acceleration unit" in capsys.readouterr().err


def test_banner_lines_above_the_header_give_start_and_rate(tmp_path):
    """Acquisition-system exports often put metadata above the header."""
    data = signals()
    lines = [
        "Measurement: hull monitoring, frame 112",
        "Start time: 01.03.2026 12:05:00",
        "Sample rate: 64 Hz",
        "",
        "acc01 [g];acc02 [g];acc03 [g]",
    ] + [
        ";".join(f"{v / STANDARD_GRAVITY_MS2:.17g}".replace(".", ",") for v in row) for row in data
    ]
    path = tmp_path / "export.txt"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    record = read_accelerations(path)
    assert record.start_time == START and record.sampling_rate_hz == RATE
    assert record.channels == CHANNELS
    np.testing.assert_allclose(record.acceleration, data, rtol=1e-14)
    # the layout wins over the banner
    record = read_accelerations(path, layout={"sampling_rate_hz": 128.0})
    assert record.sampling_rate_hz == 128.0
