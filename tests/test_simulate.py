"""Tests for the demo voyage simulator (workbench.simulate)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy import signal

from data_contracts import (
    MODAL,
    POLES,
    PREDICTORS,
    read_accelerations,
    read_dship,
    read_table,
)
from workbench.simulate import (
    CHANNELS,
    MODE_LAWS,
    ShaftHarmonics,
    mode_shapes,
    operating_profile,
    simulate_voyage,
    true_modal_parameters,
)
from workbench.simulate.imitation import (
    DAMPING_SCATTER,
    FREQUENCY_SCATTER,
    MISSING_FRACTION,
    ORDERS,
)

SEED = 3
TABLE_FILES = (
    "dship.tsv",
    "truth_predictors.csv",
    "truth_modal.csv",
    "tracked_modal.csv",
    "poles.parquet",
    "cases.csv",
    "voyage.json",
)


@pytest.fixture(scope="module")
def voyage(tmp_path_factory):
    """Default 12-h voyage without accelerations (under 1 s)."""
    return simulate_voyage(tmp_path_factory.mktemp("voyage"), seed=SEED, accelerations=False)


@pytest.fixture(scope="module")
def short_voyage(tmp_path_factory):
    """1-h voyage with accelerations; records progress calls."""
    calls = []
    summary = simulate_voyage(
        tmp_path_factory.mktemp("short"),
        seed=SEED,
        hours=1,
        progress=lambda done, total: calls.append((done, total)),
    )
    return summary, calls


def _profile(summary):
    """The true 1-s predictors, rebuilt from the seed's first stream (the profile stream)."""
    rng = np.random.default_rng(np.random.SeedSequence(summary.seed).spawn(6)[0])
    return operating_profile(summary.start_time, summary.hours, rng=rng)


def _pivot(frame, column):
    return frame.pivot(index="block", columns="mode", values=column).to_numpy()


# --------------------------------------------------------------------------- determinism
def test_same_seed_gives_identical_files_and_other_seed_differs(voyage, tmp_path):
    again = simulate_voyage(tmp_path / "again", seed=SEED, accelerations=False)
    other = simulate_voyage(tmp_path / "other", seed=SEED + 1, accelerations=False)
    for name in TABLE_FILES:
        assert (again.out_dir / name).read_bytes() == (voyage.out_dir / name).read_bytes(), name
    for name in ("dship.tsv", "truth_modal.csv", "tracked_modal.csv", "poles.parquet"):
        assert (other.out_dir / name).read_bytes() != (voyage.out_dir / name).read_bytes(), name


def test_accelerations_are_deterministic_and_do_not_change_tables(short_voyage, tmp_path):
    summary, _ = short_voyage
    again = simulate_voyage(tmp_path / "again", seed=SEED, hours=1)
    for a, b in zip(summary.acceleration_files, again.acceleration_files, strict=True):
        assert a.read_bytes() == b.read_bytes()
    tables_only = simulate_voyage(tmp_path / "tables", seed=SEED, hours=1, accelerations=False)
    for name in TABLE_FILES[:-1]:
        assert (tables_only.out_dir / name).read_bytes() == (summary.out_dir / name).read_bytes()


# --------------------------------------------------------------------------- the law
def test_truth_is_the_block_mean_of_the_law_at_one_second(voyage):
    # Average the law over each block of the true 1-s predictors: exact up to rounding.
    profile = _profile(voyage)
    frequency, damping = true_modal_parameters(profile.predictors)
    truth = read_table(voyage.truth_modal, MODAL)
    blocks = np.arange(voyage.n_blocks)
    expected_f = np.array([frequency[300 * b : 300 * b + 1200].mean(0) for b in blocks])
    expected_z = np.array([damping[300 * b : 300 * b + 1200].mean(0) for b in blocks])
    np.testing.assert_allclose(_pivot(truth, "frequency_hz"), expected_f, rtol=1e-12)
    np.testing.assert_allclose(_pivot(truth, "damping_ratio"), expected_z, rtol=1e-12)


def test_truth_follows_law_of_block_averaged_predictors(voyage):
    # The law is nonlinear (sqrt, speed x water), so law(mean predictors) differs from the
    # mean of the law only at second order: below 0.1 %, well under the 0.2-0.5 % scatter.
    predictors = read_table(voyage.truth_predictors, PREDICTORS)
    truth = read_table(voyage.truth_modal, MODAL)
    frequency, damping = true_modal_parameters(predictors)
    np.testing.assert_allclose(_pivot(truth, "frequency_hz"), frequency, rtol=1e-3)
    # damping is linear in speed: exact
    np.testing.assert_allclose(_pivot(truth, "damping_ratio"), damping, rtol=1e-12)


