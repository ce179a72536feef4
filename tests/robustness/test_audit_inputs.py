"""Inputs a ship's data system produces, and slips of the hand, that ended in lost data, a
success that did nothing or a wrong message (audit of every command, session 41).

* An output named like one of the command's inputs (``forecast --out`` the ``--modal``
  table, ``report --out`` the run's tracked table): refused before anything is written,
  the input kept.
* A pole table with a header but no rows for ``forecast --option pole-cluster``: refused
  naming the file (before: exit 0, a forecast whose option B never measured a block).
* A ship-log column that is there but holds no value in any row (a sensor dead for the
  whole export): a warning naming the column, as for a column that is missing (before:
  nothing said, the predictor quietly left out of every fit and correlation).
* A modal table whose every row lacks a frequency (an export of a failed analysis), or
  another tool's with a header only: one line saying so (before: "the table has a header
  but no rows" of a table of 279 rows, or a traceback for another tool's layout).
* ``health --train-hours`` or ``--reference-hours`` not a positive number (nan, inf, 0,
  -1): a usage error naming the flag (before: a traceback, or exit 1 naming the library's
  ``train_blocks=-12`` against the modal file).
* ``--grid`` with a block length or step of years, or block numbers that reach past the
  calendar on the grid: one line (before: a traceback, OutOfBoundsTimedelta or
  OverflowError).
* Another tool's modal table with one cell of its zoned time column that is not a time:
  that cell named (before: "some times carry a time zone and some do not").
* A predictor (or any contract) table re-saved by a spreadsheet in a decimal-comma locale
  (``;`` between fields, ``12,5``): read as the modal table of that kind already was
  (before: eight lines "required column is missing" for columns that are there).
* ``--excitation`` tables: one that is not an excitation table, or holds a cell that is no
  time, is one line naming the file (before: a traceback); intervals in another order
  (two files joined the wrong way round) weigh the log as the sorted table does (before:
  the predictors silently several knots off).
* ``simulate``/``demo --seed -1``: a usage error naming --seed (before: "expected
  non-negative integer", naming nothing, and a traceback from demo).
* A predictor table that ends before the modal table: the warning says the forecast does
  not reach the blocks without a predictor row (before: "forecasts fill them from the
  logged blocks", while the forecast left them out).

Inputs are small (a 4-h simulated table set without accelerations), so the file runs in
seconds.
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.cli import main


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    """A 4-h simulated voyage (tables only), its forecast and a `selected` table."""
    from workbench.simulate import simulate_voyage

    base = tmp_path_factory.mktemp("audit")
    sim = base / "sim"
    simulate_voyage(sim, seed=0, hours=4, accelerations=False)
    modal = pd.read_csv(sim / "tracked_modal.csv")
    modal.drop(columns=["mode", "mac"]).to_csv(base / "selected.csv", index=False)
    argv = ["forecast", "--modal", str(sim / "tracked_modal.csv"), "--predictors"]
    assert main([*argv, str(sim / "truth_predictors.csv"), "--out", str(base / "fc.csv")]) == 0
    return base


def _run(capsys, argv) -> tuple[int, str, str]:
    status = main([str(part) for part in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return status, out, err


def _one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if not line.startswith("warning:")]
    assert len(lines) == 1, err
    return lines[0]


# ----------------------------------------------------------------- output equal to an input
def _copies(root: Path, tmp_path: Path) -> dict[str, Path]:
    names = {
        "modal": root / "sim" / "tracked_modal.csv",
        "predictors": root / "sim" / "truth_predictors.csv",
        "truth": root / "sim" / "truth_modal.csv",
        "selected": root / "selected.csv",
        "forecast": root / "fc.csv",
    }
    copies = {}
    for key, source in names.items():
        copies[key] = tmp_path / source.name
        shutil.copyfile(source, copies[key])
    return copies


@pytest.mark.parametrize(
    ("command", "output", "flag"),
    [
        (["forecast", "--modal", "{modal}", "--predictors", "{predictors}"], "modal", "--modal"),
        (
            ["forecast", "--modal", "{modal}", "--predictors", "{predictors}"],
            "predictors",
            "--predictors",
        ),
        (["track", "{selected}"], "selected", "SELECTED"),
        (["evaluate", "--forecast", "{forecast}", "--truth", "{truth}"], "truth", "--truth"),
        (["evaluate", "--forecast", "{forecast}", "--truth", "{truth}"], "forecast", "--forecast"),
    ],
    ids=[
        "forecast-modal",
        "forecast-predictors",
        "track-selected",
        "evaluate-truth",
        "evaluate-fc",
    ],
)
def test_out_naming_an_input_is_refused_and_the_input_kept(
    root, tmp_path, capsys, command, output, flag
):
    """Before: exit 0, the input replaced by the output (a tracked modal table by the
    forecast, the truth by the evaluation)."""
    files = _copies(root, tmp_path)
    before = files[output].read_bytes()
    argv = [part.format(**files) for part in command] + ["--out", files[output]]
    status, _, err = _run(capsys, argv)
    assert status == 2, err
    line = _one_error_line(err)
    assert "--out" in line and flag in line and "replace" in line
    assert files[output].read_bytes() == before


def test_out_naming_the_same_file_by_another_path_is_refused(root, tmp_path, capsys):
    files = _copies(root, tmp_path)
    before = files["modal"].read_bytes()
    other = tmp_path / "sub" / ".." / files["modal"].name
    (tmp_path / "sub").mkdir()
    argv = ["forecast", "--modal", files["modal"], "--predictors", files["predictors"]]
    status, _, err = _run(capsys, [*argv, "--out", other])
    assert status == 2 and "--modal" in _one_error_line(err)
    assert files["modal"].read_bytes() == before


def test_report_out_naming_a_table_of_the_run_is_refused(root, tmp_path, capsys):
    """Before: exit 0, the run's tracked modal table replaced by the HTML page."""
    run = tmp_path / "run"
    run.mkdir()
    shutil.copyfile(root / "sim" / "tracked_modal.csv", run / "tracked_modal.csv")
    before = (run / "tracked_modal.csv").read_bytes()
    status, _, err = _run(capsys, ["report", run, "--out", run / "tracked_modal.csv"])
    assert status == 2, err
    assert "tracked modal table" in _one_error_line(err)
    assert (run / "tracked_modal.csv").read_bytes() == before
    assert not list(run.glob("report_files"))


