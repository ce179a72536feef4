"""Files conditioned once (workbench.signals.file_conditioning) against the per-block builder.

The reference is :func:`workbench.signals.load_block`, which conditions every block from its
raw files. The two paths must agree

* in the faulty-channel statistics (NaN fraction and runs, variance and kurtosis of the
  detrended block) up to rounding: the per-file path assembles them exactly from sums;
* in the conditioned samples of a block's interior: samples farther than
  ``padding_samples / factor`` from both block ends, where the per-block filters' start-up
  transients have decayed below ``SETTLED`` (1e-9) of their peak. Measured, the interiors
  agree to a few 1e-12 of the channel RMS (rounding): the tolerance is 1e-10;
* at file joins: the conditioned files equal filtering the whole continuous record to
  1e-8 of the RMS (overlap-and-discard with the same padding).
"""

from __future__ import annotations

import collections
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from data_contracts import AccelerationRecord, read_accelerations, write_accelerations
from workbench.signals import ConditioningOptions, bandpass, decimate, load_block, plan_blocks
from workbench.signals.block_plan import read_file_info
from workbench.signals.file_conditioning import FileConditioner
from workbench.signals.file_reads import _edge_rows, _read_rows
from workbench.signals.filter_cascade import (
    _decimate_channels_last,
    default_decimation_rate,
    padding_samples,
)

RATE = 512.0
TARGET = 64.0
BAND = (2.0, 12.0)
FILE_S = 30
N_FILES = 6
CHANNELS = tuple(f"acc{j:02d}" for j in range(5))
T0 = pd.Timestamp("2024-01-01T00:00:00Z")


def _record(rng, n):
    """Broadband noise, a 5 Hz resonance, a drift and gravity-like offsets."""
    t = np.arange(n) / RATE
    x = rng.standard_normal((n, len(CHANNELS)))
    x += np.sin(2 * np.pi * 5.0 * t)[:, None] * np.linspace(1, 2, len(CHANNELS))
    x += 0.002 * rng.standard_normal((n, len(CHANNELS))).cumsum(axis=0)
    x += np.array([9.81, 0.0, -3.0, 0.5, 0.0])
    return x


@pytest.fixture(scope="module")
def voyage(tmp_path_factory):
    folder = tmp_path_factory.mktemp("files")
    rng = np.random.default_rng(7)
    n_file = int(FILE_S * RATE)
    full = _record(rng, n_file * N_FILES)
    # a 3-s NaN run across the join of files 1 and 2, a 15-s run (too long to bridge) in
    # file 4, a short one inside file 0
    join = 2 * n_file
    full[join - int(1.5 * RATE) : join + int(1.5 * RATE), 1] = np.nan
    full[4 * n_file + 1000 : 4 * n_file + 1000 + int(15 * RATE), 3] = np.nan
    full[2000:2100, 4] = np.nan
    paths = []
    for k in range(N_FILES):
        path = folder / f"acc_{k}.npz"
        part = full[k * n_file : (k + 1) * n_file]
        start = T0 + pd.Timedelta(seconds=k * FILE_S)
        write_accelerations(AccelerationRecord(part, RATE, start, CHANNELS), path)
        paths.append(path)
    plan = plan_blocks(paths, length_s=4 * FILE_S, step_s=FILE_S)
    return full, paths, plan


def test_default_rate_rule():
    assert default_decimation_rate(2048.0, (2.0, 12.0)) == 64.0
    assert default_decimation_rate(1000.0, (2.0, 12.0)) == 62.5
    assert default_decimation_rate(200.0, (2.0, 12.0)) == 50.0
    assert default_decimation_rate(64.0, (2.0, 12.0)) == 64.0
    assert default_decimation_rate(2048.0, (1.0, 30.0)) == 128.0
    assert default_decimation_rate(2048.0, None) == 2048.0
    assert default_decimation_rate(2048.0, (5.0, None)) == 2048.0
    with pytest.raises(ValueError, match="sampling_rate_hz"):
        default_decimation_rate(0.0, BAND)


