"""Modal tables as other tools export them: long, wide and block-indexed layouts."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import ContractError
from data_contracts.modal_layout import ModalLayout, read_modal_table
from workbench.cli import main

#: Three 20-min windows every 5 min from 2024-03-01 00:00 UTC; two modes.
STARTS = pd.date_range("2024-03-01T00:00Z", periods=3, freq="5min")
FREQUENCIES = {1: [2.90, 2.91, 2.92], 2: [4.70, 4.71, 4.72]}
DAMPING_PCT = {1: [1.2, 1.3, 1.1], 2: [0.8, 0.9, 0.7]}


def write(tmp_path: Path, text: str, name: str = "modes.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def expected() -> pd.DataFrame:
    rows = [
        (k, STARTS[k], STARTS[k] + pd.Timedelta(minutes=20), m, FREQUENCIES[m][k])
        for k in range(3)
        for m in (1, 2)
    ]
    return pd.DataFrame(rows, columns=["block", "block_start", "block_end", "mode", "frequency_hz"])


def check(table: pd.DataFrame, blocks_from: int = 0) -> None:
    want = expected()
    assert table["block"].tolist() == (want["block"] + blocks_from).tolist()
    assert table["block_start"].tolist() == want["block_start"].tolist()
    assert table["block_end"].tolist() == want["block_end"].tolist()
    assert table["mode"].tolist() == want["mode"].tolist()
    assert table["frequency_hz"].tolist() == want["frequency_hz"].tolist()
    damping = [DAMPING_PCT[m][k] / 100 for k in range(3) for m in (1, 2)]
    assert table["damping_ratio"].to_numpy() == pytest.approx(damping, rel=1e-12)


def long_text(time_of, sep=",", decimal=".", damping_header="Damping [%]", zone="Z") -> str:
    lines = [sep.join(["Time", "Mode", "Frequency [Hz]", damping_header])]
    for k in range(3):
        for m in (1, 2):
            cells = [
                time_of(STARTS[k]).strftime("%Y-%m-%dT%H:%M:%S") + zone,
                f"Mode {m}",
                str(FREQUENCIES[m][k]),
                str(DAMPING_PCT[m][k]),
            ]
            lines.append(
                sep.join(c.replace(".", decimal) if i > 1 else c for i, c in enumerate(cells))
            )
    return "\n".join(lines) + "\n"


def test_long_artemis_style_with_centre_times_needs_no_guess(tmp_path):
    text = long_text(lambda start: start + pd.Timedelta(minutes=10), sep=";", decimal=",")
    path = write(tmp_path, text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check(read_modal_table(path, time_reference="centre"))


def test_time_reference_from_the_column_name_and_end_times(tmp_path):
    text = long_text(lambda start: start + pd.Timedelta(minutes=20)).replace("Time,", "window_end,")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check(read_modal_table(write(tmp_path, text)))


def test_unstated_time_reference_and_naive_times_warn(tmp_path):
    path = write(tmp_path, long_text(lambda start: start, zone=""))
    with pytest.warns(UserWarning) as caught:
        table = read_modal_table(path)
    messages = " | ".join(str(w.message) for w in caught)
    assert "have no time zone; taken as UTC" in messages
    assert "taken as the start of each analysis window" in messages
    check(table)
    # a stated zone moves the times: 01:00 Berlin (CET) is 00:00 UTC
    shifted = long_text(lambda start: start + pd.Timedelta(hours=1), zone="")
    table = read_modal_table(
        write(tmp_path, shifted, "berlin.csv"), time_zone="Europe/Berlin", time_reference="start"
    )
    check(table)


def test_wide_layout_with_fraction_damping_stated(tmp_path):
    lines = ["window_start,f1,f2,d1,d2"]
    for k in range(3):
        lines.append(
            ",".join(
                [
                    STARTS[k].isoformat(),
                    str(FREQUENCIES[1][k]),
                    str(FREQUENCIES[2][k]),
                    str(DAMPING_PCT[1][k] / 100),
                    str(DAMPING_PCT[2][k] / 100),
                ]
            )
        )
    path = write(tmp_path, "\n".join(lines) + "\n")
    with pytest.raises(ContractError) as caught:
        read_modal_table(path)
    assert "column 'd1': damping unit not stated (values 0.011 to 0.013)" in str(caught.value)
    check(read_modal_table(path, damping_unit="fraction"))


def test_block_indexed_layout_needs_the_grid_t0(tmp_path):
    lines = ["block;mode;f [Hz];zeta [%]"]
    for k in range(3):
        for m in (1, 2):
            lines.append(f"{k + 7};{m};{FREQUENCIES[m][k]};{DAMPING_PCT[m][k]}")
    path = write(tmp_path, "\n".join(lines) + "\n")
    with pytest.raises(ContractError, match="block numbers .* but no times: give the grid's t0"):
        read_modal_table(path)
    t0 = STARTS[0] - pd.Timedelta(minutes=35)
    table = read_modal_table(path, grid_t0=t0.isoformat())
    check(table, blocks_from=7)
    # the grid the layout placed the rows on travels with the table
    assert table.attrs["block_grid"] == {"t0": t0.isoformat(), "length_s": 1200.0, "step_s": 300.0}


def test_rows_without_frequency_are_dropped_and_counted(tmp_path):
    text = long_text(lambda start: start, damping_header="damping_pct")
    text += "2024-03-01T00:15:00Z,Mode 1,,\n2024-03-01T00:15:00Z,Mode 2,NaN,\n"
    with pytest.warns(UserWarning, match="dropped 2 mode estimate"):
        table = read_modal_table(write(tmp_path, text), time_reference="start")
    check(table)


def test_times_off_the_grid_are_refused_with_rows(tmp_path):
    text = long_text(lambda start: start + pd.Timedelta(minutes=2))
    path = write(tmp_path, text)
    with pytest.raises(ContractError) as caught:
        read_modal_table(path, time_reference="start", grid_t0="2024-03-01T00:00Z")
    message = str(caught.value)
    assert "column 'Time', row 0, row 1" in message and "not on the block grid" in message
    # the tool's own grid (10-min windows every 5 min from 00:02) reads it
    table = read_modal_table(
        path, time_reference="start", grid_t0="2024-03-01T00:02Z", block_length_s=600.0
    )
    assert table["block"].tolist() == [0, 0, 1, 1, 2, 2]
    assert (table["block_end"] - table["block_start"]).eq(pd.Timedelta(minutes=10)).all()


def test_unknown_layout_lists_the_columns(tmp_path):
    path = write(tmp_path, "when,what\n2024-03-01T00:00Z,3\n")
    with pytest.raises(ContractError, match="columns in the file: when, what"):
        read_modal_table(path)


def test_layout_options_are_checked():
    with pytest.raises(ValueError, match="damping_unit='%'"):
        ModalLayout(damping_unit="%")
    with pytest.raises(ValueError, match="block_step_s=600 must not exceed"):
        ModalLayout(block_length_s=300.0, block_step_s=600.0)


def test_evaluate_against_ones_own_observed_table(tmp_path, capsys):
    """The observed table as truth: SSI errors are zero, gains undefined, no crash."""
    modal = expected().assign(damping_ratio=0.01)
    modal_path = tmp_path / "observed.csv"
    modal.to_csv(modal_path, index=False)
    forecast = modal[["block", "block_start", "mode"]].assign(
        phase="forecast",
        ssi_frequency_hz=modal["frequency_hz"],
        model_frequency_hz=modal["frequency_hz"] + 0.01,
        model_lower_hz=modal["frequency_hz"] - 0.1,
        model_upper_hz=modal["frequency_hz"] + 0.1,
        kalman_frequency_hz=modal["frequency_hz"] + 0.005,
        kalman_std_hz=0.01,
        option="A",
        window_start_block=0,
        window_end_block=0,
    )
    forecast_path = tmp_path / "forecast.csv"
    forecast.to_csv(forecast_path, index=False)
    code = main(["evaluate", "--forecast", str(forecast_path), "--truth", str(modal_path)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "no gain vs SSI defined (SSI error is zero)" in out
    assert "the truth equals the SSI estimates" in err
    assert "model 0.060 Hz, Kalman 0.030 Hz" in out


def test_cli_reads_a_long_table_with_one_flag(tmp_path, capsys):
    text = long_text(lambda start: start, damping_header="damping").replace("Time,", "start,")
    path = write(tmp_path, text)
    forecast = tmp_path / "f.csv"
    pd.DataFrame(
        {
            "block": [0],
            "block_start": [STARTS[0]],
            "mode": [1],
            "phase": ["forecast"],
            "ssi_frequency_hz": [2.95],
            "model_frequency_hz": [2.9],
            "model_lower_hz": [2.8],
            "model_upper_hz": [3.0],
            "kalman_frequency_hz": [2.92],
            "kalman_std_hz": [0.01],
            "option": ["A"],
            "window_start_block": [0],
            "window_end_block": [0],
        }
    ).to_csv(forecast, index=False)
    assert main(["evaluate", "--forecast", str(forecast), "--truth", str(path)]) == 1
    assert "damping unit not stated" in capsys.readouterr().err
    code = main(
        ["evaluate", "--forecast", str(forecast), "--truth", str(path), "--damping-unit", "percent"]
    )
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "SSI 0.050 Hz, model 0.000 Hz, Kalman 0.020 Hz" in out
    assert np.isclose(0.02, abs(2.92 - FREQUENCIES[1][0]))


def test_frequency_only_wide_table_warns_and_leaves_damping_empty(tmp_path):
    lines = ["Time;f1 [Hz];f2 [Hz]"]
    for k in range(3):
        lines.append(f"{STARTS[k].isoformat()};{FREQUENCIES[1][k]};{FREQUENCIES[2][k]}")
    path = write(tmp_path, "\n".join(lines) + "\n")
    with pytest.warns(UserWarning, match="no damping column .*damping_ratio is left empty"):
        table = read_modal_table(path, time_reference="start")
    assert table["frequency_hz"].tolist() == expected()["frequency_hz"].tolist()
    assert table["damping_ratio"].isna().all()
    assert table["block"].tolist() == [0, 0, 1, 1, 2, 2]


def test_correlate_a_frequency_only_wide_table(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path), "--hours", "3", "--no-accelerations"]) == 0
    tracked = pd.read_csv(tmp_path / "tracked_modal.csv")
    wide = tracked.pivot(index="block_start", columns="mode", values="frequency_hz")
    wide.columns = [f"f{m} [Hz]" for m in wide.columns]
    wide.index.name = "window_start"
    wide.reset_index().to_csv(tmp_path / "wide.csv", index=False)
    capsys.readouterr()
    code = main(
        [
            "correlate",
            "--modal",
            str(tmp_path / "wide.csv"),
            "--dship",
            str(tmp_path / "dship.tsv"),
            "--out",
            str(tmp_path / "corr"),
        ]
    )
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "damping_ratio is left empty" in err and "Mean of empty slice" not in err
    table = pd.read_csv(tmp_path / "corr" / "correlation.csv")
    assert table["y"].str.endswith("frequency_hz").any()
    assert not table["y"].str.endswith("damping_ratio").any()


def test_a_monitors_parted_tracked_table_is_read_as_one_table(tmp_path):
    """The monitor's STATE/tracked.parquet is a folder of parts (data_contracts.parts);
    correlate, fit, forecast and evaluate read it as the one table its parts make, with
    its block grid. Before: "tracked.parquet: file not found" (it is a folder)."""
    from data_contracts import write_table
    from data_contracts.grid import GRID_ATTR, set_grid
    from data_contracts.parts import PartWriter
    from data_contracts.tables import MODAL

    table = expected()
    table["damping_ratio"] = [DAMPING_PCT[m][k] / 100 for k in range(3) for m in (1, 2)]
    grid = {"t0": "2024-03-01T00:00:00+00:00", "length_s": 1200.0, "step_s": 300.0}
    table = set_grid(MODAL.validate(table), grid)
    whole = write_table(table, tmp_path / "whole.parquet", MODAL)
    parted = tmp_path / "state" / "tracked.parquet"
    PartWriter(parted, MODAL, part_blocks=2).write(table)  # blocks 0-1 and block 2
    assert len(list(parted.glob("part-*.parquet"))) == 2
    read = read_modal_table(parted)
    check(read)
    pd.testing.assert_frame_equal(read, read_modal_table(whole))
    assert read.attrs[GRID_ATTR] == read_modal_table(whole).attrs[GRID_ATTR] == grid