def test_out_beside_the_inputs_is_written(root, tmp_path, capsys):
    files = _copies(root, tmp_path)
    argv = ["forecast", "--modal", files["modal"], "--predictors", files["predictors"]]
    status, _, err = _run(capsys, [*argv, "--out", tmp_path / "forecast.csv"])
    assert status == 0, err
    assert (tmp_path / "forecast.csv").is_file()


# ----------------------------------------------------------------------- empty pole table
def test_option_b_with_a_pole_table_without_rows_is_refused(root, tmp_path, capsys):
    poles = pd.read_parquet(root / "sim" / "poles.parquet")
    poles.iloc[:0].to_parquet(tmp_path / "poles.parquet")
    sim = root / "sim"
    argv = ["forecast", "--modal", sim / "tracked_modal.csv"]
    argv += ["--predictors", sim / "truth_predictors.csv", "--option", "B"]
    status, _, err = _run(
        capsys, [*argv, "--poles", tmp_path / "poles.parquet", "--out", tmp_path / "f.csv"]
    )
    assert status == 1, err
    line = _one_error_line(err)
    assert line.startswith(f"error: {tmp_path / 'poles.parquet'}: ") and "no rows" in line
    assert not (tmp_path / "f.csv").exists()


def test_forecast_stage_refuses_option_b_without_poles_rows(root):
    from workbench.forecasting.options import ForecastOptions
    from workbench.stages import forecast

    sim = root / "sim"
    poles = pd.read_parquet(sim / "poles.parquet").iloc[:0]
    with pytest.raises(ValueError, match="no rows") as raised:
        forecast(
            sim / "tracked_modal.csv",
            sim / "truth_predictors.csv",
            poles=poles,
            options=ForecastOptions(options=("B",)),
        )
    assert "option B" in str(raised.value)


