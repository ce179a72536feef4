"""``workbench health --modal --predictors`` checks that the two tables mean the same
blocks, as ``forecast``, ``fit`` and ``correlate`` check it.

Before: health joined the tables on block numbers alone, so a predictor table of another
voyage (or of this one with another grid: block 0 thirty days later) gave a chart with
exit 0 and no word, the operational model fitted on another voyage's speeds and
temperatures; ``forecast`` over the same two tables refuses them ("block numbers must
mean the same times in every input"). A predictor table without any value charted with
an intercept-only model behind a warning about the training window only.

Inputs: an 8-h simulated voyage's tables (93 blocks of 20 min every 5 min), no
accelerations: long enough for a 4-h operational model and a 2-h reference.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main

HEALTH_ARGS = ["--train-hours", "4", "--reference-hours", "2", "--quiet"]


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("health_joins") / "sim"
    simulate_voyage(folder, seed=0, hours=8, accelerations=False)
    return folder


def _health(capsys, sim: Path, predictors: Path, out: Path) -> tuple[int, list[str]]:
    argv = ["health", "--modal", sim / "tracked_modal.csv", "--predictors", predictors]
    status = main([str(a) for a in [*argv, "--out", out, *HEALTH_ARGS]])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return status, [line for line in err.splitlines() if not line.startswith("warning:")]


def test_the_untouched_tables_chart(sim, tmp_path, capsys):
    status, errors = _health(capsys, sim, sim / "truth_predictors.csv", tmp_path / "out")
    assert status == 0, errors
    assert (tmp_path / "out" / "health.csv").is_file()


def test_predictors_of_other_times_are_refused_as_forecast_refuses_them(sim, tmp_path, capsys):
    table = pd.read_csv(sim / "truth_predictors.csv")
    for column in ("block_start", "block_end"):
        later = pd.to_datetime(table[column]) + pd.Timedelta(days=30)
        table[column] = later.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    path = tmp_path / "other_voyage.csv"
    table.to_csv(path, index=False)
    status, errors = _health(capsys, sim, path, tmp_path / "out")
    assert status == 1
    assert len(errors) == 1
    assert errors[0].startswith(f"error: {path}: block 0 starts 2024-03-31T00:00:00Z")
    assert "block numbers must mean the same times in every input" in errors[0]
    assert not (tmp_path / "out").exists()


def test_predictors_without_any_value_are_refused(sim, tmp_path, capsys):
    table = pd.read_csv(sim / "truth_predictors.csv")
    keys = ["block", "block_start", "block_end"]
    table[[c for c in table.columns if c not in keys]] = float("nan")
    path = tmp_path / "empty_predictors.csv"
    table.to_csv(path, index=False)
    status, errors = _health(capsys, sim, path, tmp_path / "out")
    assert status == 1
    assert errors == [
        f"error: {path}: no predictor value in any of its {len(table)} rows (speed_kn, "
        "water_temp_c, air_temp_c, wind_speed_ms, wind_dir_rel_deg, elapsed_hours empty "
        "throughout)"
    ]
    assert not (tmp_path / "out").exists()
