"""Issue 28's fuzz round: each case ends with the right table or a one-line error with the
right exit code (1 bad data, 2 usage), no traceback.

The cases: a table cut mid-row, boolean accelerations, an RFC 4180 quoted ship-log header,
cases outside the voyage, evaluation without SSI rows or without forecast rows, and identify
runs that would do nothing (records shorter than a block, files 1 s short, every block
failing, a band edge at 1e-9 Hz). Inputs are small (a 4-h simulated table set without
accelerations, 4-minute 32-Hz voyages), so the file runs in seconds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import (
    AccelerationRecord,
    ContractError,
    read_dship,
    validate_accelerations,
    write_accelerations,
)
from workbench.cli import main

from .voyage import CHANNELS, IDENTIFY_ARGS, RATE_HZ, T0, response, write_voyage


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    base = tmp_path_factory.mktemp("fuzz28")
    simulate_voyage(base / "sim", seed=0, hours=4, accelerations=False)
    return base


def _run(capsys, argv) -> tuple[int, str, str]:
    status = main([str(part) for part in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "np.float64(" not in out + err
    return status, out, err


def _one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if not line.startswith("warning:")]
    assert len(lines) == 1, err
    return lines[0]


# --------------------------------------------------------------------------- cut mid-row
def _cut_mid_row(source: Path, target: Path) -> int:
    """*source* with its last line cut in half; returns that line's number (1-based)."""
    text = source.read_text(encoding="utf-8").rstrip("\n")
    lines = text.split("\n")
    lines[-1] = lines[-1][: len(lines[-1]) // 2]
    target.write_text("\n".join(lines), encoding="utf-8")
    return len(lines)


def test_modal_table_cut_mid_row_is_refused_naming_file_and_line(root, tmp_path, capsys):
    cut = tmp_path / "modal_cut.csv"
    line = _cut_mid_row(root / "sim" / "tracked_modal.csv", cut)
    # before: "valid modal file", the last row's missing fields read as NaN
    for argv in (
        ["validate", "modal", cut],
        [
            "correlate",
            "--modal",
            cut,
            "--predictors",
            root / "sim" / "truth_predictors.csv",
            "--out",
            tmp_path / "c",
        ],
    ):
        status, _, err = _run(capsys, argv)
        assert status == 1
        message = _one_error_line(err)
        assert "modal_cut.csv" in message and f"line {line}:" in message
        assert "ends mid-row" in message
    assert not (tmp_path / "c").exists()
    # the whole file (the cut row dropped by hand) is a valid table: the check is the cut
    whole = tmp_path / "modal_whole.csv"
    whole.write_text(
        "\n".join(cut.read_text(encoding="utf-8").split("\n")[:-1]) + "\n", encoding="utf-8"
    )
    status, out, _ = _run(capsys, ["validate", "modal", whole])
    assert status == 0 and f"({line - 2} rows)" in out


def test_acceleration_csv_cut_mid_row_is_refused(tmp_path, capsys):
    n = 256
    times = T0 + pd.to_timedelta(np.arange(n) / RATE_HZ, unit="s")
    frame = pd.DataFrame(response(n, 1), columns=list(CHANNELS))
    frame.insert(0, "time", times.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
    frame.to_csv(tmp_path / "whole.csv", index=False)
    line = _cut_mid_row(tmp_path / "whole.csv", tmp_path / "cut.csv")
    status, _, err = _run(capsys, ["validate", "accelerations", tmp_path / "cut.csv"])
    assert status == 1
    assert f"cut.csv: cannot read file: line {line}: " in _one_error_line(err)
    assert _run(capsys, ["validate", "accelerations", tmp_path / "whole.csv"])[0] == 0


# --------------------------------------------------------------------------- boolean samples
def test_boolean_accelerations_are_refused(tmp_path, capsys):
    record = AccelerationRecord(response(256, 1) > 0, RATE_HZ, T0, CHANNELS)
    with pytest.raises(ContractError, match="boolean values") as caught:
        validate_accelerations(record)
    assert "acceleration" in str(caught.value)
    path = tmp_path / "mask.npz"
    with open(path, "wb") as handle:
        np.savez(
            handle,
            acceleration=record.acceleration,
            sampling_rate_hz=np.float64(RATE_HZ),
            start_time=np.str_("2026-03-01T00:00:00Z"),
            channels=np.array(CHANNELS),
        )
    status, _, err = _run(capsys, ["validate", "accelerations", path])
    assert status == 1
    message = _one_error_line(err)
    assert "mask.npz" in message and "boolean values" in message
    # 0/1 as numbers are samples (a float array that happens to hold 0 and 1)
    numbers = AccelerationRecord(record.acceleration.astype(float), RATE_HZ, T0, CHANNELS)
    assert validate_accelerations(numbers).acceleration.dtype == np.float64


# --------------------------------------------------------------------------- quoted header
def test_rfc4180_quoted_ship_log_header_is_read(root, tmp_path, capsys):
    source = root / "sim" / "dship.tsv"
    lines = source.read_text(encoding="utf-8").splitlines(keepends=True)
    head = next(i for i, line in enumerate(lines) if line.startswith("Date/Time"))
    names = lines[head].rstrip("\n").split("\t")
    quoted = lines.copy()
    quoted[head] = "\t".join(f'"{name}"' for name in names) + "\n"
    # quoted values too, as a spreadsheet's "quote all fields" export writes them
    quoted[head + 1 :] = [
        "\t".join(f'"{field}"' for field in line.rstrip("\n").split("\t")) + "\n"
        for line in lines[head + 1 :]
    ]
    path = tmp_path / "dship_quoted.tsv"
    path.write_text("".join(quoted), encoding="utf-8")
    # before: "column 'Date/Time': time column is missing"
    status, out, _ = _run(capsys, ["validate", "dship", path])
    assert status == 0 and "valid dship file" in out
    expected = read_dship(source)
    pd.testing.assert_frame_equal(read_dship(path), expected)


# --------------------------------------------------------------------------- cases outside
def test_case_wholly_outside_the_voyage_is_named(root, tmp_path, capsys):
    from workbench.stages import correlate

    cases = pd.read_csv(root / "sim" / "cases.csv")
    cases.loc[len(cases)] = ["harbour", "2024-05-01T00:00:00Z", "2024-05-02T00:00:00Z"]
    cases.to_csv(tmp_path / "cases.csv", index=False)
    # the stage (the CLI prints its warnings as "warning: ..." lines; figures not needed)
    result = correlate(
        root / "sim" / "tracked_modal.csv",
        root / "sim" / "truth_predictors.csv",
        cases=tmp_path / "cases.csv",
    )
    # before: the case listed with 0 useful pairs and no warning
    assert len(result.warnings) == 1
    assert "case 'harbour' holds no block of the voyage" in result.warnings[0]
    assert "2024-03-01T00:00Z to 2024-03-01T04:00Z" in result.warnings[0]
    table = result.table
    assert (table.loc[table["case"] == "harbour", "n"] == 0).all()
    assert (table.loc[table["case"] == "stationary", "n"] > 0).all()
    assert (
        correlate(
            root / "sim" / "tracked_modal.csv",
            root / "sim" / "truth_predictors.csv",
            cases=root / "sim" / "cases.csv",
        ).warnings
        == []
    )
    argv = [
        "correlate",
        "--modal",
        root / "sim" / "tracked_modal.csv",
        "--predictors",
        root / "sim" / "truth_predictors.csv",
        "--out",
        tmp_path / "c",
    ]
    # every case outside: nothing to correlate is an error naming the cases file
    outside = cases[cases["case"] == "harbour"]
    outside.to_csv(tmp_path / "outside.csv", index=False)
    status, _, err = _run(capsys, [*argv, "--cases", tmp_path / "outside.csv"])
    assert status == 1
    message = _one_error_line(err)
    assert "outside.csv: no case holds a block of the voyage" in message and "'harbour'" in message
    assert not (tmp_path / "c").exists()


# --------------------------------------------------------------------------- evaluate
@pytest.fixture(scope="module")
def forecast(root) -> Path:
    path = root / "forecast.csv"
    argv = [
        "forecast",
        "--modal",
        root / "sim" / "tracked_modal.csv",
        "--predictors",
        root / "sim" / "truth_predictors.csv",
        "--out",
        path,
        "--quiet",
    ]
    assert main([str(part) for part in argv]) == 0
    return path


def test_evaluate_mode_without_ssi_says_no_data_not_zero_hz(root, forecast, tmp_path, capsys):
    table = pd.read_csv(forecast)
    blind = table.copy()
    blind.loc[(blind["mode"] == 1) & (blind["phase"] == "forecast"), "ssi_frequency_hz"] = np.nan
    blind.to_csv(tmp_path / "blind.csv", index=False)
    out_file = tmp_path / "evaluation.csv"
    status, out, err = _run(
        capsys,
        [
            "evaluate",
            "--forecast",
            tmp_path / "blind.csv",
            "--truth",
            root / "sim" / "truth_modal.csv",
            "--out",
            out_file,
        ],
    )
    assert status == 0
    result = pd.read_csv(out_file).set_index("mode")
    errors = ["ssi_cumulative_error_hz", "model_cumulative_error_hz", "kalman_cumulative_error_hz"]
    # before: 0 / 0 / 0 Hz, which reads as a perfect estimate
    assert result.loc[1, "n_ssi"] == 0 and result.loc[1, errors].isna().all()
    assert result.loc[1, "n_blocks"] > 0
    assert (result.drop(index=1)[errors] > 0).all().all()
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert any("mode 1: no SSI estimate in the forecast rows" in line for line in warnings)
    # the totals are over the modes with data: equal to the sums of the other modes
    ssi_total = result.drop(index=1)["ssi_cumulative_error_hz"].sum()
    assert f"cumulative |error| SSI {ssi_total:.3f} Hz" in out


def test_evaluate_training_only_table_is_an_error(root, forecast, tmp_path, capsys):
    table = pd.read_csv(forecast)
    training = table[table["phase"] == "train"]
    training.to_csv(tmp_path / "train_only.csv", index=False)
    argv = ["evaluate", "--forecast", tmp_path / "train_only.csv", "--truth"]
    status, out, err = _run(capsys, [*argv, root / "sim" / "truth_modal.csv"])
    # before: exit 0 printing "Empty DataFrame"
    assert status == 1 and "Empty DataFrame" not in out
    message = _one_error_line(err)
    assert "train_only.csv" in message and "no 'forecast' rows" in message
    assert "phases in it: train" in message
    # the training phase of the same table is evaluated
    status, out, _ = _run(capsys, [*argv, root / "sim" / "truth_modal.csv", "--phase", "train"])
    assert status == 0 and "option A: cumulative |error|" in out


# --------------------------------------------------------------------------- identify
def _identify(capsys, folder: Path, out: Path, *extra) -> tuple[int, str, str]:
    return _run(capsys, ["identify", folder, "--out", out, *IDENTIFY_ARGS, *extra])


def test_identify_every_record_shorter_than_a_block_is_an_error(tmp_path, capsys):
    folder = tmp_path / "short_records"
    folder.mkdir()
    for k in range(3):  # 50-s records 150 s apart: none holds a 2-min block
        record = AccelerationRecord(
            response(int(50 * RATE_HZ), k), RATE_HZ, T0 + pd.Timedelta(seconds=200 * k), CHANNELS
        )
        write_accelerations(record, folder / f"acc_{k:03d}.npz")
    status, out, err = _identify(capsys, folder, tmp_path / "out")
    # before: exit 0, "0 block(s) processed, 6 skipped"
    assert status == 1 and "0 block(s) processed" not in out
    message = _one_error_line(err)
    assert "each of the 3 records" in message and "shorter than one block (2 min" in message
    assert "150.0 s between acc_000.npz and acc_001.npz" in message


def test_identify_files_one_second_short_is_an_error_naming_the_gap(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=4, short_s=1.0)
    status, _, err = _identify(capsys, tmp_path / "voyage", tmp_path / "out")
    assert status == 1
    message = _one_error_line(err)
    assert "each of the 4 records" in message and "1.0 s between acc_000.npz" in message
    assert "--max-gap" in message
    # with the gap allowed the same files are identified
    status, out, _ = _identify(capsys, tmp_path / "voyage", tmp_path / "out", "--max-gap", "2")
    assert status == 0 and "2 block(s) processed" in out


def test_identify_with_every_block_failing_is_an_error(tmp_path, capsys):
    folder = tmp_path / "silent"
    folder.mkdir()
    for k in range(4):  # sensors that recorded nothing: every channel flat
        record = AccelerationRecord(
            np.zeros((int(60 * RATE_HZ), 4)), RATE_HZ, T0 + pd.Timedelta(seconds=60 * k), CHANNELS
        )
        write_accelerations(record, folder / f"acc_{k:03d}.npz")
    status, out, err = _identify(capsys, folder, tmp_path / "out")
    assert status == 1 and "0 block(s) processed" not in out
    message = _one_error_line(err)
    assert "no block identified: all 3 block(s) skipped: all channels faulty (3)" in message


def test_identify_band_edge_below_one_cycle_per_block_is_a_usage_error(tmp_path, capsys):
    write_voyage(tmp_path / "voyage", n_files=4)
    # before: exit 0, "0 block(s) processed, 3 skipped: Singular matrix"
    status, _, err = _identify(
        capsys, tmp_path / "voyage", tmp_path / "out", "--band", "1e-9", "12"
    )
    assert status == 2
    message = _one_error_line(err)
    assert "--band" in message and "1e-09" in message and "0.00833 Hz" in message
    assert str(tmp_path) not in message  # usage errors do not blame an input file
    assert not (tmp_path / "out" / "blocks.csv").exists()
    # one cycle per 2-min block and above, and 0 (a low-pass), are identified
    for low in ("0.0084", "0"):
        status, out, _ = _identify(
            capsys, tmp_path / "voyage", tmp_path / f"out_{low}", "--band", low, "12"
        )
        assert status == 0 and "3 block(s) processed, 0 skipped" in out


def test_identify_library_refuses_the_band_before_any_work(tmp_path):
    from workbench.errors import OptionError
    from workbench.stages import IdentifyOptions, identify

    write_voyage(tmp_path / "voyage", n_files=4)
    options = IdentifyOptions(length_s=120.0, step_s=60.0, band_hz=(1e-9, 12.0))
    with pytest.raises(OptionError, match=r"lower edge must be 0 \(a low-pass\) or at least"):
        identify(tmp_path / "voyage", tmp_path / "out", options=options, scheduler="synchronous")
    assert not (tmp_path / "out" / "poles.parquet").exists()