# ------------------------------------------------------------- ship-log column with no value
def _log_without_speed(root: Path, target: Path) -> Path:
    """The simulated ship log with every cell of its speed column emptied."""
    lines = (root / "sim" / "dship.tsv").read_text(encoding="utf-8").splitlines(keepends=True)
    head = next(i for i, line in enumerate(lines) if line.startswith("Date/Time"))
    column = lines[head].rstrip("\n").split("\t").index("Speed [kn]")
    rows = []
    for line in lines[head + 1 :]:
        fields = line.rstrip("\n").split("\t")
        fields[column] = ""
        rows.append("\t".join(fields) + "\n")
    target.write_text("".join(lines[: head + 1] + rows), encoding="utf-8")
    return target


def test_ship_log_column_without_any_value_is_named(root, tmp_path):
    from data_contracts import read_dship

    path = _log_without_speed(root, tmp_path / "dship.tsv")
    with pytest.warns(UserWarning, match=r"'Speed \[kn\]' \(speed_kn\) holds no value"):
        log = read_dship(path)
    assert log["speed_kn"].isna().all() and log["water_temp_c"].notna().any()


def test_correlate_says_the_speed_column_of_the_log_is_empty(root, tmp_path, capsys):
    path = _log_without_speed(root, tmp_path / "dship.tsv")
    argv = ["correlate", "--modal", root / "sim" / "tracked_modal.csv", "--dship", path]
    status, _, err = _run(capsys, [*argv, "--out", tmp_path / "c"])
    assert status == 0, err
    assert f"warning: {path}: column 'Speed [kn]' (speed_kn) holds no value" in err


# -------------------------------------------------------------- modal table without frequency
def _correlate_refuses(root, tmp_path, capsys, modal):
    """Write *modal* (a table, or a file's text) as tmp_path/modal.csv, run ``correlate``
    on it with the simulated voyage's predictors: exit 1; the path and the one error line."""
    path = tmp_path / "modal.csv"
    if isinstance(modal, str):
        path.write_text(modal, encoding="utf-8")
    else:
        modal.to_csv(path, index=False)
    predictors = root / "sim" / "truth_predictors.csv"
    argv = ["correlate", "--modal", path, "--predictors", predictors, "--out", tmp_path / "c"]
    status, _, err = _run(capsys, argv)
    assert status == 1, err
    return path, _one_error_line(err)


def _long_modal(root) -> pd.DataFrame:
    """The simulated voyage's tracked table as another tool's long table (time, mode,
    frequency, damping)."""
    modal = pd.read_csv(root / "sim" / "tracked_modal.csv")
    modal = modal[["block_start", "mode", "frequency_hz", "damping_ratio"]]
    return modal.rename(columns={"block_start": "time"})


@pytest.mark.parametrize("layout", ["contract", "long", "wide"])
def test_modal_table_whose_every_frequency_is_missing_says_so(root, tmp_path, capsys, layout):
    """Before: the MODAL layout said "header but no rows"; another tool's long or wide
    table ended in a traceback (OutOfBoundsDatetime: the grid's t0 from no time)."""
    modal = pd.read_csv(root / "sim" / "tracked_modal.csv")
    modal["frequency_hz"] = float("nan")
    if layout == "long":  # another tool's table: time, mode, frequency, damping
        modal = modal[["block_start", "mode", "frequency_hz", "damping_ratio"]]
        modal = modal.rename(columns={"block_start": "time", "frequency_hz": "Frequency [Hz]"})
    elif layout == "wide":  # time, f1, f2, ...
        modal = modal.pivot(index="block_start", columns="mode", values="frequency_hz")
        modal = modal.rename(columns=lambda mode: f"f{mode}").rename_axis("time").reset_index()
    path, line = _correlate_refuses(root, tmp_path, capsys, modal)
    assert str(path) in line and f"no row has a frequency ({len(modal)} rows)" in line
    assert "header but no rows" not in line


def test_long_modal_table_with_a_header_only_says_so(root, tmp_path, capsys):
    """Before: a traceback (OutOfBoundsDatetime)."""
    path, line = _correlate_refuses(
        root, tmp_path, capsys, "time,mode,Frequency [Hz],damping_ratio\n"
    )
    assert line == f"{path}: the table has a header but no rows"


