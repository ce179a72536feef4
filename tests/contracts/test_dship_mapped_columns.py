"""A column the user's mapping names (``--dship-columns speed_kn=SOG``, ``[dship] columns``)
that the ship log lacks is refused - in the reader and in every command reading the log.

Main read such a log without the quantity: "no column for speed_kn; filled with NaN" (a
warning) and every command went on without the speed, the log's own speed column
("Speed [kn]") read as an extra predictor ``speed_kn_``; a mapped ``shaft_rpm`` that is not
there was not even said (the harmonics then marked from the speed).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from data_contracts import (
    AccelerationRecord,
    ColumnMappingError,
    ContractError,
    read_dship,
    write_accelerations,
)

HEADER = "Date/Time\tSpeed [kn]\tTemp [°C]\tTTT [°C]\tff [m/s]\tRelWindDir [deg]\tSYS.PROP.RPM\n"
ROWS = "".join(
    f"2026-01-01T00:{m:02d}:00\t{5 + m / 10:.1f}\t2\t-1\t7\t10\t{80 + m}\n" for m in range(30)
)


def _log(tmp_path, text=HEADER + ROWS, name="dship.tsv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_a_mapped_column_the_log_lacks_is_refused_naming_it(tmp_path):
    path = _log(tmp_path)
    with pytest.raises(ColumnMappingError) as caught:
        read_dship(path, mapping={"speed_kn": "SOG"})
    (line,) = caught.value.lines()
    assert line.startswith(f"{path}: column 'SOG': not in the file, named by the column mapping")
    assert "speed_kn=SOG" in line and "Speed [kn]" in line  # the columns there, to choose from
    # a ContractError like every bad log (exit 1)
    assert isinstance(caught.value, ContractError)
    # any quantity: the shaft speed too (main: silently none, the harmonics then marked
    # from the speed), and a name the relative wind would be derived from
    for mapping in ({"shaft_rpm": "n_shaft"}, {"heading_deg": "HDG"}, {"time": "Zeit"}):
        with pytest.raises(ContractError, match=f"'{next(iter(mapping.values()))}'"):
            read_dship(path, mapping=mapping)


def test_a_mapped_column_present_is_read_as_before(tmp_path):
    path = _log(tmp_path)
    # by its name, by the last part of a dotted name, and the other quantities by the
    # built-in names; a quantity left to them may be absent (NaN, said in a warning)
    log = read_dship(path, mapping={"speed_kn": "Speed", "shaft_rpm": "RPM"})
    assert log["speed_kn"].iloc[[0, 29]].tolist() == [5.0, 7.9]
    assert log["shaft_rpm"].iloc[[0, 29]].tolist() == [80.0, 109.0]
    assert "speed_kn_" not in log.columns
    text = "Date/Time\tSpeed [kn]\n" + "".join(f"2026-01-01T00:{m:02d}:00\t{m}\n" for m in range(3))
    with pytest.warns(UserWarning, match="no column for water_temp_c"):
        assert read_dship(_log(tmp_path, text, "speed_only.tsv"))["speed_kn"].tolist() == [0, 1, 2]


@pytest.fixture(scope="module")
def voyage(tmp_path_factory):
    """A 2-h simulated voyage's ship log and tracked modal table, and one acceleration file."""
    from workbench.simulate import simulate_voyage

    root = tmp_path_factory.mktemp("mapped_columns")
    simulate_voyage(root, seed=3, hours=2, accelerations=False)
    (root / "accelerations").mkdir()
    rng = np.random.default_rng(0)
    write_accelerations(
        AccelerationRecord(
            rng.standard_normal((64 * 300, 3)),
            64.0,
            pd.Timestamp("2024-03-01", tz="UTC"),
            ("acc01", "acc02", "acc03"),
        ),
        root / "accelerations" / "acc_20240301T000000Z.npz",
    )
    return root


def _commands(root, out):
    log, modal = root / "dship.tsv", root / "tracked_modal.csv"
    mapped = ["--dship-columns", "speed_kn=SOG"]
    toml = out / "ship.toml"
    toml.write_text(
        f'[dship]\nfile = "{log}"\ncolumns = {{ speed_kn = "SOG" }}\n'
        f'[accelerations]\ninputs = ["{root / "accelerations"}"]\n'
        f'[output]\ndir = "{out / "run"}"\n',
        encoding="utf-8",
    )
    return {
        "validate": ["validate", "dship", log, *mapped],
        "identify": ["identify", root / "accelerations", "--out", out / "id", "--dship", log,
                     *mapped, "--blades", "5", "--scheduler", "synchronous"],
        "correlate": ["correlate", "--modal", modal, "--dship", log, *mapped, "--out", out / "c"],
        "fit": ["fit", "--modal", modal, "--dship", log, *mapped, "--out", out / "fit"],
        "forecast": ["forecast", "--modal", modal, "--dship", log, *mapped,
                     "--out", out / "forecast.csv"],
        "monitor": ["monitor", "--watch", root / "accelerations", "--dship", log, *mapped,
                    "--state", out / "state", "--once"],
        "run": ["run", toml],
    }  # fmt: skip


@pytest.mark.parametrize(
    "command", ["validate", "identify", "correlate", "fit", "forecast", "monitor", "run"]
)
def test_every_command_refuses_the_log_alike(command, voyage, tmp_path, capsys):
    from workbench.cli import main

    argv = _commands(voyage, tmp_path)[command]
    assert main([str(a) for a in argv]) == 1  # main: 0, the speed left out
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines == [
        f"{voyage / 'dship.tsv'}: column 'SOG': not in the file, named by the column mapping "
        "speed_kn=SOG (columns in the file: Date/Time, Latitude, Longitude, Speed [kn], "
        "Temp [°C], TTT [°C], ff [m/s], RelWindDir [deg], Shaft speed [rpm])"
    ], err
    assert not (tmp_path / "forecast.csv").exists()