def test_truth_ranges(voyage):
    truth = read_table(voyage.truth_modal, MODAL)
    assert truth["frequency_hz"].between(2.0, 10.0).all()
    assert truth["damping_ratio"].between(0.004, 0.03).all()
    assert sorted(truth["mode"].unique()) == list(range(1, 8))
    assert len(truth) == 7 * voyage.n_blocks == 7 * (12 * 12 - 3)


def test_law_sensitivities_as_documented():
    base = {"speed_kn": 0.0, "water_temp_c": 2.0, "air_temp_c": -2.0, "elapsed_hours": 0.0}
    reference = true_modal_parameters(base)
    np.testing.assert_allclose(reference.frequency_hz[0], [m.frequency_hz for m in MODE_LAWS])
    fast = true_modal_parameters({**base, "speed_kn": 10.0})
    speed_effect = fast.frequency_hz[0] / reference.frequency_hz[0] - 1
    assert np.all(speed_effect < 0) and np.all(speed_effect > -0.03)
    assert abs(speed_effect[3]) < 0.002  # mode 4 nearly insensitive to speed
    assert np.sum(speed_effect < -0.01) >= 5
    assert np.all(fast.damping_ratio > reference.damping_ratio)
    warm = true_modal_parameters({**base, "water_temp_c": 5.0})
    water_effect = warm.frequency_hz[0] / reference.frequency_hz[0] - 1
    assert np.all(water_effect < 0) and np.all(water_effect > -0.01)
    assert abs(water_effect[4]) < 0.001  # mode 5 nearly insensitive to water
    # interaction: the water effect at 10 kn differs from that at rest for modes 2, 5, 7
    fast_warm = true_modal_parameters({**base, "speed_kn": 10.0, "water_temp_c": 5.0})
    interaction = fast_warm.frequency_hz[0] / fast.frequency_hz[0] - 1 - water_effect
    assert np.all(np.abs(interaction[[1, 4, 6]]) > 0.002)
    assert np.all(np.abs(interaction[[0, 2, 3, 5]]) < 1e-4)
    # fuel burn: 12 h raise every frequency by 0.3-0.7 %
    later = true_modal_parameters(base, elapsed_hours=12.0)
    fuel_effect = later.frequency_hz[0] / reference.frequency_hz[0] - 1
    assert np.all((fuel_effect > 0.003) & (fuel_effect < 0.007))
    # the burn slows as the tanks empty: a 51-day voyage keeps a positive mass and the
    # frequencies rise by less than 15 %
    long = true_modal_parameters(base, elapsed_hours=51 * 24.0)
    rise = long.frequency_hz[0] / reference.frequency_hz[0] - 1
    assert np.all(np.isfinite(rise)) and np.all((rise > 0.05) & (rise < 0.15))


def test_law_rejects_missing_predictor():
    with pytest.raises(ValueError, match="water_temp_c") as error:
        true_modal_parameters({"speed_kn": [1.0], "air_temp_c": [0.0]}, elapsed_hours=0.0)
    assert "no entry" in str(error.value)


def test_mode_shapes_are_distinct_unit_vectors():
    shapes = mode_shapes()
    assert shapes.shape == (7, 19)
    np.testing.assert_allclose(np.linalg.norm(shapes, axis=1), 1.0)
    mac = (shapes @ shapes.T) ** 2
    off_diagonal = mac[~np.eye(7, dtype=bool)]
    assert off_diagonal.max() < 0.8
    assert mac[2, 3] < 0.2  # 5.2 Hz (VB2) vs 5.4 Hz (T1) distinguishable by shape
    assert np.all(shapes[np.arange(7), np.abs(shapes).argmax(axis=1)] > 0)