# ------------------------------------------------------------------------ health hour flags
@pytest.mark.parametrize("value", ["nan", "inf", "0", "-1"])
@pytest.mark.parametrize("flag", ["--train-hours", "--reference-hours"])
def test_health_hours_that_are_not_a_positive_number_are_a_usage_error(
    root, tmp_path, capsys, flag, value
):
    sim = root / "sim"
    argv = ["health", "--modal", sim / "tracked_modal.csv"]
    argv += ["--predictors", sim / "truth_predictors.csv", "--train-hours", "2"]
    status, _, err = _run(capsys, [*argv, flag, value, "--out", tmp_path / "h"])
    assert status == 2, err
    line = _one_error_line(err)
    assert line.startswith(f"workbench: error: {flag} must be a positive number of hours")
    assert not (tmp_path / "h").exists()


@pytest.mark.parametrize("value", [float("nan"), float("inf"), 0.0])
def test_health_stage_refuses_reference_hours_that_are_not_positive(root, value):
    from workbench.stages import health

    with pytest.raises(ValueError, match="reference_hours"):
        health(root / "fc.csv", reference_hours=value)


# ----------------------------------------------------------------------- grids past the calendar
@pytest.fixture()
def block_only(root, tmp_path) -> Path:
    """Another tool's table with block numbers and no times."""
    modal = pd.read_csv(root / "sim" / "tracked_modal.csv")
    path = tmp_path / "blocks.csv"
    modal[["block", "mode", "frequency_hz", "damping_ratio"]].to_csv(path, index=False)
    return path


@pytest.mark.parametrize("grid", ["1e30,1e30", "1e7,1e7,2024-03-01", "1e12,1e12,2024-03-01"])
def test_grid_of_years_long_blocks_is_a_usage_error(root, tmp_path, capsys, block_only, grid):
    sim = root / "sim"
    argv = ["correlate", "--modal", block_only, "--grid", grid]
    status, _, err = _run(
        capsys, [*argv, "--predictors", sim / "truth_predictors.csv", "--out", tmp_path / "c"]
    )
    assert status == 2, err
    assert _one_error_line(err).startswith("workbench: error: --grid: block_")


def test_block_numbers_past_the_calendar_are_named(root, tmp_path, capsys, block_only):
    table = pd.read_csv(block_only)
    table.loc[0, "block"] = 10**15  # 10^15 blocks of 5 min: ~10^10 years after t0
    table.to_csv(block_only, index=False)
    sim = root / "sim"
    argv = ["correlate", "--modal", block_only, "--grid", "20,5,2024-03-01T00:00Z"]
    status, _, err = _run(
        capsys, [*argv, "--predictors", sim / "truth_predictors.csv", "--out", tmp_path / "c"]
    )
    assert status == 1, err
    line = _one_error_line(err)
    assert line.startswith(f"{block_only}: column 'block'") and "1000000000000000" in line


# ------------------------------------------------------------------- a cell that is no time
def test_a_cell_that_is_not_a_time_among_zoned_times_is_named(root, tmp_path, capsys):
    modal = _long_modal(root)
    modal.loc[5, "time"] = "sensor fault"
    _, line = _correlate_refuses(root, tmp_path, capsys, modal)
    assert "'sensor fault'" in line and "time zone" not in line


def test_times_with_and_without_a_zone_are_still_refused_as_mixed(root, tmp_path, capsys):
    modal = _long_modal(root)
    modal.loc[5, "time"] = modal.loc[5, "time"].rstrip("Z")
    _, line = _correlate_refuses(root, tmp_path, capsys, modal)
    assert "some times carry a time zone and some do not" in line


# ------------------------------------------------------------- spreadsheet re-saves with ';'
@pytest.mark.parametrize("decimal", [",", "."])
def test_contract_table_with_semicolons_is_read_as_written(root, tmp_path, decimal):
    from data_contracts import PREDICTORS, read_table

    source = root / "sim" / "truth_predictors.csv"
    path = tmp_path / "predictors.csv"
    pd.read_csv(source).to_csv(path, sep=";", decimal=decimal, index=False)
    pd.testing.assert_frame_equal(read_table(path, PREDICTORS), read_table(source, PREDICTORS))


def test_forecast_reads_a_semicolon_predictor_table(root, tmp_path, capsys):
    path = tmp_path / "predictors.csv"
    pd.read_csv(root / "sim" / "truth_predictors.csv").to_csv(
        path, sep=";", decimal=",", index=False
    )
    argv = ["forecast", "--modal", root / "sim" / "tracked_modal.csv", "--predictors", path]
    status, _, err = _run(capsys, [*argv, "--out", tmp_path / "f.csv"])
    assert status == 0, err
    expected = pd.read_csv(root / "fc.csv")
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "f.csv"), expected)


