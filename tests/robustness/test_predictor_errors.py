"""Errors about the predictor table name the predictor file (or the ship log) and the
flag, not the modal table and the library's parameter.

Before: a predictor table ending early, or with holes, so that the training window did
not fit, ended ``forecast`` with "error: tracked_modal.csv: only 10 block(s) with
predictors in the span to forecast: 20 training blocks (train_blocks) and one to forecast
need at least 21" (the modal file, the library's name), and ``health --modal
--predictors`` with "error: tracked_modal.csv: training window of 24 blocks from block 0:
predictors have only 10 of them". A voyage shorter than the window (the predictor table
covering the modal table) was blamed on the predictors too; now the modal table is named.

Inputs: a 4-h simulated voyage's tables (45 blocks of 20 min every 5 min), no
accelerations, so the file runs in seconds.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main
from workbench.errors import DataError, PredictorError
from workbench.forecasting import sliding_forecast
from workbench.forecasting.options import ForecastOptions


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("predictor_errors") / "sim"
    simulate_voyage(folder, seed=0, hours=4, accelerations=False)
    return folder


def _predictors(sim: Path, folder: Path, name: str, keep) -> Path:
    """The voyage's predictor table with only the rows *keep* selects (grid file kept)."""
    source = sim / "truth_predictors.csv"
    table = pd.read_csv(source)
    path = folder / name
    table[keep(table)].to_csv(path, index=False)
    shutil.copyfile(
        source.with_name(source.name + ".grid.json"), path.with_name(path.name + ".grid.json")
    )
    return path


def _error(capsys, argv) -> tuple[int, str]:
    status = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(errors) <= 1, err
    return status, errors[0] if errors else ""


@pytest.mark.parametrize("model", ["memory", "window"])
def test_a_predictor_table_ending_early_is_named_with_the_flag(sim, tmp_path, capsys, model):
    predictors = _predictors(sim, tmp_path, "short.csv", lambda t: t["block"] < 10)
    argv = ["forecast", "--modal", sim / "tracked_modal.csv", "--predictors", predictors]
    argv += ["--train-blocks", "20", "--model", model, "--out", tmp_path / "fc.csv"]
    status, error = _error(capsys, argv)
    assert status == 1
    assert error == (
        f"error: {predictors}: the predictor table holds only 10 block(s) in the span to "
        "forecast (blocks 0 to 9): a training window of 20 blocks and one block to forecast "
        "need at least 21 (--train-blocks 20)"
    )
    assert not (tmp_path / "fc.csv").exists()


def test_a_predictor_table_with_holes_says_how_many_of_which_blocks(sim, tmp_path, capsys):
    predictors = _predictors(
        sim, tmp_path, "holes.csv", lambda t: (t["block"] < 8) | (t["block"] > 40)
    )
    argv = ["forecast", "--modal", sim / "tracked_modal.csv", "--predictors", predictors]
    status, error = _error(capsys, [*argv, "--train-blocks", "12", "--out", tmp_path / "f.csv"])
    assert status == 1
    # blocks 0-7 and 41-44: 12 rows, the window of 12 leaves none to forecast
    assert error == (
        f"error: {predictors}: the predictor table holds only 12 block(s) in the span to "
        "forecast (12 of blocks 0 to 44): a training window of 12 blocks and one block to "
        "forecast need at least 13 (--train-blocks 12)"
    )


@pytest.mark.parametrize("source", ["--predictors", "--dship"])
def test_a_voyage_shorter_than_the_window_names_the_modal_table(sim, tmp_path, capsys, source):
    """Every block of the modal table has predictors: the voyage is what is short."""
    given = sim / ("truth_predictors.csv" if source == "--predictors" else "dship.tsv")
    argv = ["forecast", "--modal", sim / "tracked_modal.csv", source, given]
    status, error = _error(capsys, [*argv, "--train-blocks", "45", "--out", tmp_path / "f.csv"])
    assert status == 1
    assert error == (
        f"error: {sim / 'tracked_modal.csv'}: the modal table holds only 45 block(s) in the "
        "span to forecast (blocks 0 to 44), each with predictors: a training window of 45 "
        "blocks and one block to forecast need at least 46 (--train-blocks 45)"
    )


def test_health_names_the_predictor_file_and_train_hours(sim, tmp_path, capsys):
    predictors = _predictors(sim, tmp_path, "short.csv", lambda t: t["block"] < 10)
    argv = ["health", "--modal", sim / "tracked_modal.csv", "--predictors", predictors]
    argv += ["--train-hours", "2", "--reference-hours", "1", "--out", tmp_path / "health"]
    status, error = _error(capsys, argv)
    assert status == 1
    # 2 h of 5-min steps: 24 blocks
    assert error == (
        f"error: {predictors}: the predictor table holds only 10 of the 24 blocks of the "
        "training window from block 0 (--train-hours 2: 24 blocks)"
    )


def test_the_library_says_the_parameter(sim):
    """A notebook reads the parameter's name and value, and can tell predictor problems
    (PredictorError) from a voyage too short (DataError) apart."""
    modal = pd.read_csv(sim / "tracked_modal.csv")
    predictors = pd.read_csv(sim / "truth_predictors.csv")
    options = ForecastOptions(train_blocks=20)
    with pytest.raises(PredictorError) as short:
        sliding_forecast(modal, predictors[predictors["block"] < 10], options)
    assert short.value.parameter == "train_blocks"
    assert short.value.value == 20
    assert str(short.value).endswith("need at least 21 (train_blocks=20)")
    with pytest.raises(DataError) as voyage:
        sliding_forecast(modal, predictors, ForecastOptions(train_blocks=45))
    assert not isinstance(voyage.value, PredictorError)
    assert str(voyage.value).startswith("the modal table holds only 45 block(s)")
    with pytest.raises(PredictorError, match="the predictor table has no column 'block_start'"):
        sliding_forecast(modal, predictors.drop(columns=["block_start"]), options)


def test_health_train_hours_too_short_for_the_model_is_a_usage_error(sim, tmp_path, capsys):
    """Before: "error: tracked_modal.csv: train_blocks=6 must be an integer >= 12" (exit 1,
    the modal file and the library's name for what is the flag's value)."""
    argv = ["health", "--modal", sim / "tracked_modal.csv"]
    argv += ["--predictors", sim / "truth_predictors.csv", "--train-hours", "0.5"]
    status = main([str(a) for a in [*argv, "--out", tmp_path / "health"]])
    err = capsys.readouterr().err
    assert status == 2
    assert err.strip().splitlines()[-1] == (
        "workbench: error: --train-hours 0.5 gives 6 block(s) of 5 min; the operational "
        "model needs at least 12 (1 h)"
    )
    assert not (tmp_path / "health").exists()


def test_fit_names_the_predictor_file_when_no_column_is_usable(sim, tmp_path, capsys):
    """Before: "error: tracked_modal.csv: no usable predictor column (all NaN or constant)"
    - the modal file blamed for a predictor table of one block (every column constant)."""
    predictors = _predictors(sim, tmp_path, "one.csv", lambda t: t["block"] == 0)
    argv = ["fit", "--modal", sim / "tracked_modal.csv", "--predictors", predictors]
    status, error = _error(capsys, [*argv, "--out", tmp_path / "fit", "--quiet"])
    assert status == 1
    assert error == f"error: {predictors}: no usable predictor column (all NaN or constant)"
