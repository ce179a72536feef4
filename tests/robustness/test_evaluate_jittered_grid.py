"""``evaluate`` scores a voyage whose block grid is anchored at a recorder's jittered first
stamp against the simulator's truth on whole minutes, and still refuses another voyage's.

``identify`` anchors its grid at the first file's start, which a recorder stamps to within
its clock jitter (files within 50 ms of each other are one record). The simulated voyage
with its files' stamps jittered by up to +-10 ms (seed 2: the first 4.768 ms early) gave
block starts 4.768 ms before the truth's, and ``evaluate`` refused it: "truth_modal.csv:
block 0 starts 2024-03-01T00:00:00Z, but 2024-02-29T23:59:59.995Z in forecast.parquet (69
of 69 common blocks differ, first by +0.004768 s)". Block starts within the clock jitter
are now the same block; a table of another day or shifted by a block (minutes) is refused.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from workbench.cli import main

#: How far before the truth's the jittered voyage's grid lies (its first stamp). [s]
JITTER_S = 0.004768


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> tuple[Path, Path]:
    """A 3-h simulated voyage (tables only) and its forecast."""
    from workbench.simulate import simulate_voyage

    folder = tmp_path_factory.mktemp("evaluate_grid") / "sim"
    simulate_voyage(folder, seed=0, hours=3, accelerations=False)
    forecast = folder / "forecast.csv"
    argv = ["forecast", "--modal", folder / "tracked_modal.csv"]
    argv += ["--predictors", folder / "truth_predictors.csv", "--out", forecast]
    assert main([str(a) for a in argv]) == 0
    return folder, forecast


def _shifted_truth(sim: Path, folder: Path, seconds: float) -> Path:
    """The truth with every block time (and its grid's anchor) moved by *seconds*."""
    truth = pd.read_csv(sim / "truth_modal.csv")
    shift = pd.Timedelta(seconds=seconds)
    for column in ("block_start", "block_end"):
        times = pd.to_datetime(truth[column], utc=True) + shift
        truth[column] = times.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    path = folder / "truth.csv"
    truth.to_csv(path, index=False)
    grid = json.loads((sim / "truth_modal.csv.grid.json").read_text(encoding="utf-8"))
    grid["t0"] = (pd.Timestamp(grid["t0"]) + shift).isoformat()
    path.with_name(path.name + ".grid.json").write_text(json.dumps(grid), encoding="utf-8")
    return path


def _evaluate(capsys, forecast: Path, truth: Path, out: Path) -> tuple[int, str]:
    argv = ["evaluate", "--forecast", forecast, "--truth", truth, "--out", out]
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err


def test_a_grid_within_the_clock_jitter_is_scored_as_the_truth_on_its_own(sim, tmp_path, capsys):
    folder, forecast = sim
    code, err = _evaluate(capsys, forecast, folder / "truth_modal.csv", tmp_path / "own.csv")
    assert code == 0, err
    # main: exit 1, "truth.csv: block 0 starts 2024-02-29T23:59:59.995Z, but ..."
    for seconds in (-JITTER_S, +JITTER_S, -0.049):
        truth = _shifted_truth(folder, tmp_path, seconds)
        code, err = _evaluate(capsys, forecast, truth, tmp_path / "shifted.csv")
        assert code == 0, err
        # the same blocks paired: the same errors to the last digit
        pd.testing.assert_frame_equal(
            pd.read_csv(tmp_path / "shifted.csv"), pd.read_csv(tmp_path / "own.csv")
        )
    scored = pd.read_csv(tmp_path / "own.csv")
    assert len(scored) >= 5 and (scored["n_blocks"] > 0).all()


@pytest.mark.parametrize(
    ("seconds", "said"),
    [
        (0.06, "block 0 starts 2024-03-01T00:00:00.060Z"),  # past the jitter
        (300.0, "block 0 starts 2024-03-01T00:05:00Z"),  # shifted by a block
        (86400.0, "block 0 starts 2024-03-02T00:00:00Z"),  # another day's voyage
    ],
    ids=["60 ms", "a block", "a day"],
)
def test_another_grid_is_still_refused(sim, tmp_path, capsys, seconds, said):
    folder, forecast = sim
    truth = _shifted_truth(folder, tmp_path, seconds)
    code, err = _evaluate(capsys, forecast, truth, tmp_path / "e.csv")
    assert code == 1
    lines = [line for line in err.splitlines() if not line.startswith("warning:")]
    assert len(lines) == 1
    assert lines[0].startswith(f"error: {truth}: {said}, but 2024-03-01T00:00:00Z in {forecast}")
    assert "starts within 0.05 s, a recorder's clock jitter, are the same" in lines[0]
    assert not (tmp_path / "e.csv").exists()