def test_decimation_along_channels_is_bit_equal_to_decimate():
    x = np.random.default_rng(1).standard_normal((8000, 3))
    fast = _decimate_channels_last(np.ascontiguousarray(x.T), 32).T
    np.testing.assert_array_equal(fast, decimate(x, 2048.0, 64.0))


def test_partial_read_equals_the_rows_of_the_whole_file(voyage):
    _, paths, plan = voyage
    info = plan.files[2]
    whole = read_accelerations(paths[2]).acceleration
    rows = _read_rows(info, CHANNELS, 100, 900)
    np.testing.assert_array_equal(rows, whole[100:900])
    reordered = _read_rows(info, CHANNELS[::-1], 0, 10)
    np.testing.assert_array_equal(reordered, whole[:10, ::-1])


def test_a_neighbours_edge_obeys_the_readers_glitch_rule(tmp_path):
    """The rows a file lends its neighbour's filters are read in place, yet obey the rule
    the reader applies to the whole file: with ``glitches="blank"`` a channel holding an
    infinite value (or |a| > 500 m/s²) there is NaN in them, the other channels untouched;
    rows where every channel does (wrong units: the file is refused) are not lent at all.
    Main returned them raw (inf, and 2e5 m/s² samples)."""
    n = int(FILE_S * RATE)
    x = _record(np.random.default_rng(3), n)
    path = write_accelerations(AccelerationRecord(x, RATE, T0, CHANNELS), tmp_path / "a.npz")
    x[-10, 2] = np.inf
    np.savez(path, **{**dict(np.load(path)), "acceleration": x})  # the writer refuses inf
    info = read_file_info(path)
    blank = {"glitches": "blank"}
    rows = _edge_rows(info, CHANNELS, n - 100, None, blank)
    assert np.isnan(rows[:, 2]).all()
    np.testing.assert_array_equal(rows[:, [0, 1, 3, 4]], x[n - 100 :, [0, 1, 3, 4]])
    # rows without the glitch as they are
    np.testing.assert_array_equal(_edge_rows(info, CHANNELS, 0, 100, blank), x[:100])
    x[-10, 2] = 1.0
    np.savez(path, **{**dict(np.load(path)), "acceleration": x * 2e4})  # mm/s²-like
    assert _edge_rows(info, CHANNELS, n - 100, None, blank) is None


def test_blocks_equal_the_per_block_builder_within_the_filter_transients(voyage):
    _, paths, plan = voyage
    conditioner = FileConditioner(
        plan.files,
        plan.grid,
        plan.channels,
        options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND),
    )
    edge = padding_samples(RATE, TARGET, BAND) // int(RATE / TARGET)
    n_out = int(4 * FILE_S * TARGET)
    assert 0 < 2 * edge < n_out  # the blocks have an interior to compare
    built = 0
    for planned in plan.blocks:
        fast = conditioner.block(planned)
        slow = load_block(
            paths,
            planned.block,
            plan.grid,
            options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND),
        )
        columns = ["nan_fraction", "longest_nan_run_s", "variance", "kurtosis", "variance_z"]
        np.testing.assert_allclose(
            fast.channel_report[columns].to_numpy(float),
            slow.channel_report[columns].to_numpy(float),
            rtol=1e-9,
            atol=1e-12,
        )
        assert fast.dropped == slow.dropped
        assert fast.channels == slow.channels
        assert fast.sampling_rate_hz == slow.sampling_rate_hz == TARGET
        assert fast.acceleration.shape == slow.acceleration.shape
        rms = slow.acceleration.std(axis=0)
        interior = np.abs(fast.acceleration - slow.acceleration)[edge:-edge] / rms
        # measured (issue 33): at most 4.8e-12 here, 1.6e-12 on the 1-h 2048-Hz benchmark
        # voyage (benchmarks/results/throughput_33_identify.txt): rounding, not transients
        assert interior.max() < 1e-10
        # the per-block filters' start-up transients at the block ends are not small
        assert np.abs(fast.acceleration - slow.acceleration).max() / rms.max() > 1e-3
        built += 1
    assert conditioner.fallbacks == 0
    assert built == len(plan.blocks) == 3
    # the 15-s NaN run makes acc03 faulty in the blocks holding file 4 (blocks 1 and 2)
    assert "acc03" not in conditioner.block(plan.blocks[2]).channels


