"""``workbench identify`` on data that does not fit the default grid or band, and on the
real recordings of ``../shared/realdata`` (skipped when absent).

Reference values of the real recordings: ``../shared/realdata/README.md`` (lab frame: mean
modal parameters of 14 records merged by pyOMA; shear frame: KOMA's model frequencies
corrected for the Newmark period elongation of the integration).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, write_accelerations
from workbench.cli import main

REALDATA = Path(__file__).resolve().parents[2] / "shared" / "realdata"
needs_realdata = pytest.mark.skipif(
    not REALDATA.is_dir(), reason="../shared/realdata is not beside the project"
)


def _record(
    folder: Path,
    minutes: float,
    start: str,
    rate: float = 64.0,
    seed: int = 0,
    name: str = "record.npz",
):
    from scipy import signal

    rng = np.random.default_rng(seed)
    n = int(round(minutes * 60 * rate))
    # one mode, 3.1 Hz, 2 % damping, under white noise; 30 % sensor noise
    radius = np.exp(-0.02 * 2 * np.pi * 3.1 / rate)
    angle = 2 * np.pi * 3.1 * np.sqrt(1 - 0.02**2) / rate
    modal = signal.lfilter(
        [1.0], [1.0, -2 * radius * np.cos(angle), radius**2], rng.standard_normal(n)
    )
    modal /= modal.std()
    x = np.outer(modal, [1.0, 0.7, -0.5]) + 0.3 * rng.standard_normal((n, 3))
    folder.mkdir(parents=True, exist_ok=True)
    record = AccelerationRecord(0.01 * x, rate, pd.Timestamp(start), ("a", "b", "c"))
    return write_accelerations(record, folder / name)


def _identify(tmp_path: Path, *args: str) -> int:
    return main(
        ["identify", str(tmp_path / "data"), "--out", str(tmp_path / "out"), "--quiet"]
        + ["--scheduler", "synchronous", "--block-rows", "6", "--max-order", "12", *args]
    )


def test_record_shorter_than_a_block_is_an_error_naming_it(tmp_path, capsys):
    _record(tmp_path / "data", 4.0, "2024-01-01T10:02:13Z")
    assert _identify(tmp_path) == 1
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1
    assert "record.npz" in error[0] and "4.00 min" in error[0] and "20 min" in error[0]
    # on request: one block of the record's length
    assert _identify(tmp_path, "--short-record", "one-block") == 0
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks["status"].tolist() == ["ok"]
    selected = pd.read_parquet(tmp_path / "out" / "selected.parquet")
    assert selected["frequency_hz"].to_numpy() == pytest.approx([3.1], rel=0.01)


def test_blocks_lie_inside_a_record_that_starts_at_an_odd_time(tmp_path):
    """21.9 min from 10:02:13: one 20-min block fits (the grid starts at the first
    sample, not at the start rounded down to the 5-min step)."""
    _record(tmp_path / "data", 21.9, "2024-01-01T10:02:13Z")
    assert _identify(tmp_path) == 0
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert blocks["status"].tolist() == ["ok"]
    assert blocks["block_start"].iloc[0].startswith("2024-01-01T10:02:13")


def test_a_short_record_beside_a_long_one_is_named(tmp_path, caplog):
    """Two records an hour apart: the 21-min one gives a block, the 4-min one is named in a
    warning (not silently left out)."""
    _record(tmp_path / "data", 21.0, "2024-01-01T10:00:00Z", name="long.npz")
    _record(tmp_path / "data", 4.0, "2024-01-01T11:30:00Z", seed=1, name="short.npz")
    with caplog.at_level("WARNING", logger="workbench"):
        assert _identify(tmp_path) == 0
    blocks = pd.read_csv(tmp_path / "out" / "blocks.csv")
    assert (blocks["status"] == "ok").sum() == 1  # blocks over the gap: skipped, with reason
    assert (blocks.loc[blocks["status"] == "skipped", "reason"].str.len() > 0).all()
    assert any(
        "short.npz" in r.getMessage() and "4.00 min" in r.getMessage() for r in caplog.records
    )


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["--block-minutes", "4"], "--block-minutes: step 5 min is longer than the block 4"),
        (["--block-minutes", "10", "--step-minutes", "12"], "--step-minutes: step 12 min"),
        (["--band", "1", "33"], "Nyquist frequency 32"),
        (["--rate", "16", "--band", "0.8", "7"], "anti-aliasing filter of the decimation"),
        (["--rate", "24"], "--rate 24 must divide"),
        (["--band", "1", "5", "--no-band"], "contradict"),
    ],
)
def test_option_conflicts_are_usage_errors(tmp_path, capsys, args, fragment):
    _record(tmp_path / "data", 21.0, "2024-01-01T10:00:00Z")
    assert _identify(tmp_path, *args) == 2
    error = capsys.readouterr().err
    assert fragment in error and "Traceback" not in error


def test_help_shows_every_default(capsys):
    assert main(["identify", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for fragment in (
        "anti-aliasing filter's edge 0.8 r/2",
        "SSI block rows (time lags of the Hankel matrix) (default: 20)",
        "block length [min] (default: 20)",
        "step between blocks [min] (default: 5)",
        "(default: 60)",
        "(default: 10.0)",
        "(default: 6.0)",
        "(default: 3.0)",
        "missing samples (default: 0.05)",
        "clustering of the poles of all orders",
    ):
        assert fragment in text, fragment


def _real(tmp_path: Path, source: str, rate: float) -> Path:
    samples = np.load(REALDATA / source)
    channels = tuple(f"ch{j}" for j in range(samples.shape[1]))
    record = AccelerationRecord(samples, rate, pd.Timestamp("2024-01-01T00:00Z"), channels)
    (tmp_path / "data").mkdir()
    return write_accelerations(record, tmp_path / "data" / "record.npz")


@needs_realdata
@pytest.mark.parametrize("record", [1, 6])
def test_lab_frame_ten_reference_modes_no_spurious(tmp_path, record):
    """Structure-level settings only (4-min record, decimation to 32 Hz): the ten
    reference modes below 13 Hz within 0.5 %, nothing else."""
    _real(tmp_path, f"lab_frame/measurement_{record}.npy", 256.0)
    code = main(
        ["identify", str(tmp_path / "data"), "--out", str(tmp_path / "out"), "--quiet"]
        + ["--scheduler", "synchronous", "--block-minutes", "4", "--step-minutes", "4"]
        + ["--rate", "32"]
    )
    assert code == 0
    selected = pd.read_parquet(tmp_path / "out" / "selected.parquet")
    reference = pd.read_csv(REALDATA / "lab_frame" / "reference_modes.csv")
    expected = reference["frequency_hz"].to_numpy()[reference["frequency_hz"] < 13.0]
    found = np.sort(selected["frequency_hz"].to_numpy())
    assert found.size == expected.size == 10
    # mean of 14 records vs one record: the records differ by up to ~0.3 %
    np.testing.assert_allclose(found, expected, rtol=0.005)
    assert (selected["frequency_std_hz"] > 0).all() and (selected["n_poles"] >= 3).all()


@needs_realdata
def test_shear_frame_five_modes_within_half_a_percent(tmp_path):
    _real(tmp_path, "shear_frame/data_shearframe.npy", 12.0)
    assert (
        main(
            ["identify", str(tmp_path / "data"), "--out", str(tmp_path / "out"), "--quiet"]
            + ["--scheduler", "synchronous"]
        )
        == 0
    )
    selected = pd.read_parquet(tmp_path / "out" / "selected.parquet")
    corrected = [0.1811, 0.5256, 0.8209, 1.0443, 1.1824]  # README: Newmark-corrected
    np.testing.assert_allclose(np.sort(selected["frequency_hz"]), corrected, rtol=0.005)
