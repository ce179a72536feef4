"""A drifting record's block k holds the samples recorded in its labelled UTC span.

A 6-h 5-min record of 5-min files at 64 Hz whose sample clock runs 100 ppm fast (file k stamped
k x 300 s / (1 + 1e-4) after T0); channel "utc" holds the UTC each sample was recorded at
(hundreds of seconds after T0: an accelerometer's range), the others noise. Main cuts block k on the sample count from the first
stamp: block 68 (05:40) begins with the sample recorded at 05:39:57.96 (-2.04 s, the clock's
walk 1e-4 x 20 400 s); now: within half a sample (the stamps lie on the line).
"""

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, write_accelerations
from workbench.blocks import BlockGrid
from workbench.predictors import block_predictors
from workbench.signals import ConditioningOptions, iter_blocks, plan_blocks
from workbench.signals.moments import ChannelCheckOptions

#: No channel dropped: the time channel, a ramp, is flat once detrended.
KEEP_ALL = ConditioningOptions(
    detrend=False,
    channel_check=ChannelCheckOptions(
        kurtosis_limits=(0.0, 1e9), flat_variance=-1.0, max_variance_z=1e9, max_kurtosis_z=1e9
    ),
)

RATE_HZ = 64.0
PPM = 100.0
T0 = pd.Timestamp("2026-03-01T00:00:00Z")
N_FILES = 73  # 6 h 5 min: block 68 (05:40-06:00 UTC) recorded whole by the fast clock


def _write(folder: Path) -> list[Path]:
    folder.mkdir()
    n = int(300 * RATE_HZ)
    rng = np.random.default_rng(0)
    real_rate = RATE_HZ * (1 + PPM * 1e-6)
    paths = []
    for k in range(N_FILES):
        utc = (k * n + np.arange(n)) / real_rate
        values = np.column_stack([utc / 100, rng.standard_normal((n, 2))])
        stamp = T0 + pd.Timedelta(seconds=k * n / real_rate)
        paths.append(
            write_accelerations(
                AccelerationRecord(values, RATE_HZ, stamp, ("utc", "a", "b")),
                folder / f"acc_{k:03d}.npz",
            )
        )
    return paths


def test_a_drifting_records_blocks_hold_the_samples_of_their_utc_span(tmp_path):
    files = _write(tmp_path / "acc")
    grid = BlockGrid(T0, 1200.0, 300.0)
    late = []
    for block in iter_blocks(files, grid=grid, blocks=[0, 20, 40, 68], options=KEEP_ALL):
        assert not block.skipped, block.skipped_reason
        first_utc_s = 100 * block.acceleration[0, block.channels.index("utc")]
        late.append((block.block_start - T0).total_seconds() - first_utc_s)
        assert block.acceleration.shape[0] == 1200 * RATE_HZ  # the block's fixed samples
    # main: [0.0, 0.60, 1.20, 2.04] s late; now the sample nearest the label: within half
    # a sample (7.8 ms at 64 Hz; the stamps lie on the line exactly, so its error is nil)
    np.testing.assert_allclose(late, 0.0, atol=0.5 / RATE_HZ + 1e-6)
    assert np.abs(late).max() > 1e-3  # on the sample lattice, not resampled


@pytest.mark.filterwarnings("ignore:log has no column")
def test_the_ship_log_is_averaged_over_the_minutes_the_block_was_recorded(tmp_path):
    """A 1-s speed log stepping 0 -> 10 kn at 05:40:00 UTC: the block labelled 05:40 holds
    samples recorded from 05:40:00 on, so its labelled span's mean speed (10 kn) is that of
    its samples (main: the samples begin 2.04 s earlier, at 0 kn for 2 of 1200 s)."""
    files = _write(tmp_path / "acc")
    grid = BlockGrid(T0, 1200.0, 300.0)
    (block,) = iter_blocks(files, grid=grid, blocks=[68], options=KEEP_ALL)
    utc_s = 100 * block.acceleration[:, block.channels.index("utc")]
    step_s = (block.block_start - T0).total_seconds()
    log = pd.DataFrame({"time": T0 + pd.to_timedelta(np.arange(0, 6 * 3600), unit="s")}).assign(
        speed_kn=lambda d: np.where((d.time - T0).dt.total_seconds() >= step_s, 10.0, 0.0)
    )
    labelled = block_predictors(  # the speed only: the other columns' warning unsaid
        log,
        blocks=pd.DataFrame(
            {"block": [68], "block_start": [block.block_start], "block_end": [block.block_end]}
        ),
        despike=False,
    )["speed_kn"].iloc[0]
    recorded = np.mean(np.where(np.floor(utc_s) >= step_s, 10.0, 0.0))
    assert labelled == 10.0
    assert abs(recorded - labelled) < 0.01  # main: 9.983 (2.04 s of 1200 at 0 kn)


def test_the_file_conditioner_and_load_block_cut_a_drifting_block_as_iter_blocks(tmp_path):
    """The three ways to build a block give the same samples: the plan's cut
    (``PlannedBlock.sample_start``) goes to load_block (the line of the block's own few
    files would be the record's only to its stamps' jitter), and the file conditioner builds
    a drifting record's block with it."""
    from workbench.signals import load_block
    from workbench.signals.file_conditioning import FileConditioner

    files = _write(tmp_path / "acc")
    grid = BlockGrid(T0, 1200.0, 300.0)
    options = dataclasses.replace(KEEP_ALL, target_rate_hz=16.0)
    plan = plan_blocks(files, grid)
    planned = next(b for b in plan.blocks if b.block == 40)
    # 40 x 300 s x 100 ppm / (1 + 100 ppm) after the label on the sample count, to a sample
    assert abs((planned.sample_start - planned.block_start).total_seconds() - 1.19988) < 1 / 64
    (streamed,) = iter_blocks(files, grid=grid, blocks=[40], options=options)
    loaded = load_block(plan.files, 40, grid, options=options, sample_start=planned.sample_start)
    conditioner = FileConditioner(plan.files, grid, plan.channels, options=options)
    conditioned = conditioner.block(planned)
    np.testing.assert_array_equal(loaded.acceleration, streamed.acceleration)
    np.testing.assert_array_equal(conditioned.acceleration, streamed.acceleration)


