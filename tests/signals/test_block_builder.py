"""Tests for the block plan and the streaming block builder (workbench.signals.block_plan,
workbench.signals.block_builder).

On the simulated 1-h demo voyage (12 five-minute files, 19 channels at 64 Hz; acc07 and
acc15 with short dropouts, acc12 dead in file 4 = 00:20-00:25, see
workbench/simulate/voyage.py) and on small hand-made files with gaps.
"""

from __future__ import annotations

import gc
import weakref
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import signal

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.blocks import BlockGrid
from workbench.signals import (
    ChannelCheckOptions,
    ConditioningOptions,
    block_builder,
    iter_blocks,
    load_block,
    plan_blocks,
)
from workbench.signals.block_plan import lacking_channels
from workbench.simulate import simulate_voyage


@pytest.fixture(scope="module")
def voyage(tmp_path_factory):
    return simulate_voyage(tmp_path_factory.mktemp("voyage"), seed=0, hours=1)


@pytest.fixture(scope="module")
def voyage_blocks(voyage):
    return list(iter_blocks(voyage.acceleration_files))


def test_plan_of_a_one_hour_voyage(voyage):
    files = voyage.acceleration_files
    assert len(files) == 12
    plan = plan_blocks(reversed(files))  # any order: sorted by start time
    assert plan.grid.t0 == voyage.start_time
    assert plan.sampling_rate_hz == 64.0 and len(plan.channels) == 19
    # (60 min - 20 min) / 5 min + 1 = 9 blocks, each from 4 five-minute files
    frame = plan.frame()
    assert frame["block"].tolist() == list(range(9))
    assert (frame["n_files"] == 4).all() and (frame["skipped_reason"] == "").all()
    assert plan.blocks[2].files == tuple(files[2:6])
    assert plan.blocks[2].block_start == voyage.start_time + pd.Timedelta(minutes=10)


def test_blocks_of_the_voyage_drop_the_dead_channel(voyage_blocks):
    assert [b.block for b in voyage_blocks] == list(range(9))
    for block in voyage_blocks:
        assert not block.skipped
        assert block.acceleration.shape == (76800, len(block.channels))
        assert np.isfinite(block.acceleration).all()  # short dropouts bridged
        assert "acc07" in block.channels and "acc15" in block.channels
        if block.block in (1, 2, 3, 4):  # the blocks containing 00:20-00:25
            assert len(block.channels) == 18 and "acc12" not in block.channels
            (channel, reason), *_ = block.dropped
            assert channel == "acc12" and "nan run 300.0 s" in reason
            assert any(n.startswith("acc12 dropped: ") for n in block.notes)
        else:
            assert len(block.channels) == 19 and block.dropped == ()
        report = block.channel_report
        assert report["faulty"].sum() == len(block.dropped)


def test_block_samples_are_the_files_samples(voyage, voyage_blocks):
    files = voyage.acceleration_files
    raw = np.concatenate([read_accelerations(f).acceleration for f in files[2:6]])
    block = voyage_blocks[2]
    assert block.files == tuple(f.name for f in files[2:6])
    column = block.channels.index("acc01")
    # detrended exactly as scipy does for a channel without NaN
    np.testing.assert_allclose(
        block.acceleration[:, column], signal.detrend(raw[:, 0]), rtol=0, atol=1e-12
    )
    plain = next(iter_blocks(files, blocks=[2], options=ConditioningOptions(detrend=False)))
    np.testing.assert_array_equal(plain.acceleration[:, column], raw[:, 0])


def test_load_block_equals_the_streamed_block(voyage, voyage_blocks):
    plan = plan_blocks(voyage.acceleration_files)
    one = load_block(plan.blocks[3].files, 3, plan.grid)
    assert one.channels == voyage_blocks[3].channels
    assert one.dropped == voyage_blocks[3].dropped
    np.testing.assert_array_equal(one.acceleration, voyage_blocks[3].acceleration)
    # a superset of files works too
    again = load_block(voyage.acceleration_files, 3, plan.grid)
    np.testing.assert_array_equal(again.acceleration, one.acceleration)


def test_selected_blocks_read_only_their_files(voyage, monkeypatch):
    reads: list[str] = []
    original = block_builder.read_accelerations

    def counting(path, **options):
        reads.append(Path(path).name)
        return original(path, **options)

    monkeypatch.setattr(block_builder, "read_accelerations", counting)
    blocks = list(iter_blocks(voyage.acceleration_files, blocks=[6, 7, 42]))
    assert [b.block for b in blocks] == [6, 7, 42]
    assert reads == [f.name for f in voyage.acceleration_files[6:11]]  # each file once
    assert blocks[2].skipped and "outside" in blocks[2].skipped_reason