# --------------------------------------------------------------------------- imitated SSI
def test_tracked_table_scatter_missing_and_mislabels(voyage):
    truth = read_table(voyage.truth_modal, MODAL)
    tracked = read_table(voyage.tracked_modal, MODAL)
    summary = json.loads(voyage.summary_json.read_text())
    mislabelled = set(summary["defects"]["mislabelled_blocks"])
    assert len(mislabelled) >= 1
    low_mac = tracked[tracked["mac"] < 0.5]
    assert set(low_mac["block"]) == mislabelled
    assert set(low_mac["mode"]) == {3, 4}
    merged = tracked[~tracked["block"].isin(mislabelled)].merge(
        truth[["block", "mode", "frequency_hz", "damping_ratio"]],
        on=["block", "mode"],
        suffixes=("", "_true"),
    )
    # ~120 rows per mode: a sample std has relative std 1/sqrt(2n) ≈ 6.5 %; allow 25 %.
    for mode, rows in merged.groupby("mode"):
        relative = rows["frequency_hz"] / rows["frequency_hz_true"] - 1
        assert np.std(relative) == pytest.approx(FREQUENCY_SCATTER[mode - 1], rel=0.25)
    log_damping = np.log(merged["damping_ratio"] / merged["damping_ratio_true"])
    assert np.std(log_damping) == pytest.approx(DAMPING_SCATTER, rel=0.15)
    # missing: 10 % at random (binomial std ≈ 1 % of ~930 pairs) plus the weak-mode stretch
    first, last = summary["defects"]["weak_mode_blocks"]
    weak = tracked[(tracked["mode"] == 4) & tracked["block"].between(first, last)]
    assert weak.empty and last - first >= 10
    outside = (voyage.n_blocks - (last - first + 1)) + 6 * voyage.n_blocks
    n_outside = len(tracked[~((tracked["mode"] == 4) & tracked["block"].between(first, last))])
    assert 1 - n_outside / outside == pytest.approx(MISSING_FRACTION, abs=0.035)
    assert tracked["model_order"].notna().all()
    assert tracked["mac"][~tracked["block"].isin(mislabelled)].min() > 0.85


def test_poles_contain_tracked_values_and_truth_at_top_orders(voyage):
    poles = read_table(voyage.poles, POLES)
    tracked = read_table(voyage.tracked_modal, MODAL)
    truth = read_table(voyage.truth_modal, MODAL)
    assert set(poles["model_order"]) == set(ORDERS)
    # the pole at the tracked model order is the tracked row
    keyed = poles.set_index(["block", "model_order", "frequency_hz"])
    for row in tracked.sample(50, random_state=0).itertuples():
        assert (row.block, row.model_order, row.frequency_hz) in keyed.index
    # every true mode present in the tracked table has a stable pole within 4 scatter
    # std (≤ 2 %) of the truth at every order >= 50
    top = poles[(poles["model_order"] >= 50) & poles["stable"]]
    present = tracked[["block", "mode"]].drop_duplicates()
    checked = truth.merge(present, on=["block", "mode"])
    for row in checked.sample(200, random_state=1).itertuples():
        candidates = top[top["block"] == row.block]
        for order in (50, 60):
            at = candidates[candidates["model_order"] == order]["frequency_hz"].to_numpy()
            tolerance = 4 * FREQUENCY_SCATTER[row.mode - 1] * row.frequency_hz
            assert np.min(np.abs(at - row.frequency_hz)) < tolerance
    # spurious poles (outside 2-10 Hz) are almost never stable
    outside = poles[~poles["frequency_hz"].between(1.5, 10.5)]
    assert outside["stable"].mean() < 0.05
    assert poles["mpc"].between(0, 1 + 1e-9).all()


# --------------------------------------------------------------------------- other files
def test_predictors_cases_and_summary(voyage):
    predictors = read_table(voyage.truth_predictors, PREDICTORS)
    assert len(predictors) == voyage.n_blocks
    assert predictors["speed_kn"].between(0, 11.5).all()
    assert predictors["speed_kn"].max() > 9 and predictors["speed_kn"].min() < 0.5
    assert predictors["water_temp_c"].max() - predictors["water_temp_c"].min() > 2.5
    steps = predictors["block_start"].diff().dropna().unique()
    assert list(steps) == [pd.Timedelta(minutes=5)]
    assert (predictors["block_end"] - predictors["block_start"] == pd.Timedelta(minutes=20)).all()
    cases = pd.read_csv(voyage.cases)
    assert list(cases.columns) == ["case", "start", "end"]
    assert list(cases["case"]) == [
        "stationary",
        "constant_speed",
        "alternating",
        "temperature_drift",
    ]
    hours = (pd.to_datetime(cases["end"]) - pd.to_datetime(cases["start"])).dt.total_seconds()
    assert list(hours / 3600) == [2, 3, 4, 3]
    summary = json.loads(voyage.summary_json.read_text())
    assert summary["seed"] == SEED and summary["hours"] == 12
    assert len(summary["law"]["modes"]) == 7


