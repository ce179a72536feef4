"""``workbench health`` on damaged tables: one line naming the file, exit 1, no traceback;
a predictor column without a value in the training window is named, not dropped unsaid.

Before: a forecast, modal or predictor table with a header and no rows, or a table of one
block without a recorded grid, ended ``health`` with a traceback ("ValueError: cannot
convert float NaN to integer": the block step of a table of fewer than two blocks is
NaN).

Inputs: a 4-h simulated voyage's tables (45 blocks of 20 min every 5 min), no
accelerations, so the file runs in seconds.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("health_inputs") / "sim"
    simulate_voyage(folder, seed=0, hours=4, accelerations=False)
    assert (
        main(
            ["forecast", "--modal", str(folder / "tracked_modal.csv"), "--predictors"]
            + [str(folder / "truth_predictors.csv"), "--scheme", "single-window"]
            + ["--out", str(folder / "forecast.csv"), "--quiet"]
        )
        == 0
    )
    return folder


def _health(capsys, argv) -> tuple[int, list[str]]:
    status = main([str(a) for a in ["health", *argv, "--quiet"]])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return status, [line for line in err.splitlines() if not line.startswith("warning:")]


def _rows(source: Path, path: Path, keep) -> Path:
    """*source* with only the rows *keep* selects, written to *path* (no grid file)."""
    table = pd.read_csv(source)
    table[keep(table)].to_csv(path, index=False)
    return path


@pytest.mark.parametrize("given", ["forecast", "modal", "predictors"])
def test_a_table_with_a_header_only_is_named(sim, tmp_path, capsys, given):
    sources = {
        "forecast": sim / "forecast.csv",
        "modal": sim / "tracked_modal.csv",
        "predictors": sim / "truth_predictors.csv",
    }
    empty = _rows(sources[given], tmp_path / f"{given}.csv", lambda t: t["block"] < 0)
    tables = {**sources, given: empty}
    if given == "forecast":
        argv = ["--forecast", tables["forecast"]]
    else:
        argv = ["--modal", tables["modal"], "--predictors", tables["predictors"]]
        argv += ["--train-hours", "2"]
    status, lines = _health(capsys, [*argv, "--reference-hours", "1", "--out", tmp_path / "h"])
    assert status == 1
    assert lines == [f"error: {empty}: the table has a header but no rows"]
    assert not (tmp_path / "h").exists()


@pytest.mark.parametrize("given", ["forecast", "predictors"])
def test_a_table_of_one_block_without_its_grid_is_named(sim, tmp_path, capsys, given):
    source = sim / ("forecast.csv" if given == "forecast" else "truth_predictors.csv")
    one = _rows(source, tmp_path / f"{given}.csv", lambda t: t["block"] == 30)
    if given == "forecast":
        argv = ["--forecast", one]
    else:
        argv = ["--modal", sim / "tracked_modal.csv", "--predictors", one, "--train-hours", "2"]
    status, lines = _health(capsys, [*argv, "--reference-hours", "1", "--out", tmp_path / "h"])
    assert status == 1
    assert lines == [
        f"error: {one}: the table holds one block only and records no block grid: no block "
        "step to turn hours into blocks"
    ]
    assert not (tmp_path / "h").exists()


def test_a_dead_predictor_column_is_said_to_leave_its_terms_out(sim, tmp_path, capsys):
    """Before: a speed column without any value (a log whose speed sensor was dead) was left
    out of the operational model without a word, and the chart ran on a model without
    speed (exit 0, nothing said)."""
    table = pd.read_csv(sim / "truth_predictors.csv")
    table["speed_kn"] = float("nan")
    dead = tmp_path / "dead_speed.csv"
    table.to_csv(dead, index=False)
    argv = ["health", "--modal", sim / "tracked_modal.csv", "--predictors", dead]
    argv += ["--train-hours", "2", "--reference-hours", "1", "--out", tmp_path / "h"]
    assert main([str(a) for a in [*argv, "--quiet"]]) == 0
    err = capsys.readouterr().err
    assert err.splitlines() == [
        "warning: the predictor table holds no value of speed_kn in the training window "
        "(blocks 0-23): the operational model leaves out speed_kn, speed_kn^2, "
        "speed_kn*water_temp_c"
    ]


def test_a_column_empty_in_the_training_window_only_is_left_out_with_a_warning(sim):
    """Before: the speed logged only after the training window kept its terms in the model,
    whose every training row was then NaN: "no mode has enough training blocks" (every
    mode "only 0 training blocks"), which blamed the blocks instead of the column."""
    from data_contracts import MODAL, PREDICTORS, read_table
    from workbench.shm import fit_operational_model

    modal = read_table(sim / "tracked_modal.csv", MODAL)
    predictors = read_table(sim / "truth_predictors.csv", PREDICTORS)
    late = predictors.assign(speed_kn=predictors["speed_kn"].where(predictors["block"] >= 24))
    with pytest.warns(UserWarning, match=r"no value of speed_kn in the training window") as seen:
        model = fit_operational_model(modal, late, train_blocks=24)
    assert model.terms == ("water_temp_c", "air_temp_c")
    assert all("training blocks for" not in str(w.message) for w in seen)
    without = fit_operational_model(
        modal, predictors, train_blocks=24, terms=("water_temp_c", "air_temp_c")
    )
    assert model.modes == without.modes
    assert (model.coefficients == without.coefficients).all()
