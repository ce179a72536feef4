"""Timing of acceleration files: what the readers accept, refuse, and how gaps plan."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, ContractError, read_accelerations
from data_contracts.accelerations import validate_accelerations
from workbench.cli import _plain, main

from .voyage import CHANNELS, IDENTIFY_ARGS, RATE_HZ, T0, response, write_voyage


def _csv(path, times) -> None:
    frame = pd.DataFrame(response(len(times), 2), columns=list(CHANNELS))
    frame.insert(0, "time", pd.DatetimeIndex(times).strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
    frame.to_csv(path, index=False)


def test_csv_with_jitter_below_half_a_sample_reads_at_the_nominal_rate(tmp_path):
    n = 200
    jitter = np.random.default_rng(0).uniform(-0.2, 0.2, n) / RATE_HZ  # ±0.2 sample
    _csv(tmp_path / "a.csv", T0 + pd.to_timedelta(np.arange(n) / RATE_HZ + jitter, unit="s"))
    record = read_accelerations(tmp_path / "a.csv")
    assert record.sampling_rate_hz == pytest.approx(RATE_HZ, rel=1e-2)
    assert record.n_samples == n


def test_csv_rate_contradicting_the_times_is_refused(tmp_path):
    _csv(tmp_path / "a.csv", T0 + pd.to_timedelta(np.arange(100) / RATE_HZ, unit="s"))
    with pytest.raises(ContractError) as error:
        read_accelerations(tmp_path / "a.csv", csv_sampling_rate_hz=2 * RATE_HZ)
    assert "contradicts the sampling rate 64 Hz" in str(error.value)
    record = read_accelerations(tmp_path / "a.csv", csv_sampling_rate_hz=RATE_HZ)
    assert record.sampling_rate_hz == RATE_HZ


@pytest.mark.parametrize(
    ("start", "fragment"),
    [
        (1.7e9, "got the number 1700000000.0"),
        (np.float64(0.0), "got the number 0.0"),
        ("12345", "not an ISO-8601 time: '12345'"),
        ("yesterday", "not an ISO-8601 time"),
    ],
)
def test_start_time_must_be_a_time(start, fragment):
    record = AccelerationRecord(np.zeros((4, 1)), 1.0, start, ("a",))
    with pytest.raises(ContractError) as error:
        validate_accelerations(record)
    assert fragment in str(error.value) and "np.float64" not in str(error.value)


def test_iso_start_times_with_offsets_are_times():
    record = AccelerationRecord(np.zeros((4, 1)), 1.0, "2026-03-01T01:00:00+01:00", ("a",))
    assert validate_accelerations(record).start_time == pd.Timestamp("2026-03-01T00:00Z")


def test_complex_samples_are_refused_not_truncated():
    record = AccelerationRecord(np.ones((4, 1)) * (1 + 2j), 1.0, "2026-03-01", ("a",))
    with pytest.raises(ContractError, match="complex values"):
        validate_accelerations(record)


def test_block_ending_inside_an_allowed_gap_is_built(tmp_path, capsys):
    """Files 1 s short of their 60-s slot: with --max-gap 2 each 2-minute block holds a 1-s
    gap and one at its end, NaN-padded and bridged (before: skipped as "outside the span of
    the acceleration files" by the worker, although the plan listed it)."""
    write_voyage(tmp_path / "voyage", n_files=4, short_s=1.0)
    argv = ["identify", str(tmp_path / "voyage"), "--out", str(tmp_path / "out"), *IDENTIFY_ARGS]
    assert main([*argv, "--max-gap", "2"]) == 0
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks["status"].tolist() == ["ok", "ok"]
    assert "2 block(s) processed, 0 skipped" in capsys.readouterr().out
    selected = pd.read_parquet(tmp_path / "out" / "selected.parquet")
    for block in (0, 1):  # the two modes of the simulation, 3.1 and 5.7 Hz
        found = np.sort(selected.loc[selected["block"] == block, "frequency_hz"].to_numpy())
        assert found == pytest.approx([3.1, 5.7], rel=0.02)
    # without the allowance every record is shorter than a block: nothing to identify is
    # an error naming the first gap (issue 28; before: exit 0, "0 block(s) processed")
    capsys.readouterr()
    assert main([*argv[:3], str(tmp_path / "strict"), *argv[4:]]) == 1
    err = capsys.readouterr().err
    assert "1.0 s between acc_000.npz and acc_001.npz" in err
    assert "shorter than one block" in err and len(err.strip().splitlines()) == 1


def test_numpy_scalars_print_plainly():
    assert _plain("threshold=np.float64(2.0), k=np.int64(3)") == "threshold=2.0, k=3"
