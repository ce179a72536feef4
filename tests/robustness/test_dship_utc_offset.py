"""A ship log in local time written without a UTC offset.

Before: ``2024-03-01T02:00:00`` meant as UTC+02:00 was read as UTC, so every predictor
landed two hours after the blocks it belongs to (the models fitted the wrong speed to the
modes, the harmonic marking read the wrong shaft speed), and the only hint was a "no
predictor value" warning for the blocks at the ends.

Now ``--dship-utc-offset +02:00`` (identify, correlate, fit, forecast, monitor, validate,
report) places such times; times carrying their own offset keep it. A bad value is a
one-line usage error (exit 2). Identify checks the two clocks from physics: the hull's
vibration level rises with the speed, so when the log's speed follows the blocks' level
clearly better at another whole or half hour, one warning names the file and the likely
offset.
"""

from __future__ import annotations

from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import read_dship
from data_contracts.modal_layout import read_modal_table
from workbench.cli import main
from workbench.predictors import load_predictors
from workbench.predictors.clock import clock_shift_scores
from workbench.simulate import simulate_voyage

#: Light identification: the check reads only the blocks' RMS per channel.
IDENTIFY_ARGS = [
    "--block-rows",
    "10",
    "--min-order",
    "4",
    "--max-order",
    "12",
    "--stabilisation-figures",
    "0",
    "--scheduler",
    "synchronous",
    "--quiet",
]


def _local_log(correct: Path, local: Path, hours: float) -> Path:
    """*correct* (times in UTC, no offset) rewritten as a clock *hours* ahead of UTC would
    have logged it, still without an offset."""
    lines = correct.read_text(encoding="utf-8").split("\n")
    start = next(i for i, line in enumerate(lines) if line.startswith("Date/Time")) + 1
    for i in range(start, len(lines)):
        if lines[i]:
            time, rest = lines[i].split("\t", 1)
            moved = datetime.fromisoformat(time) + timedelta(hours=hours)
            lines[i] = f"{moved:%Y-%m-%dT%H:%M:%S}\t{rest}"
    local.write_text("\n".join(lines), encoding="utf-8")
    return local


@pytest.fixture(scope="module")
def voyage(tmp_path_factory) -> Path:
    """A simulated 3-h voyage (33 blocks of 20 min every 5 min: at rest, 10 kn,
    alternating 0-10 kn, 7 kn) with its log also written at UTC+02:00 without an offset."""
    root = tmp_path_factory.mktemp("local_log")
    simulate_voyage(root, seed=2, hours=3)
    _local_log(root / "dship.tsv", root / "dship_local.tsv", 2.0)
    return root


def _write(tmp_path: Path, times: list[str]) -> Path:
    path = tmp_path / "log.tsv"
    rows = [f"{t}\t10.0\t2.0\t-1.0\t7.0\t90" for t in times]
    header = "Date/Time\tSpeed [kn]\tTemp [°C]\tTTT [°C]\tff [m/s]\tRelWindDir [deg]\n"
    path.write_text(header + "\n".join(rows) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("offset", "utc"),
    [("+02:00", "12:00:00"), ("UTC-05:30", "19:30:00"), ("+0545", "08:15:00"), ("Z", "14:00:00")],
)
def test_times_without_an_offset_are_placed_at_the_given_one(tmp_path, offset, utc):
    path = _write(tmp_path, ["2024-03-01T14:00:00", "2024-03-01T14:00:01"])
    log = read_dship(path, utc_offset=offset)
    assert log["time"].tolist() == list(pd.date_range(f"2024-03-01T{utc}Z", periods=2, freq="1s"))


def test_times_carrying_an_offset_keep_it(tmp_path):
    # the file's own offset wins: the option is for times written without one
    path = _write(tmp_path, ["2024-03-01T14:00:00+01:00", "2024-03-01T14:00:01+01:00"])
    log = read_dship(path, utc_offset="+02:00")
    assert log["time"].tolist() == list(pd.date_range("2024-03-01T13:00:00Z", periods=2, freq="1s"))


def test_the_option_shifts_the_predictors_exactly(voyage):
    modal = read_modal_table(voyage / "tracked_modal.csv")
    correct = load_predictors(dship=voyage / "dship.tsv", onto=modal)
    local = voyage / "dship_local.tsv"
    placed = load_predictors(dship=local, onto=modal, dship_utc_offset="+02:00")
    pd.testing.assert_frame_equal(placed, correct)
    # read as UTC, the log starts at 02:00: blocks 0-21 (21: 01:45-02:05) have less than
    # half their 20 min in it and no value, the others the speed of two hours earlier
    shifted = load_predictors(dship=local, onto=modal)
    assert shifted["speed_kn"].isna().tolist() == [True] * 22 + [False] * 11
    assert (shifted["speed_kn"] - correct["speed_kn"]).abs().max() > 5.0