def test_longer_voyage_repeats_the_profile(tmp_path):
    profile = operating_profile(
        pd.Timestamp("2024-01-01", tz="UTC"), 30, rng=np.random.default_rng(0)
    )
    assert len(profile.cases) == 12
    assert (profile.cases["end"].iloc[-1] - profile.cases["start"].iloc[0]) == pd.Timedelta(
        hours=30
    )
    assert (
        profile.cases["start"].iloc[1:].to_numpy() == profile.cases["end"].iloc[:-1].to_numpy()
    ).all()


def test_dship_log_layout_rates_gaps_and_spikes(voyage):
    text = voyage.dship_log.read_text(encoding="utf-8")
    assert text.startswith("/* DATA DESCRIPTION:")
    header = text.split("*/\n", 1)[1].splitlines()[0]
    assert header.split("\t") == [
        "Date/Time",
        "Latitude",
        "Longitude",
        "Speed [kn]",
        "Temp [°C]",
        "TTT [°C]",
        "ff [m/s]",
        "RelWindDir [deg]",
        "Shaft speed [rpm]",
    ]
    log = read_dship(voyage.dship_log)
    seconds = log["time"].dt.second
    assert log["water_temp_c"].notna().sum() > 0
    assert (seconds[log["water_temp_c"].notna()] == 0).all()  # 60 s rate
    assert (seconds[log["wind_speed_ms"].notna()] % 10 == 0).all()  # 10 s rate
    assert log["speed_kn"].notna().mean() > 0.99  # 1 s rate
    assert log["time"].diff().max() == pd.Timedelta(minutes=10, seconds=1)  # missing rows
    summary = json.loads(voyage.summary_json.read_text())
    defects = summary["defects"]
    start, end = (pd.Timestamp(t) for t in defects["water_temp_missing"])
    assert log["water_temp_c"][log["time"].between(start, end, inclusive="left")].isna().all()
    # faulty air sensor: spikes of 20-35 °C away from the true (profile) values
    truth = _profile(voyage).predictors.set_index("time")["air_temp_c"]
    air = log.set_index("time")["air_temp_c"].dropna()
    deviation = np.abs(air - truth.reindex(air.index))
    assert int((deviation > 15).sum()) == defects["air_temp_spikes"] >= 5
    assert deviation[deviation < 15].std() < 0.2  # sensor noise 0.1 °C + rounding
    # the shaft speed: 60 x 0.3 Hz/kn x the true speed, noise 0.2 rpm + 0.05 rpm rounding
    assert summary["shaft"]["rpm_per_kn"] == pytest.approx(18.0)
    speed = _profile(voyage).predictors.set_index("time")["speed_kn"]
    rpm = log.set_index("time")["shaft_rpm"]
    error = rpm - 18.0 * speed.reindex(rpm.index)
    assert abs(error.mean()) < 0.02 and 0.18 < error.std() < 0.23


def test_shaft_speed_left_out_of_the_log(tmp_path):
    summary = simulate_voyage(
        tmp_path, hours=0.5, accelerations=False, shaft=ShaftHarmonics(log_rpm=False)
    )
    header = summary.dship_log.read_text(encoding="utf-8").split("*/\n", 1)[1].splitlines()[0]
    assert "Shaft speed [rpm]" not in header
    assert "shaft_rpm" not in read_dship(summary.dship_log).columns


def test_shaft_harmonics_options_are_checked():
    with pytest.raises(ValueError, match="orders") as error:
        ShaftHarmonics(orders=(0, 1))
    assert "at least 1" in str(error.value)
    assert ShaftHarmonics(orders=(1, 2), blades=4).components() == [
        (1.0, 0.008),
        (2.0, 0.008),
        (4.0, 0.004),
    ]


# the dead channel is all-NaN on purpose; the contract validator's nanmax warns about it
@pytest.mark.filterwarnings("ignore:All-NaN slice:RuntimeWarning")
def test_acceleration_files(short_voyage):
    summary, calls = short_voyage
    files = summary.acceleration_files
    assert len(files) == 12
    assert calls == [(k, 12) for k in range(1, 13)]
    assert files[1].name == "acc_20240301T000500Z.npz"
    records = [read_accelerations(f) for f in files]
    for k, record in enumerate(records):
        assert record.acceleration.shape == (19200, 19)
        assert record.sampling_rate_hz == 64.0
        assert record.channels == CHANNELS
        assert record.start_time == summary.start_time + pd.Timedelta(minutes=5 * k)
    nan = np.array([np.isnan(r.acceleration).sum(axis=0) for r in records])
    assert nan[:, CHANNELS.index("acc07")].sum() > 0
    dead = nan[:, CHANNELS.index("acc12")] == 19200
    assert dead.sum() == 1
    others = [j for j, c in enumerate(CHANNELS) if c not in ("acc07", "acc12", "acc15")]
    assert nan[:, others].sum() == 0
    rms = np.nanstd(records[0].acceleration, axis=0)
    assert np.all((rms > 1e-3) & (rms < 0.05))  # m/s²: a few mm/s² at rest