def test_file_joins_equal_filtering_the_whole_record(voyage):
    full, _, plan = voyage
    conditioner = FileConditioner(
        plan.files,
        plan.grid,
        plan.channels,
        options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND),
    )
    clean = [0, 2, 4]  # channels without NaN runs longer than can be bridged
    whole = bandpass(decimate(full[:, clean], RATE, TARGET), TARGET, *BAND)
    joined = np.concatenate([conditioner._conditioned(k).samples for k in range(N_FILES)])
    assert joined.shape == (whole.shape[0], len(CHANNELS))
    error = np.abs(joined[:, clean] - whole) / whole.std(axis=0)
    assert error.max() < 1e-8


def test_blocks_with_a_padded_gap_fall_back_to_the_per_block_builder(tmp_path):
    rng = np.random.default_rng(3)
    n_file = int(FILE_S * RATE)
    paths = []
    for k in range(5):
        start = T0 + pd.Timedelta(seconds=k * FILE_S + (2.0 if k >= 2 else 0.0))
        path = tmp_path / f"acc_{k}.npz"
        write_accelerations(AccelerationRecord(_record(rng, n_file), RATE, start, CHANNELS), path)
        paths.append(path)
    plan = plan_blocks(paths, length_s=4 * FILE_S, step_s=FILE_S, max_gap_s=3.0)
    conditioner = FileConditioner(
        plan.files,
        plan.grid,
        plan.channels,
        options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND, max_gap_s=3.0),
    )
    planned = plan.blocks[0]
    fast = conditioner.block(planned)
    slow = load_block(
        paths,
        planned.block,
        plan.grid,
        options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND, max_gap_s=3.0),
    )
    assert conditioner.fallbacks == 1
    np.testing.assert_array_equal(fast.acceleration, slow.acceleration)


def test_conditioner_rejects_a_rate_that_is_not_a_decimation(voyage):
    _, _, plan = voyage
    with pytest.raises(ValueError, match="target_rate_hz"):
        FileConditioner(
            plan.files,
            plan.grid,
            plan.channels,
            options=ConditioningOptions(target_rate_hz=300.0, band_hz=BAND),
        )
    with pytest.raises(ValueError, match="target_rate_hz"):
        FileConditioner(
            plan.files,
            plan.grid,
            plan.channels,
            options=ConditioningOptions(target_rate_hz=RATE, band_hz=BAND),
        )


def test_an_unreadable_neighbour_breaks_the_chain_only(voyage, tmp_path):
    _, paths, _ = voyage
    copies = []
    for path in paths:
        copy = tmp_path / path.name
        copy.write_bytes(path.read_bytes())
        copies.append(copy)
    plan = plan_blocks(copies, length_s=4 * FILE_S, step_s=FILE_S)
    copies[4].write_bytes(b"not an npz file")  # after planning: the file went bad
    conditioner = FileConditioner(
        plan.files,
        plan.grid,
        plan.channels,
        options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND),
    )
    first = conditioner.block(plan.blocks[0])  # files 0-3; file 4 only pads file 3
    assert first.acceleration is not None and conditioner.fallbacks == 0
    with pytest.raises(ValueError, match="acc_4"):
        conditioner.block(plan.blocks[1])