def test_memory_is_bounded(voyage, monkeypatch):
    """At most length / file duration + 1 = 5 files' arrays are alive at any block."""
    arrays: list[weakref.ref] = []
    original = block_builder.read_accelerations

    def tracking(path, **options):
        record = original(path, **options)
        arrays.append(weakref.ref(record.acceleration))
        return record

    monkeypatch.setattr(block_builder, "read_accelerations", tracking)
    peak = 0
    for block in iter_blocks(voyage.acceleration_files, options=ConditioningOptions(detrend=False)):
        del block
        gc.collect()
        peak = max(peak, sum(ref() is not None for ref in arrays))
    assert 4 <= peak <= 20 // 5 + 1


def test_decimation_and_band_options(voyage):
    block = next(
        iter_blocks(
            voyage.acceleration_files,
            blocks=[0],
            options=ConditioningOptions(target_rate_hz=32.0, band_hz=(2, 12)),
        )
    )
    assert block.sampling_rate_hz == 32.0
    assert block.acceleration.shape == (38400, 19)
    # nothing left below 0.5 Hz: the mean of each channel is ~0 relative to its RMS
    rms = block.acceleration.std(axis=0)
    assert (np.abs(block.acceleration.mean(axis=0)) < 0.01 * rms).all()


# ----------------------------------------------------------------------------------------
# hand-made files
# ----------------------------------------------------------------------------------------
T0 = pd.Timestamp("2024-05-01T00:00:00Z")
RATE = 8.0
CHANNELS = ("a", "b", "c")


def _write(
    folder: Path,
    start_s: float,
    seconds: float = 60.0,
    *,
    channels=CHANNELS,
    rate=RATE,
    name: str | None = None,
    seed: int = 0,
) -> Path:
    rng = np.random.default_rng(seed + int(start_s))
    n = int(seconds * rate)
    record = AccelerationRecord(
        rng.standard_normal((n, len(channels))) * 0.01,
        rate,
        T0 + pd.Timedelta(seconds=start_s),
        tuple(channels),
    )
    path = folder / (name or f"f{int(start_s):04d}.npz")
    return write_accelerations(record, path)


@pytest.fixture
def gappy(tmp_path):
    """Files [0,60) [60,120) [120,180), gap 2 s, [182,242) [242,302), gap, [600,660)."""
    return [_write(tmp_path, s) for s in (600, 182, 0, 242, 120, 60)]  # shuffled


def test_gaps_skip_blocks_with_the_reason(gappy):
    grid = BlockGrid(T0, 120, 60)
    plan = plan_blocks(gappy, grid)
    reasons = dict(zip(plan.frame()["block"], plan.frame()["skipped_reason"], strict=True))
    assert list(reasons) == list(range(10))  # blocks inside [0, 660)
    assert reasons[0] == reasons[1] == ""
    assert reasons[2] == "gap of 2.0 s between f0120.npz and f0182.npz"
    assert reasons[3] == "gap of 2.0 s between f0120.npz and f0182.npz"
    assert reasons[4] == "gap of 58.0 s between f0242.npz and f0600.npz"  # [240,360)
    assert reasons[6].startswith("no data (gap between f0242.npz and f0600.npz")
    blocks = list(iter_blocks(gappy, grid=grid))
    assert [b.skipped for b in blocks] == [False, False] + [True] * 8
    assert blocks[2].acceleration is None and blocks[2].skipped_reason == reasons[2]


def test_an_edge_pad_within_the_clock_jitter_is_said_in_milliseconds(tmp_path):
    # a record 31.25 ms (two samples at 64 Hz) short of its only block's end: the block is
    # the record's (a record is placed to within the clock jitter), its end NaN-padded
    path = _write(tmp_path, 0.0, seconds=7678 / 64, rate=64.0)
    (block,) = iter_blocks([path], grid=BlockGrid(T0, 120, 60))
    assert not block.skipped
    assert "gap of 31 ms NaN-padded" in block.notes


def test_short_gaps_are_nan_padded_when_allowed(gappy):
    grid = BlockGrid(T0, 120, 60)
    blocks = {
        b.block: b
        for b in iter_blocks(
            gappy, grid=grid, options=ConditioningOptions(max_gap_s=5.0, detrend=False)
        )
    }
    assert not blocks[2].skipped and not blocks[3].skipped and blocks[4].skipped
    block = blocks[2]
    assert block.acceleration.shape == (960, 3)
    assert "gap of 2.0 s NaN-padded" in block.notes
    assert np.isfinite(block.acceleration).all()
    # the samples after the gap are the second file's first samples, on time
    second = read_accelerations(gappy[1]).acceleration  # f0182
    np.testing.assert_array_equal(block.acceleration[62 * 8 :], second[: 960 - 62 * 8])


