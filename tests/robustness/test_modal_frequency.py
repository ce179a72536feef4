"""A mode's natural frequency lies above 0 Hz: a modal (or selected) table with a row at
0 Hz is refused with exit 1 naming the file, the column and the first offending row; a
pole table keeps its real poles at 0 Hz.

Before: the MODAL contract's frequency bound was [0, 10000] Hz, so ``validate modal``,
``forecast``, ``correlate``, ``fit``, ``evaluate --truth`` and ``report`` took a mode at
0 Hz (exit 0; a regression of log f on it, a forecast of it); a negative frequency was
refused, but in another tool's wide table named as the reshaped table's ``frequency_hz``,
row 13, not the file's ``f2 [Hz]``, row 4.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from data_contracts import MODAL, POLES, SELECTED, ContractError
from workbench.cli import main

REASON = "values outside (0.0, 10000.0] Hz (a natural frequency lies above 0 Hz)"


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> Path:
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("modal_frequency") / "sim"
    simulate_voyage(folder, seed=0, hours=3, accelerations=False)
    return folder


def _modal_with(sim: Path, folder: Path, row: int, frequency_hz: float) -> Path:
    table = pd.read_csv(sim / "tracked_modal.csv")
    table.loc[row, "frequency_hz"] = frequency_hz
    path = folder / "tracked.csv"
    table.to_csv(path, index=False)
    grid = sim / "tracked_modal.csv.grid.json"
    path.with_name(path.name + ".grid.json").write_bytes(grid.read_bytes())
    return path


def _run(capsys, argv) -> tuple[int, list[str]]:
    status = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return status, [line for line in err.splitlines() if not line.startswith("warning:")]


@pytest.mark.parametrize("frequency_hz", [0.0, -2.5])
@pytest.mark.parametrize(
    "command",
    [
        ["validate", "modal", "{modal}"],
        ["forecast", "--modal", "{modal}", "--predictors", "{predictors}", "--out", "{out}.csv"],
        ["correlate", "--modal", "{modal}", "--predictors", "{predictors}", "--out", "{out}"],
        ["fit", "--modal", "{modal}", "--predictors", "{predictors}", "--out", "{out}"],
    ],
    ids=["validate", "forecast", "correlate", "fit"],
)
def test_a_mode_at_or_below_0_hz_is_refused_naming_file_column_row(
    sim, tmp_path, capsys, command, frequency_hz
):
    modal = _modal_with(sim, tmp_path, 17, frequency_hz)
    names = {"modal": modal, "predictors": sim / "truth_predictors.csv", "out": tmp_path / "o"}
    status, lines = _run(capsys, [part.format(**names) for part in command])
    assert status == 1
    assert lines == [f"{modal}: column 'frequency_hz', row 17: {REASON}"]
    assert not list(tmp_path.glob("o*"))  # nothing written


def test_evaluate_refuses_a_truth_at_0_hz(sim, tmp_path, capsys):
    truth = _modal_with(sim, tmp_path, 3, 0.0)
    forecast = tmp_path / "fc.csv"
    argv = ["forecast", "--modal", sim / "tracked_modal.csv"]
    argv += ["--predictors", sim / "truth_predictors.csv", "--out", forecast]
    assert main([str(a) for a in argv]) == 0
    capsys.readouterr()
    status, lines = _run(capsys, ["evaluate", "--forecast", forecast, "--truth", truth])
    assert status == 1
    assert lines == [f"{truth}: column 'frequency_hz', row 3: {REASON}"]


def test_another_tools_wide_table_is_named_by_its_own_column_and_row(sim, tmp_path, capsys):
    tracked = pd.read_csv(sim / "tracked_modal.csv")
    wide = tracked[tracked["mode"] <= 3].pivot(
        index="block_start", columns="mode", values="frequency_hz"
    )
    wide.columns = [f"f{m} [Hz]" for m in wide.columns]
    wide.index.name = "window_start"
    wide = wide.reset_index()
    wide.loc[4, "f2 [Hz]"] = 0.0
    path = tmp_path / "wide.csv"
    wide.to_csv(path, index=False)
    argv = ["correlate", "--modal", path, "--predictors", sim / "truth_predictors.csv"]
    argv += ["--time-reference", "start", "--out", tmp_path / "c"]
    status, lines = _run(capsys, argv)
    assert status == 1
    assert lines == [
        f"{path}: column 'f2 [Hz]', row 4: values at or below 0 (a natural frequency lies "
        "above 0 Hz)"
    ]
    # a cell left empty is a mode not found in that window, as before: dropped, not refused
    wide.loc[4, "f2 [Hz]"] = float("nan")
    wide.to_csv(path, index=False)
    assert main([str(a) for a in argv]) == 0


def _table(frequencies) -> pd.DataFrame:
    starts = pd.date_range("2026-03-01", periods=len(frequencies), freq="5min", tz="UTC")
    return pd.DataFrame(
        {
            "block": range(len(frequencies)),
            "block_start": starts,
            "block_end": starts + pd.Timedelta(minutes=20),
            "mode": 1,
            "frequency_hz": frequencies,
            "damping_ratio": 0.01,
        }
    )


def test_the_contracts_modal_and_selected_refuse_0_hz_poles_keep_it():
    frame = _table([3.1, 3.2, 0.0, 0.0])
    with pytest.raises(ContractError) as modal:
        MODAL.validate(frame, source="tracked.csv")
    assert modal.value.lines() == [f"tracked.csv: column 'frequency_hz', rows 2, 3: {REASON}"]
    with pytest.raises(ContractError, match=r"'frequency_hz', rows 2, 3: values outside \(0"):
        SELECTED.validate(frame.drop(columns=["mode"]))
    # a stabilisation diagram's real pole (no oscillation, damping 1) sits at 0 Hz
    poles = pd.DataFrame(
        {
            "block": [0, 0],
            "model_order": [4, 4],
            "frequency_hz": [0.0, 3.1],
            "damping_ratio": [1.0, 0.01],
            "stable": [False, True],
        }
    )
    assert POLES.validate(poles)["frequency_hz"].tolist() == [0.0, 3.1]
    # the smallest positive frequency is a frequency
    assert MODAL.validate(_table([1e-6, 3.2]))["frequency_hz"].tolist() == [1e-6, 3.2]


def test_validate_poles_at_0_hz_is_fine(sim, tmp_path, capsys):
    poles = pd.DataFrame(
        {
            "block": [0, 0, 1],
            "model_order": [4, 4, 4],
            "frequency_hz": [0.0, 3.1, 3.1],
            "damping_ratio": [1.0, 0.01, 0.01],
            "stable": [False, True, True],
        }
    )
    path = tmp_path / "poles.parquet"
    poles.to_parquet(path)
    assert main(["validate", "poles", str(path)]) == 0
    assert "valid poles file (3 rows)" in capsys.readouterr().out
