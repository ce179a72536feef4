"""Identification of recorder-rate files: simulate --sampling-rate, default analysis rate, files
conditioned once (issue 18).

A 40-minute voyage at 256 Hz (8 five-minute files, 5 blocks) stands in for 2048-Hz
recordings (same code path, factor 4 instead of 32, fast enough for a test).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import signal

from data_contracts import read_accelerations
from workbench.cli import main
from workbench.identification import IdentifyOptions, analysis_rate, identify_voyage
from workbench.signals import decimate
from workbench.simulate import simulate_voyage

OPTIONS = IdentifyOptions(block_rows=10, orders=tuple(range(4, 41, 2)), band_hz=(2.0, 12.0))
RATE = 256.0
HOURS = 40 / 60


@pytest.fixture(scope="module")
def voyages(tmp_path_factory):
    fast = simulate_voyage(
        tmp_path_factory.mktemp("v256"), seed=3, hours=HOURS, sampling_rate_hz=RATE
    )
    slow = simulate_voyage(tmp_path_factory.mktemp("v64"), seed=3, hours=HOURS)
    return fast, slow


def test_simulated_files_have_the_rate_the_band_physics_and_a_hum_above_it(voyages):
    fast, slow = voyages
    record = read_accelerations(fast.acceleration_files[1])
    reference = read_accelerations(slow.acceleration_files[1])
    assert record.sampling_rate_hz == RATE
    assert record.n_samples == 300 * RATE
    # the 60-Hz hum is a line far above the broadband floor of the raw file
    x = np.nan_to_num(record.acceleration[:, 0])
    f, psd = signal.welch(x, fs=RATE, nperseg=4096)
    line = psd[np.argmin(np.abs(f - 60.0))]
    floor = np.median(psd[(f > 40) & (f < 55)])
    assert line > 100 * floor
    # after decimation to 64 Hz nothing folds to 4 Hz (where 60 Hz would alias)
    y = decimate(record.acceleration[:, :1], RATE, 64.0, max_nan_run_s=10)[:, 0]
    f, psd = signal.welch(np.nan_to_num(y), fs=64.0, nperseg=2048)
    near = (f > 3.8) & (f < 4.2)
    around = ((f > 3.5) & (f < 3.8)) | ((f > 4.2) & (f < 4.5))
    assert psd[near].max() < 3 * np.median(psd[around])

    # the band holding the modes carries the same power as in the 64-Hz voyage (other
    # random draws: RMS within 25 % per channel, 2-12 Hz)
    def band_rms(acceleration, rate):
        z = decimate(np.nan_to_num(acceleration), rate, 64.0) if rate > 64 else acceleration
        sos = signal.butter(4, [2.0, 12.0], "bandpass", fs=64.0, output="sos")
        return signal.sosfiltfilt(sos, np.nan_to_num(z), axis=0).std(axis=0)

    ratio = band_rms(record.acceleration, RATE) / band_rms(reference.acceleration, 64.0)
    good = [j for j, c in enumerate(record.channels) if c not in ("acc07", "acc12", "acc15")]
    assert np.all((ratio[good] > 0.75) & (ratio[good] < 1.25)), ratio


def test_default_rate_decimates_recorder_files_to_the_band(voyages):
    fast, slow = voyages
    assert analysis_rate(OPTIONS, RATE) == 64.0
    assert analysis_rate(OPTIONS, 2048.0) == 64.0
    assert analysis_rate(OPTIONS, 64.0) == 64.0
    native = IdentifyOptions(target_rate_hz=None)
    assert analysis_rate(native, 2048.0) == 2048.0
    # no band given: the band follows the rate, the rate keeps 4 x 25 Hz in reach
    defaults = IdentifyOptions()
    assert analysis_rate(defaults, 2048.0) == 128.0
    assert analysis_rate(defaults, 256.0) == 128.0
    assert analysis_rate(defaults, 64.0) == 64.0
    assert analysis_rate(defaults, 12.0) == 12.0


@pytest.fixture(scope="module")
def identified(voyages, tmp_path_factory):
    fast, _ = voyages
    runs = {}
    for mode in ("per-file", "per-block"):
        out = tmp_path_factory.mktemp(mode)
        options = IdentifyOptions(
            block_rows=OPTIONS.block_rows,
            orders=OPTIONS.orders,
            band_hz=OPTIONS.band_hz,
            conditioning=mode,
        )
        result = identify_voyage([fast.out_dir], out, options=options, scheduler="synchronous")
        runs[mode] = (out, result)
    return runs


def test_per_file_conditioning_gives_the_per_block_modes(identified):
    tables = {m: pd.read_parquet(out / "selected.parquet") for m, (out, _) in identified.items()}
    for mode, (_, result) in identified.items():
        assert result.run.processed == 5, mode
    a, b = tables["per-file"], tables["per-block"]
    assert sorted(a["block"].unique()) == sorted(b["block"].unique())
    # the same modes to the blocks' edge effects: each per-block mode has a per-file mode
    # within 0.1 % in frequency and 5 % in damping in the same block
    matched = 0
    for block, group in b.groupby("block"):
        other = a[a["block"] == block]
        for _, mode in group.iterrows():
            gap = np.abs(other["frequency_hz"].to_numpy() - mode["frequency_hz"])
            k = int(np.argmin(gap))
            if gap[k] < 1e-3 * mode["frequency_hz"]:
                damping = other["damping_ratio"].to_numpy()[k]
                assert abs(damping - mode["damping_ratio"]) <= 0.05 * mode["damping_ratio"]
                matched += 1
    assert matched >= 0.9 * len(b)
    # no mode at 4 Hz, where the 60-Hz hum would alias without the anti-alias filter
    assert not ((a["frequency_hz"] - 4.0).abs() < 0.05).any()
    faults = {m: pd.read_csv(out / "faults.csv") for m, (out, _) in identified.items()}
    pd.testing.assert_frame_equal(faults["per-file"], faults["per-block"])


def test_resume_of_runs_of_blocks_gives_the_same_tables(voyages, identified, tmp_path):
    fast, _ = voyages
    reference = pd.read_parquet(identified["per-file"][0] / "selected.parquet")
    identify_voyage(
        [fast.out_dir], tmp_path, options=OPTIONS, scheduler="synchronous", blocks=[1, 3]
    )
    result = identify_voyage([fast.out_dir], tmp_path, options=OPTIONS, scheduler="synchronous")
    assert result.run.already_done == 2
    assert result.run.processed == 3
    again = pd.read_parquet(tmp_path / "selected.parquet")
    pd.testing.assert_frame_equal(again, reference)


def test_cli_rate_arguments(tmp_path, capsys):
    assert (
        main(["simulate", "--out", str(tmp_path / "v"), "--hours", "0.5", "--sampling-rate", "100"])
        == 2
    )
    assert "sampling_rate_hz" in capsys.readouterr().err
    assert main(["identify", str(tmp_path), "--out", str(tmp_path / "o"), "--rate", "fast"]) == 2
    assert "'fast' is not a rate" in capsys.readouterr().err


def test_two_forked_workers_give_the_tables_of_one_and_of_this_process(
    voyages, identified, tmp_path
):
    """Two workers (a contiguous range of the 5 blocks each, the files at the ranges' join
    conditioned once and handed over) give exactly the tables of one worker and of the
    in-process run (issue 33)."""
    fast, _ = voyages
    reference, _ = identified["per-file"]
    tables = {}
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        result = identify_voyage([fast.out_dir], out, options=OPTIONS, n_workers=workers)
        assert result.run.processed == 5
        tables[workers] = {
            name: pd.read_parquet(out / f"{name}.parquet") for name in ("poles", "selected")
        }
    for name in ("poles", "selected"):
        expected = pd.read_parquet(reference / f"{name}.parquet")
        assert len(expected) > 0
        pd.testing.assert_frame_equal(tables[2][name], tables[1][name], check_exact=True)
        pd.testing.assert_frame_equal(tables[1][name], expected, check_exact=True)
    for name in ("faults.csv", "channels.csv", "blocks.csv"):
        assert (tmp_path / "w2" / name).read_bytes() == (reference / name).read_bytes()