def test_channel_order_is_unified(tmp_path):
    files = [
        _write(tmp_path, 0),
        _write(tmp_path, 60, channels=("c", "a", "b"), seed=5),
    ]
    block = next(
        iter_blocks(files, grid=BlockGrid(T0, 120, 60), options=ConditioningOptions(detrend=False))
    )
    assert block.channels == CHANNELS
    second = read_accelerations(files[1]).acceleration
    np.testing.assert_array_equal(block.acceleration[480:, 0], second[:, 1])  # "a"


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"channels": ("a", "d", "e")}, r"f0060\.npz: channels differ .*missing b, c; extra d, e"),
        ({"rate": 16.0}, r"f0060\.npz: sampling rate 16 Hz differs"),
    ],
)
def test_inconsistent_files_are_errors_naming_the_file(tmp_path, kwargs, match):
    files = [_write(tmp_path, 0), _write(tmp_path, 60, **kwargs)]
    with pytest.raises(ValueError, match=match):
        plan_blocks(files)
    with pytest.raises(ValueError, match=match):
        iter_blocks(files)


@pytest.mark.parametrize("lacking", [0, 1])
def test_a_file_lacking_a_channel_loses_it_only_in_its_blocks(tmp_path, lacking):
    """A recorder that drops a channel writes files without it: the channel set is the one
    most files carry (also when the first file is the one lacking it), the lacking file
    reads it as NaN and the blocks holding that file drop it as faulty; the others keep it."""
    files = [
        _write(tmp_path, 60 * k, channels=("a", "c") if k == lacking else CHANNELS)
        for k in range(4)
    ]
    plan = plan_blocks(files, BlockGrid(T0, 120, 60))
    assert plan.channels == CHANNELS
    assert lacking_channels(plan.files, plan.channels) == {("b",): [files[lacking].name]}
    blocks = list(iter_blocks(files, grid=plan.grid, options=ConditioningOptions(detrend=False)))
    holding = {b.block for b in plan.blocks if files[lacking] in b.files}
    assert holding == ({0} if lacking == 0 else {0, 1})
    for block in blocks:
        assert not block.skipped
        if block.block in holding:
            assert block.channels == ("a", "c")
            (channel, reason), *_ = block.dropped
            assert channel == "b" and "nan run 60.0 s" in reason
        else:
            assert block.channels == CHANNELS and block.dropped == ()
    # the kept channels are the files' samples
    first = read_accelerations(files[0]).acceleration
    np.testing.assert_array_equal(blocks[0].acceleration[:480, 0], first[:, 0])


def test_overlapping_files_are_an_error(tmp_path):
    files = [_write(tmp_path, 0), _write(tmp_path, 30)]
    with pytest.raises(ValueError, match=r"f0030\.npz: starts 30 s before the end of f0000"):
        plan_blocks(files)


def test_all_faulty_block_is_skipped_and_options_are_checked(tmp_path):
    files = [_write(tmp_path, 0), _write(tmp_path, 60)]
    grid = BlockGrid(T0, 120, 60)
    (block,) = iter_blocks(
        files,
        grid=grid,
        options=ConditioningOptions(channel_check=ChannelCheckOptions(kurtosis_limits=(3.5, 10.0))),
    )
    assert block.skipped and block.skipped_reason == "all channels faulty"
    assert len(block.dropped) == 3
    with pytest.raises(TypeError, match="kurtosis_limit"):
        ChannelCheckOptions(kurtosis_limit=5)
    with pytest.raises(ValueError, match="contradicts"):
        iter_blocks(files, grid=grid, length_s=600)
    with pytest.raises(ValueError, match="whole number"):
        iter_blocks(
            files, grid=grid, options=ConditioningOptions(target_rate_hz=3.0)
        )  # 8 Hz / 3 Hz
    with pytest.raises(ValueError, match="Nyquist"):
        iter_blocks(
            files, grid=grid, options=ConditioningOptions(target_rate_hz=4.0, band_hz=(0.5, 3.0))
        )


def test_planning_from_read_headers_equals_planning_from_files(voyage):
    """plan_file_infos (headers already read, as the identify planner and the monitor keep
    them) gives the plan plan_blocks gives from the files."""
    from workbench.signals import plan_file_infos, read_file_info

    files = voyage.acceleration_files
    infos = [read_file_info(f) for f in reversed(files)]
    expected = plan_blocks(files, max_gap_s=1.0).frame()
    pd.testing.assert_frame_equal(plan_file_infos(infos, max_gap_s=1.0).frame(), expected)
    with pytest.raises(ValueError, match="no acceleration files"):
        plan_file_infos([])
