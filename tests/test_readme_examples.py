"""The README's "Bring your own data" commands, run on files laid out like real exports.

A simulated 3-hour voyage supplies the numbers; they are written the way other tools and
ships write them (CSV in g with relative times, MATLAB, HDF5, UFF 58, a raw DSHIP
extraction, an ARTeMIS-style long modal table and a wide one), then every command of the
README section runs as written.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io

from data_contracts import read_accelerations, read_dship
from data_contracts.formats import STANDARD_GRAVITY_MS2
from workbench.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"


def readme_commands() -> list[str]:
    text = README.read_text(encoding="utf-8")
    section = text.split("## Bring your own data", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```bash\n(.*?)```", section, flags=re.S)
    return [
        line.strip()
        for block in blocks
        for line in block.splitlines()
        if line.strip().startswith("workbench ")
    ]


def _csv_in_g(record, path: Path) -> None:
    t = np.arange(record.n_samples) / record.sampling_rate_hz
    g = record.acceleration / STANDARD_GRAVITY_MS2
    lines = ["Time [s];" + ";".join(record.channels)]
    for k in range(record.n_samples):
        cells = [f"{t[k]:.6f}", *(f"{v:.10g}" for v in g[k])]
        lines.append(";".join(cells).replace(".", ","))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _daq_export(record, path: Path) -> None:
    """An NI DAQ CSV export: ``key,value`` metadata lines above the header, relative times."""
    t = np.arange(record.n_samples) / record.sampling_rate_hz
    lines = [
        "Device,NI cDAQ-9189",
        "Task,HullVibration",
        f"Start Time,{record.start_time.strftime('%d.%m.%Y %H:%M:%S')}",
        f"Sample Rate,{record.sampling_rate_hz:g} Hz",
        f"Samples per Channel,{record.n_samples}",
        "Operator,J. Hansen",
        "Time [s]," + ",".join(f"{c} [m/s^2]" for c in record.channels),
    ]
    for k in range(record.n_samples):
        lines.append(",".join([f"{t[k]:.6f}", *(f"{v:.10g}" for v in record.acceleration[k])]))
    path.write_text("\r\n".join(lines) + "\r\n", encoding="utf-8")


def _relative_csv(record, path: Path) -> None:
    """Relative times restarting at 0 in every file, no start anywhere."""
    t = np.arange(record.n_samples) / record.sampling_rate_hz
    lines = ["Time [s]," + ",".join(record.channels)]
    for k in range(record.n_samples):
        lines.append(",".join([f"{t[k]:.6f}", *(f"{v:.10g}" for v in record.acceleration[k])]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _uff(record, path: Path, n: int) -> None:
    pyuff = pytest.importorskip("pyuff")
    common = dict(
        binary=0, id1="Time response", id2="", id3="", id4="", id5="", func_type=1, ver_num=0,
        load_case_id=0, rsp_ent_name="pt", ref_ent_name="NONE", ref_node=0, ref_dir=0,
        ord_data_type=4, num_pts=n, abscissa_spacing=1, abscissa_min=0.0,
        abscissa_inc=1.0 / record.sampling_rate_hz, z_axis_value=0.0,
        abscissa_spec_data_type=17, abscissa_len_unit_exp=0, abscissa_force_unit_exp=0,
        abscissa_temp_unit_exp=0, abscissa_axis_units_lab="s", ordinate_spec_data_type=12,
        ordinate_len_unit_exp=1, ordinate_force_unit_exp=0, ordinate_temp_unit_exp=0,
        ordinate_axis_units_lab="m/s^2", orddenom_spec_data_type=0, orddenom_len_unit_exp=0,
        orddenom_force_unit_exp=0, orddenom_temp_unit_exp=0, orddenom_axis_units_lab="NONE",
        z_axis_spec_data_type=0, z_axis_len_unit_exp=0, z_axis_force_unit_exp=0,
        z_axis_temp_unit_exp=0, z_axis_axis_units_lab="NONE",
    )  # fmt: skip
    sets = [
        pyuff.prepare_58(
            **common,
            rsp_node=j + 1,
            rsp_dir=3,
            data=record.acceleration[:n, j],
            x=np.arange(n) / record.sampling_rate_hz,
        )
        for j in range(3)
    ]
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")


def _raw_dship(log_path: Path, path: Path) -> None:
    log = read_dship(log_path)
    names = {
        "speed_kn": ("SYS.STR.SOG", "Speed over ground", "kn"),
        "water_temp_c": ("Thermosalinograph.TSG1.Water_temperature", "Water temperature", "°C"),
        "air_temp_c": ("Weatherstation.PEWDS.Air_temperature", "Air temperature", "°C"),
        "wind_speed_ms": ("Weatherstation.PEWDS.Wind_speed", "Wind speed", "m/s"),
        "wind_dir_rel_deg": ("Weatherstation.PEWDS.Wind_direction_rel", "Rel. wind dir.", "deg"),
    }
    rows = [
        ";".join(["date time", *(v[0] for v in names.values())]),
        ";".join(["", *(v[1] for v in names.values())]),
        ";".join(["", *(v[2] for v in names.values())]),
    ]
    for record in log.iloc[::10].itertuples(index=False):
        cells = [record.time.strftime("%d.%m.%Y %H:%M:%S")]
        cells += ["" if pd.isna(v) else f"{v:.4f}".replace(".", ",") for v in
                  (getattr(record, c) for c in names)]  # fmt: skip
        rows.append(";".join(cells))
    path.write_text("\n".join(rows) + "\n", encoding="latin-1")


@pytest.fixture(scope="module")
def mydata(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("readme")
    voyage = root / "voyage"
    assert main(["simulate", "--out", str(voyage), "--hours", "3", "--seed", "1"]) == 0
    data = root / "mydata"
    for sub in ("recordings", "matlab", "hdf5", "uff", "dship", "modes", "daq", "relative"):
        (data / sub).mkdir(parents=True)
    files = sorted((voyage / "accelerations").glob("*.npz"))
    for k, path in enumerate(files[:4]):  # 20 min: one 20-min block
        record = read_accelerations(path)
        _csv_in_g(record, data / "recordings" / f"rec_{path.stem[4:]}.csv")
        _daq_export(record, data / "daq" / f"export_{k:03d}.csv")
        _relative_csv(record, data / "relative" / f"part{k + 1}.csv")
    first = read_accelerations(files[0])
    datenum = (
        719529 + (first.start_time - pd.Timestamp("1970-01-01T00:00Z")).total_seconds() / 86400
    )
    scipy.io.savemat(
        data / "matlab" / "rec_0001.mat",
        {
            "data": first.acceleration,
            "fs": first.sampling_rate_hz,
            "t0": datenum,
            "chanNames": np.array(first.channels, dtype=object),
        },
    )
    scipy.io.savemat(
        data / "matlab" / "custom.mat",
        {
            "X": first.acceleration.T,
            "Fs_Hz": first.sampling_rate_hz,
            "Zeit": first.start_time.isoformat(),
            "Kanal": np.array(first.channels, dtype=object),
        },
    )
    h5py = pytest.importorskip("h5py")
    with h5py.File(data / "hdf5" / "rec_0001.h5", "w") as handle:
        dataset = handle.create_dataset("recording/data", data=first.acceleration)
        dataset.attrs["fs"] = first.sampling_rate_hz
        dataset.attrs["start_time"] = first.start_time.isoformat()
        handle["recording/channel_names"] = np.array(first.channels, dtype="S")
    _uff(first, data / "uff" / "rec_0001.uff", n=640)
    _raw_dship(voyage / "dship.tsv", data / "dship" / "extraction.dat")
    (data / "dship" / "bridge_log.csv").write_text(
        "Zeit;Fahrt;Lufttemperatur\n01.03.2024 00:00:00;5,5;-2,0\n01.03.2024 00:01:00;5,7;-2,1\n",
        encoding="utf-8",
    )
    tracked = pd.read_csv(voyage / "tracked_modal.csv")
    start = pd.to_datetime(tracked["block_start"])
    pd.DataFrame(
        {
            "Time": (start + pd.Timedelta(minutes=10)).dt.strftime("%Y-%m-%dT%H:%M:%SZ"),
            "Mode": tracked["mode"].map(lambda m: f"Mode {m}"),
            "Frequency [Hz]": tracked["frequency_hz"],
            "Damping [%]": 100 * tracked["damping_ratio"],
        }
    ).to_csv(data / "modes" / "artemis_modes.csv", sep=";", decimal=",", index=False)
    wide = tracked.pivot(
        index="block_start", columns="mode", values=["frequency_hz", "damping_ratio"]
    )
    wide.columns = [f"{'f' if q == 'frequency_hz' else 'd'}{m}" for q, m in wide.columns]
    wide.index.name = "window_start"
    wide.reset_index().to_csv(data / "modes" / "wide_modes.csv", index=False)
    (data / "ship.toml").write_text(
        '[modal]\nfile = "modes/artemis_modes.csv"\ntime_reference = "centre"\n'
        '[dship]\nfile = "dship/extraction.dat"\n[forecast]\ntrain_blocks = 10\n',
        encoding="utf-8",
    )
    return root


def test_readme_has_one_example_per_input_kind():
    commands = readme_commands()
    text = " ".join(commands)
    for needed in (".csv", ".mat", ".h5", ".uff", "validate dship", "--modal", "run "):
        assert needed in text, needed


@pytest.mark.parametrize("command", readme_commands())
def test_readme_command(mydata, command, monkeypatch, capsys):
    monkeypatch.chdir(mydata)
    argv = shlex.split(command)[1:]
    if argv[0] == "identify":
        argv += ["--scheduler", "synchronous", "--quiet"]  # no cluster start-up in a test
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 0, f"{command}\n{out}\n{err}"
    if argv[0] == "validate" and argv[1] == "accelerations":
        assert "valid accelerations file" in out
    if argv[0] == "identify":
        assert "1 block(s) processed, 0 skipped" in out