def test_fit_of_the_local_log_with_the_option_equals_that_of_the_correct_log(voyage, tmp_path):
    modal = str(voyage / "tracked_modal.csv")
    for name, extra in (
        ("correct", ["--dship", str(voyage / "dship.tsv")]),
        ("local", ["--dship", str(voyage / "dship_local.tsv"), "--dship-utc-offset", "+02:00"]),
    ):
        assert main(["fit", "--modal", modal, *extra, "--out", str(tmp_path / name)]) == 0
    for table in ("coefficients.csv", "fit_statistics.csv", "fit_summary.txt"):
        local, correct = (tmp_path / run / table for run in ("local", "correct"))
        assert local.read_bytes() == correct.read_bytes(), table


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        ("+15:00", "beyond the world's clocks"),
        ("2", "not a UTC offset"),
        ("+02:60", "minutes must be below 60"),
        ("CET", "not a UTC offset"),
    ],
)
@pytest.mark.parametrize("command", ["identify", "fit", "validate"])
def test_a_bad_offset_is_a_one_line_usage_error(voyage, tmp_path, capsys, command, value, reason):
    log = str(voyage / "dship.tsv")
    argv = {
        "identify": ["identify", str(voyage / "accelerations"), "--out", str(tmp_path / "id")],
        "fit": ["fit", "--modal", str(voyage / "tracked_modal.csv"), "--out", str(tmp_path)],
        "validate": ["validate", "dship", log],
    }[command]
    if command != "validate":
        argv += ["--dship", log]
    status = main([*argv, f"--dship-utc-offset={value}"])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2
    assert len(lines) == 1 and "--dship-utc-offset" in lines[0] and reason in lines[0], err
    assert not (tmp_path / "id").exists()


def _clock_warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if "vibration level" in line]


def test_identify_warns_on_the_local_log_and_not_on_the_correct_one(voyage, tmp_path, capsys):
    accelerations = str(voyage / "accelerations")
    store = ["--store", str(tmp_path / "store")]  # blocks identified once, marked per log
    runs = {
        "correct": ["--dship", str(voyage / "dship.tsv")],
        "local": ["--dship", str(voyage / "dship_local.tsv")],
        "placed": ["--dship", str(voyage / "dship_local.tsv"), "--dship-utc-offset", "+02:00"],
    }
    warned = {}
    for name, extra in runs.items():
        out = str(tmp_path / name)
        assert main(["identify", accelerations, "--out", out, *store, *IDENTIFY_ARGS, *extra]) == 0
        warned[name] = _clock_warnings(capsys.readouterr().err)
    assert warned["correct"] == [] and warned["placed"] == []
    (line,) = warned["local"]
    assert line.startswith(f"warning: {voyage / 'dship_local.tsv'}: ")
    assert "UTC+02:00" in line and line.endswith("give --dship-utc-offset +02:00")


def test_the_clock_check_reads_each_blocks_own_span():
    # blocks of 5, 15, 25 and 35 min every 5 min, each as loud as the log's mean speed over
    # its own span; the log (a random walk read every 10 s) ends at 03:00
    t0 = pd.Timestamp("2024-03-01T00:00:00Z")
    times = t0 + pd.to_timedelta(np.arange(0, 3 * 3600, 10), unit="s")
    seconds = (times - t0).total_seconds().to_numpy()
    speed = 8.0 + np.cumsum(np.random.default_rng(0).normal(0.0, 0.1, len(times)))
    log = pd.DataFrame({"time": times, "speed_kn": speed})
    length_s = np.resize([300.0, 900.0, 1500.0, 2100.0], 36)
    start_s = 300.0 * np.arange(36)
    spans = zip(start_s, start_s + length_s, strict=True)
    own = [speed[(seconds >= start) & (seconds < end)].mean() for start, end in spans]
    level = pd.DataFrame(
        {
            "block_start": t0 + pd.to_timedelta(start_s, unit="s"),
            "level": np.log(np.asarray(own)),
        }
    )
    scores = clock_shift_scores(level, length_s, log, shifts_h=[0.0]).iloc[0]
    # every block with half its span in the log: all but the 25-min one from 02:50 and the
    # 35-min one from 02:55, which a span of one step (5 min, as before) took as in it
    assert (start_s + length_s / 2 <= 3 * 3600).sum() == 34
    assert scores["n_blocks"] == 34
    assert scores["correlation"] == pytest.approx(1.0, abs=1e-12)
    first_steps = clock_shift_scores(level, 300.0, log, shifts_h=[0.0]).iloc[0]
    assert first_steps["n_blocks"] == 36
    assert first_steps["correlation"] == pytest.approx(0.9532, abs=1e-4)


def test_identify_auto_warns_from_each_blocks_own_span(voyage, tmp_path, capsys):
    # identify --block-minutes auto (5, 15, 25 and 35 min blocks): the level of each block
    # against the log's speed over its own span (before: its first 5 min, 0.96 here, and
    # identify stopped before the check: a length none of whose blocks the log as read
    # covers had no harmonic_checked column, the merged table NaN there)
    accelerations = str(voyage / "accelerations")
    auto = ["--block-minutes", "auto", "--store", str(tmp_path / "store")]
    warned = {}
    for name in ("dship_local", "dship"):
        out = tmp_path / name
        argv = ["identify", accelerations, "--out", str(out), *auto, *IDENTIFY_ARGS]
        assert main([*argv, "--dship", str(voyage / f"{name}.tsv")]) == 0
        warned[name] = _clock_warnings(capsys.readouterr().err)
    assert warned["dship"] == []
    (line,) = warned["dship_local"]
    assert "taken as UTC+02:00 (rank correlation 0.99, against 0.00 as read, UTC+00:00)" in line
    selected = pd.read_parquet(tmp_path / "dship_local" / "selected.parquet")
    # the log as read starts at 02:00: the 35-min blocks (00:30-01:45) are not checked
    longest = selected[selected["block_length_s"] == 2100.0]
    assert len(longest) == 8 and not longest["harmonic_checked"].any()
