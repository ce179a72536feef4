"""A channel that repeats one value for a whole file (a stuck sensor, or a recorder that
fills a dropout with zeros) is dropped from the blocks holding it, as the same dropout
written as NaN is.

Before: a file whose channel was all zeros passed the channel check (the blocks' variance
halved, kurtosis 5.6, neither out of limits), so the blocks over it were identified with
a minute of zeros in that channel, silently, while the same minute as NaN dropped the
channel ("nan fraction 50.0 % > 5 %"). Now the longest run of one repeated value counts
like a NaN run (``--max-nan-fraction``'s companion limit, 10 s): ``flat run 60.0 s``, on
both conditioning paths, and the modes equal those of the NaN-filled file.

The voyages are the small ones of :mod:`tests.robustness.voyage` (60-s files at 32 Hz,
2-minute blocks every minute): 6 files give blocks 0-4, block k holding files k and k + 1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.cli import main
from workbench.signals import faulty_channels
from workbench.signals.conditioning import constant_runs
from workbench.signals.step_sums import _block_flat_runs, _step_sums

from .voyage import IDENTIFY_ARGS, RATE_HZ, write_voyage


def _fill(path: Path, channel: int, value: float) -> None:
    """Channel *channel* of *path* set to *value* from start to end."""
    record = read_accelerations(path)
    values = record.acceleration.copy()
    values[:, channel] = value
    write_accelerations(
        AccelerationRecord(values, record.sampling_rate_hz, record.start_time, record.channels),
        path,
    )


@pytest.mark.parametrize("conditioning", ["per-file", "per-block"])
def test_a_channel_of_zeros_for_a_file_is_dropped_like_nan(tmp_path, capsys, conditioning):
    runs = {}
    for fill in ("zero", "nan"):
        paths = write_voyage(tmp_path / fill, n_files=6)
        _fill(paths[2], 1, 0.0 if fill == "zero" else np.nan)
        out = tmp_path / f"out_{fill}"
        argv = ["identify", str(tmp_path / fill), "--out", str(out), *IDENTIFY_ARGS]
        assert main([*argv, "--conditioning", conditioning]) == 0
        runs[fill] = out
    printed = capsys.readouterr().out
    assert "  note (2): channel acc02 dropped (flat run)" in printed.splitlines()
    faults = pd.read_csv(runs["zero"] / "faults.csv")
    assert faults[["block", "channel", "reason"]].values.tolist() == [
        [1, "acc02", "flat run 60.0 s"],
        [2, "acc02", "flat run 60.0 s"],
    ]
    pd.testing.assert_frame_equal(
        pd.read_parquet(runs["zero"] / "selected.parquet"),
        pd.read_parquet(runs["nan"] / "selected.parquet"),
    )


def test_a_stuck_value_at_any_level_and_a_short_one_are_told_apart():
    """Stuck at a non-zero value (a sensor's offset) for 20 s is a fault; 5 s is bridged
    like a 5-s NaN run would be; a channel constant throughout stays 'flat (variance 0)'."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal((int(120 * RATE_HZ), 4))
    x[int(10 * RATE_HZ) : int(30 * RATE_HZ), 0] = 9.81
    x[int(10 * RATE_HZ) : int(15 * RATE_HZ), 1] = 0.0
    x[:, 2] = 0.5
    reasons = faulty_channels(x, RATE_HZ)["reason"].tolist()
    assert reasons == ["flat run 20.0 s", "", "flat (variance 0)", ""]


@pytest.mark.parametrize("cuts", [(), (640,), (100, 700, 701), (1, 3000)])
def test_flat_runs_from_step_sums_equal_the_whole_block(cuts):
    """Runs joined across the pieces a block is assembled from, as on the whole block."""
    rng = np.random.default_rng(1)
    x = rng.standard_normal((3200, 5))
    x[600:1000, 0] = 0.0  # across the cuts
    x[:700, 1] = 2.0  # from the start
    x[2900:, 2] = -1.0  # to the end
    x[650:700, 3] = np.nan  # NaN never repeats
    x[100:120, 4] = 3.0
    x[121:160, 4] = 3.0  # two runs of one value split by one sample
    bounds = [0, *cuts, len(x)]
    pieces = [
        _step_sums(x[a:b], int(round(a / RATE_HZ * 1e9)), RATE_HZ)
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
    ]
    np.testing.assert_array_equal(
        _block_flat_runs(pieces, RATE_HZ) * RATE_HZ, [400, 700, 300, 1, 39]
    )
    np.testing.assert_array_equal(constant_runs(x)[2], [400, 700, 300, 1, 39])
    reasons = faulty_channels(x, RATE_HZ)["reason"].tolist()
    assert reasons[:3] == ["flat run 12.5 s", "flat run 21.9 s", ""]


def test_the_note_of_a_channel_flat_throughout_closes_its_parenthesis(tmp_path, capsys):
    """The run summary counts drops by kind, the reason without its numbers: 'flat
    (variance 0)' is 'flat (variance)', not the 'flat (variance' printed before."""
    paths = write_voyage(tmp_path / "acc", n_files=4)
    for path in paths:
        _fill(path, 1, 0.5)
    argv = ["identify", str(tmp_path / "acc"), "--out", str(tmp_path / "out"), *IDENTIFY_ARGS]
    assert main(argv) == 0
    notes = [line for line in capsys.readouterr().out.splitlines() if "note (" in line]
    assert notes == ["  note (3): channel acc02 dropped (flat (variance))"]
