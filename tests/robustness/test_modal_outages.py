"""A tracked modal table with a stretch of rows without a frequency (an SSI outage: the
rows kept, their estimates empty) is read by ``health --modal`` and ``report`` as by
``forecast``, ``fit`` and ``correlate``: those rows dropped, with a warning counting them.

Before: ``forecast`` over such a table ran (warning "dropped 92 row(s) without a
frequency"), but ``health --modal`` over the same table stopped with "column
'frequency_hz', rows 187, ... (+87 more): missing values are not allowed", and so did
``report`` of the run whose forecast had just been written from it.

Inputs: an 8-h simulated voyage's tables (93 blocks of 20 min every 5 min), no
accelerations; blocks 30-45 lose every mode's frequency and damping.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    sim = tmp_path_factory.mktemp("modal_outages") / "sim"
    simulate_voyage(sim, seed=0, hours=8, accelerations=False)
    folder = sim.parent / "run"
    folder.mkdir()
    table = pd.read_csv(sim / "tracked_modal.csv")
    outage = table["block"].between(30, 45)
    table.loc[outage, ["frequency_hz", "damping_ratio"]] = float("nan")
    table.to_csv(folder / "tracked_modal.csv", index=False)
    for name in ("tracked_modal.csv.grid.json",):
        shutil.copyfile(sim / name, folder / name)
    shutil.copyfile(sim / "truth_predictors.csv", folder / "predictors.csv")
    shutil.copyfile(sim / "truth_predictors.csv.grid.json", folder / "predictors.csv.grid.json")
    return folder


def _run(capsys, argv) -> tuple[int, str]:
    status = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return status, err


def test_health_reads_the_table_as_forecast_does(run, tmp_path, capsys):
    modal, predictors = run / "tracked_modal.csv", run / "predictors.csv"
    argv = ["health", "--modal", modal, "--predictors", predictors, "--train-hours", "4"]
    status, err = _run(capsys, [*argv, "--reference-hours", "2", "--out", tmp_path / "health"])
    assert status == 0, err
    assert f"warning: {modal}: dropped 92 row(s) without a frequency" in err
    assert (tmp_path / "health" / "health.csv").is_file()
    argv = ["forecast", "--modal", modal, "--predictors", predictors]
    status, err = _run(capsys, [*argv, "--out", tmp_path / "forecast.csv", "--quiet"])
    assert status == 0, err
    assert f"warning: {modal}: dropped 92 row(s) without a frequency" in err


def test_report_of_the_run_reads_it_too(run, capsys):
    status, err = _run(capsys, ["report", run, "--quiet"])
    assert status == 0, err
    assert f"warning: {run / 'tracked_modal.csv'}: dropped 92 row(s) without a frequency" in err
    assert (run / "report.html").is_file()