def test_text_files_are_parsed_once_and_give_the_npz_blocks(voyage, tmp_path, monkeypatch):
    """CSV files (read whole, no partial reads): conditioning a file needs its neighbours'
    edges, yet each file is parsed once when the files are conditioned in order, and the
    blocks equal those of the same samples in ``.npz`` files."""
    from workbench.signals import file_reads

    full, _, plan = voyage
    n_file = int(FILE_S * RATE)
    paths = []
    for k in range(N_FILES):
        part = pd.DataFrame(full[k * n_file : (k + 1) * n_file], columns=list(CHANNELS))
        times = (
            T0
            + pd.Timedelta(seconds=k * FILE_S)
            + pd.to_timedelta(np.arange(n_file) / RATE, unit="s")
        )
        part.insert(0, "time", times.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
        paths.append(tmp_path / f"acc_{k}.csv")
        part.to_csv(paths[-1], index=False, float_format="%.17g")
    options = {"csv_sampling_rate_hz": RATE}  # the times are rounded to microseconds
    text_plan = plan_blocks(paths, length_s=4 * FILE_S, step_s=FILE_S, read_options=options)
    parsed = []

    def counting(path, **options):
        parsed.append(Path(path).name)
        return read_accelerations(path, **options)

    monkeypatch.setattr(file_reads, "read_accelerations", counting)
    monkeypatch.setattr(file_reads, "_whole_reads", collections.OrderedDict())
    text = FileConditioner(
        text_plan.files,
        text_plan.grid,
        text_plan.channels,
        options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND, read_options=options),
    )
    binary = FileConditioner(
        plan.files,
        plan.grid,
        plan.channels,
        options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND),
    )
    for planned_text, planned in zip(text_plan.blocks, plan.blocks, strict=True):
        a, b = text.block(planned_text), binary.block(planned)
        assert a.channels == b.channels
        np.testing.assert_array_equal(a.acceleration, b.acceleration)
    assert text.fallbacks == 0
    csv = sorted(name for name in parsed if name.endswith(".csv"))
    assert csv == sorted(p.name for p in paths)  # each CSV parsed once


def _conditioned_reference(conditioner, index, raw_padded, origin, start, n):
    """File *index* conditioned the straightforward way (issue 18's code): the padded record
    copied whole, every channel with a NaN bridged, ``decimate`` and ``bandpass`` of the
    whole array, channels left with NaN set NaN."""
    from workbench.signals.conditioning import interpolate_nan_runs

    f = conditioner.factor
    lead = (-origin) % f
    x = raw_padded[lead:].copy()
    holes = np.flatnonzero(np.isnan(x).any(axis=0))
    bad = np.zeros(x.shape[1], dtype=bool)
    if holes.size:
        bridged = interpolate_nan_runs(x[:, holes], RATE, max_run_s=conditioner.max_nan_run_s)
        bad[holes] = np.isnan(bridged).any(axis=0)
        x[:, holes] = np.where(np.isnan(bridged), 0.0, bridged)
    y = bandpass(decimate(x, RATE, TARGET), TARGET, *BAND)
    first_out = -(-start // f)
    skip = first_out - (origin + lead) // f
    samples = y[skip : skip + (-(-(start + n) // f) - first_out)].copy()
    samples[:, bad] = np.nan
    return samples


def test_conditioned_files_equal_decimating_the_padded_file_whole_to_the_last_bit(voyage):
    """The per-channel pipeline (buffers reused, filters in place, unbridgeable channels
    not filtered) gives the very numbers of conditioning the padded file as one array."""
    full, _, plan = voyage
    conditioner = FileConditioner(
        plan.files,
        plan.grid,
        plan.channels,
        options=ConditioningOptions(target_rate_hz=TARGET, band_hz=BAND),
    )
    n_file = int(FILE_S * RATE)
    pad = conditioner.padding
    for index in range(N_FILES):
        start = index * n_file  # the grid starts with the first file
        lo = max(start - pad, 0)  # padding from the neighbours (none before file 0)
        hi = min(start + n_file + pad + conditioner.factor, full.shape[0])
        expected = _conditioned_reference(conditioner, index, full[lo:hi], lo, start, n_file)
        got = conditioner._conditioned(index).samples
        np.testing.assert_array_equal(got, expected)
    # file 4 holds the 15-s run of acc03: NaN throughout; the short runs were bridged
    assert np.isnan(conditioner._conditioned(4).samples[:, 3]).all()
    assert not np.isnan(conditioner._conditioned(2).samples[:, [0, 1, 2, 4]]).any()