def test_a_record_without_drift_is_cut_at_its_labels(tmp_path):
    """Stamps jittered by up to 10 ms about a clock on its rate: no drift, every block cut
    at its label, as before."""
    folder = tmp_path / "acc"
    folder.mkdir()
    n = int(300 * RATE_HZ)
    rng = np.random.default_rng(1)
    files = [
        write_accelerations(
            AccelerationRecord(
                rng.standard_normal((n, 2)),
                RATE_HZ,
                T0 + pd.Timedelta(seconds=300 * k + rng.uniform(-0.01, 0.01)),
                ("a", "b"),
            ),
            folder / f"acc_{k:03d}.npz",
        )
        for k in range(24)
    ]
    plan = plan_blocks(files, BlockGrid(T0, 1200.0, 300.0))
    assert len(plan.blocks) == 21
    assert all(b.sample_start == b.block_start for b in plan.blocks)


def _write_noise(folder: Path, ppm: float, n_files: int = 25) -> list[Path]:
    """2 h 5 min of white noise in 3 channels, 5-min files at 64 Hz, the clock *ppm* fast."""
    folder.mkdir()
    n = int(300 * RATE_HZ)
    rng = np.random.default_rng(2)
    real_rate = RATE_HZ * (1 + ppm * 1e-6)
    return [
        write_accelerations(
            AccelerationRecord(
                rng.standard_normal((n, 3)),
                RATE_HZ,
                T0 + pd.Timedelta(seconds=k * n / real_rate),
                ("x", "y", "z"),
            ),
            folder / f"acc_{k:03d}.npz",
        )
        for k in range(n_files)
    ]


def test_the_file_conditioner_builds_a_drifting_records_blocks_from_the_files(tmp_path):
    """Planned on the 16-Hz analysis lattice (every 4th sample from the grid's origin) and
    the step sums split at every block's cut and end, the conditioner cuts each block of
    the fast clock's record from its files conditioned once (before: every block but the
    first by load_block from the raw files, x5 a block's time at 1024 Hz), as the per-block
    builder does within the filters' transients, the faulty-channel statistics to rounding
    (as on a record without drift: tests/signals/test_file_conditioning.py)."""
    from workbench.signals import load_block
    from workbench.signals.block_plan import plan_file_infos, read_file_info
    from workbench.signals.file_conditioning import FileConditioner, block_cuts, padding_samples

    files = _write_noise(tmp_path / "acc", PPM)
    grid = BlockGrid(T0, 1200.0, 300.0)
    options = ConditioningOptions(target_rate_hz=16.0, band_hz=(0.5, 6.0))
    plan = plan_file_infos([read_file_info(f) for f in files], grid, lattice=4)
    assert all(b.drifting for b in plan.blocks)
    conditioner = FileConditioner(
        plan.files, grid, plan.channels, options=options, cuts=block_cuts(plan.blocks)
    )
    edge = padding_samples(RATE_HZ, 16.0, options.band_hz) // 4
    late_s, worst = [], 0.0
    for planned in plan.blocks:
        # the cut on the analysis lattice: within half a 16-Hz sample of the label's UTC
        at = (planned.sample_start - T0).total_seconds() * 16.0
        assert abs(at - round(at)) < 1e-6
        late_s.append((planned.sample_start - planned.block_start).total_seconds())
        fast = conditioner.block(planned)
        slow = load_block(
            plan.files, planned.block, grid, options=options, sample_start=planned.sample_start
        )
        columns = ["nan_fraction", "longest_nan_run_s", "variance", "kurtosis", "variance_z"]
        np.testing.assert_allclose(
            fast.channel_report[columns].to_numpy(float),
            slow.channel_report[columns].to_numpy(float),
            rtol=1e-9,
            atol=1e-12,
        )
        assert fast.channels == slow.channels == ("x", "y", "z")
        assert fast.acceleration.shape == slow.acceleration.shape == (1200 * 16, 3)
        rms = slow.acceleration.std(axis=0)
        interior = np.abs(fast.acceleration - slow.acceleration)[edge:-edge] / rms
        worst = max(worst, interior.max())
    assert worst < 1e-10
    assert conditioner.fallbacks == 0  # h54's branch: all but block 0 (its cut on the label)
    # on the sample count the label's UTC lies k x 300 s x 100 ppm after it: 0.03 s a block
    expected = np.arange(len(late_s)) * 300 * PPM * 1e-6 / (1 + PPM * 1e-6)
    np.testing.assert_allclose(late_s[:-1], expected[:-1], atol=0.5 / 16.0 + 1e-6)
    # block 21's UTC span ends 0.75 s after the record's last sample: cut at it (its label
    # on the sample count, the record's last 1200 s of samples; h54's branch: not listed)
    assert len(plan.blocks) == 22 and len(set(late_s)) > 3
    assert late_s[-1] == 0.0 and plan.blocks[-1].sample_end == plan.files[-1].end_time
