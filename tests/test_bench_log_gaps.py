"""``benchmarks/bench_log_gaps.py``: where its cuts lie and which blocks it scores as the
gap's (its ``--gaps`` option places cuts away from the simulator's stop at 03:20)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_log_gaps.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_log_gaps_under_test", _PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_default_cuts_are_the_recorded_ones(bench):
    assert bench.parse_gaps("short=200-240,long=180-300") == bench.GAPS
    assert bench.parse_gaps("steady=150-190") == {"none": None, "steady": (150, 190)}


@pytest.mark.parametrize(
    "text", ["steady=190-150", "none=10-20", "steady", "=1-2", "steady=a-20", "steady=-5-20"]
)
def test_a_malformed_cut_is_refused(bench, text):
    with pytest.raises(ValueError, match="--gaps item"):
        bench.parse_gaps(text)


def test_a_malformed_cut_on_the_command_line_is_one_line_and_exit_2(bench, monkeypatch, capsys):
    monkeypatch.setattr("sys.argv", ["bench_log_gaps.py", "--gaps", "steady=a-20"])
    with pytest.raises(SystemExit) as stop:
        bench.main()
    assert stop.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert error[-1].endswith("--gaps item 'steady=a-20': NAME=START-END in minutes, START < END")
    assert not any("Traceback" in line for line in error)


def test_the_gap_blocks_are_those_more_than_half_inside_the_cut(bench):
    # 20-min blocks every 5 min: a cut of minutes 150-190 holds more than 10 min of the
    # blocks starting at minutes 145 ... 175 (7 blocks); 140 and 180 hold exactly 10
    start = pd.Timestamp("2024-03-01T00:00:00Z") + pd.to_timedelta(np.arange(60) * 5, "min")
    forecast = pd.DataFrame({"block": np.arange(60), "block_start": start.astype(str)})
    assert bench.gap_blocks(forecast, (150, 190)).tolist() == [29, 30, 31, 32, 33, 34, 35]
    assert bench.gap_blocks(forecast, None).size == 0


def test_the_edge_blocks_are_those_at_most_half_inside_the_cut(bench):
    # the blocks starting at minutes 135 and 140 (5 and 10 min inside 150-190) and 180 and
    # 185 (10 and 5 min): averaged over their logged part only
    start = pd.Timestamp("2024-03-01T00:00:00Z") + pd.to_timedelta(np.arange(60) * 5, "min")
    forecast = pd.DataFrame({"block": np.arange(60), "block_start": start.astype(str)})
    assert bench.edge_blocks(forecast, (150, 190)).tolist() == [27, 28, 36, 37]
    assert bench.edge_blocks(forecast, None).size == 0