def test_acceleration_psd_peaks_at_true_frequencies(short_voyage):
    # The first 10 min are stationary (no shaft harmonic). Project the channels onto the
    # modal coordinates by least squares (channels without NaN) and find each PSD peak.
    # Welch with 4096 samples: 0.0156 Hz bins; half-power bandwidths 2ζf are 4-20 bins;
    # allow 3 bins. Truth: the law averaged over the first 10 min.
    summary, _ = short_voyage
    shapes = mode_shapes()
    spectra = []
    for path in summary.acceleration_files[:2]:
        acceleration = read_accelerations(path).acceleration
        ok = ~np.isnan(acceleration).any(axis=0)
        modal = np.linalg.lstsq(shapes[:, ok].T, acceleration[:, ok].T, rcond=None)[0].T
        freqs, psd = signal.welch(modal, fs=64.0, nperseg=4096, axis=0)
        spectra.append(psd)
    psd = np.mean(spectra, axis=0)
    frequency, _ = true_modal_parameters(_profile(summary).predictors)
    first = frequency[:600].mean(axis=0)
    for m, f in enumerate(first):
        band = (freqs > 0.9 * f) & (freqs < 1.1 * f)
        peak = freqs[band][np.argmax(psd[band, m])]
        assert abs(peak - f) <= 3 * 64.0 / 4096, (m + 1, peak, f)


def test_too_short_voyage_is_rejected(tmp_path):
    with pytest.raises(ValueError, match="hours") as error:
        simulate_voyage(tmp_path, hours=0.2, accelerations=False)
    assert "at least" in str(error.value)


def test_ice_stretch_lowers_and_moves_the_frequencies_and_raises_the_excitation(tmp_path):
    """simulate --ice-hours: the last hour breaks ice (ramming at 2-5 kn); each mode's
    frequency changes from file to file with the ice load (up to ICE_FREQUENCY_DROP); the
    excitation gain is 1 outside the ice, about ICE_EXCITATION_GAIN inside and
    intermittent; without ice no truth_files.csv is written."""
    from workbench.simulate.voyage import ICE_EXCITATION_GAIN, ICE_FREQUENCY_DROP

    summary = simulate_voyage(tmp_path / "ice", seed=4, hours=3, ice_hours=1, accelerations=False)
    cases = pd.read_csv(summary.cases)
    assert cases["case"].iloc[-1] == "ice"
    assert cases["start"].iloc[-1] == "2024-03-01T02:00:00Z"
    files = pd.read_csv(tmp_path / "ice" / "truth_files.csv", parse_dates=["file_start"])
    ice = files["file_start"] >= pd.Timestamp("2024-03-01T02:00:00Z")
    assert (files.loc[~ice, "excitation_gain"] == 1.0).all()
    gain = files.loc[ice].drop_duplicates("file_start")["excitation_gain"]
    assert 0.6 * ICE_EXCITATION_GAIN < gain.median() < 1.6 * ICE_EXCITATION_GAIN
    assert gain.max() / gain.min() > 2.0  # intermittent
    speed = files.loc[ice].drop_duplicates("file_start")["speed_kn"]
    assert 2.0 < speed.median() < 5.0
    # the ice load moves every mode's frequency from one 5-min file to the next
    for mode in (1, 7):
        part = files[files["mode"] == mode]
        in_ice = part[ice[part.index]]["frequency_hz"].to_numpy()
        steps = np.abs(np.diff(in_ice)) / in_ice[:-1]
        assert steps.max() > 0.25 * ICE_FREQUENCY_DROP[mode - 1]  # moves within 5 min
    plain = simulate_voyage(tmp_path / "plain", seed=4, hours=3, accelerations=False)
    assert not (plain.out_dir / "truth_files.csv").exists()
    with pytest.raises(ValueError, match="ice_hours"):
        simulate_voyage(tmp_path / "bad", seed=4, hours=1, ice_hours=1, accelerations=False)