# -------------------------------------------------------------------------- excitation tables
def _excitation(path: Path) -> pd.DataFrame:
    """Half-steps of 150 s over the 4-h voyage with made-up powers."""
    times = pd.date_range("2024-03-01T00:00:00Z", "2024-03-01T04:00:00Z", freq="150s")
    table = pd.DataFrame(
        {
            "start": times[:-1].strftime("%Y-%m-%dT%H:%M:%SZ"),
            "end": times[1:].strftime("%Y-%m-%dT%H:%M:%SZ"),
            "power": np.random.default_rng(0).uniform(0.1, 10.0, len(times) - 1),
        }
    )
    table.to_csv(path, index=False)
    return table


@pytest.mark.parametrize(
    ("content", "fragment"),
    [
        ("x\n1\n", "lacks column(s) start, end, power"),
        ("start,end,power\nnot a time,2024-03-01T00:10:00Z,1\n", "'not a time'"),
    ],
    ids=["not-an-excitation-table", "no-time"],
)
def test_bad_excitation_table_is_one_line_naming_it(root, tmp_path, capsys, content, fragment):
    path = tmp_path / "excitation.csv"
    path.write_text(content, encoding="utf-8")
    sim = root / "sim"
    argv = ["correlate", "--modal", sim / "tracked_modal.csv", "--dship", sim / "dship.tsv"]
    status, _, err = _run(capsys, [*argv, "--excitation", path, "--out", tmp_path / "c"])
    assert status == 1, err
    line = _one_error_line(err)
    assert str(path) in line and fragment in line


def test_excitation_intervals_in_any_order_weigh_the_log_alike(root, tmp_path):
    from data_contracts import MODAL, read_table
    from workbench.predictors import load_predictors

    sim = root / "sim"
    modal = read_table(sim / "tracked_modal.csv", MODAL)
    table = _excitation(tmp_path / "sorted.csv")
    table.sample(frac=1.0, random_state=0).to_csv(tmp_path / "shuffled.csv", index=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        expected = load_predictors(
            dship=sim / "dship.tsv", onto=modal, excitation=tmp_path / "sorted.csv"
        )
        shuffled = load_predictors(
            dship=sim / "dship.tsv", onto=modal, excitation=tmp_path / "shuffled.csv"
        )
    pd.testing.assert_frame_equal(shuffled, expected)


# ------------------------------------------------------------------------------ negative seed
@pytest.mark.parametrize("command", ["simulate", "demo"])
def test_negative_seed_is_a_usage_error_naming_the_flag(tmp_path, capsys, command):
    argv = [command, "--seed", "-1", "--hours", "0.5", "--out", tmp_path / "out"]
    status, _, err = _run(capsys, argv)
    assert status == 2, err
    assert _one_error_line(err) == "workbench: error: --seed must be a non-negative integer, got -1"
    assert not (tmp_path / "out").exists()


def test_simulate_voyage_refuses_a_negative_seed_before_writing(tmp_path):
    from workbench.simulate import simulate_voyage

    with pytest.raises(ValueError, match="seed=-1 must be a non-negative integer"):
        simulate_voyage(tmp_path / "sim", seed=-1, hours=0.5, accelerations=False)
    assert not (tmp_path / "sim").exists()


# ------------------------------------------------------- predictor table shorter than modal
def test_blocks_without_a_predictor_row_are_said_to_be_left_out_of_the_forecast(
    root, tmp_path, capsys
):
    sim = root / "sim"
    predictors = pd.read_csv(sim / "truth_predictors.csv")
    path = tmp_path / "predictors.csv"
    predictors[predictors["block"] <= 30].to_csv(path, index=False)
    argv = ["forecast", "--modal", sim / "tracked_modal.csv", "--predictors", path]
    status, _, err = _run(capsys, [*argv, "--out", tmp_path / "f.csv"])
    assert status == 0, err
    warning = next(line for line in err.splitlines() if "blocks of the modal table" in line)
    assert "no predictor row for 14 of 45 blocks" in warning and "blocks 31 to 44" in warning
    assert "forecasts fill them" not in warning and "forecasts do not reach them" in warning
    assert pd.read_csv(tmp_path / "f.csv")["block"].max() == 30
