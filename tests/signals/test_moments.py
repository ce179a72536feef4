"""Tests for sliding-window moments and faulty-channel detection.

Reference values: the kurtosis (Pearson) of a Gaussian is 3, of a uniform distribution 1.8,
of a sine 1.5; the estimators are compared with scipy.stats on the same windows.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from workbench.signals import ChannelCheckOptions, faulty_channels, moments

RATE = 64.0


def test_moments_match_scipy_and_known_distributions():
    rng = np.random.default_rng(0)
    n = int(RATE * 1200)
    t = np.arange(n) / RATE
    x = np.column_stack(
        [
            rng.standard_normal(n),
            rng.uniform(-1, 1, n),
            np.sin(2 * np.pi * 2.0 * t),
        ]
    )
    result = moments(x, RATE, 300.0)
    assert result.mean.shape == (4, 3)
    np.testing.assert_allclose(result.start_s, [0, 300, 600, 900])
    window = x[: int(RATE * 300)]
    np.testing.assert_allclose(result.mean[0], window.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(result.variance[0], window.var(axis=0), rtol=1e-10)
    np.testing.assert_allclose(result.skewness[0], stats.skew(window, axis=0), atol=1e-10)
    np.testing.assert_allclose(
        result.kurtosis[0], stats.kurtosis(window, axis=0, fisher=False), rtol=1e-10
    )
    # 19 200 samples per window: the kurtosis estimator's sd is sqrt(24/n) = 0.035 for a
    # Gaussian, so 0.2 is about 6 sd; uniform 1.8 and sine 1.5 are tighter still
    np.testing.assert_allclose(result.kurtosis[:, 0], 3.0, atol=0.2)
    np.testing.assert_allclose(result.kurtosis[:, 1], 1.8, atol=0.05)
    np.testing.assert_allclose(result.kurtosis[:, 2], 1.5, atol=1e-3)
    np.testing.assert_allclose(result.skewness[:, 0], 0.0, atol=0.1)


def test_moments_overlapping_windows_and_nan():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((6400, 2))
    x[:4000, 1] = np.nan
    result = moments(x, RATE, 25.0, step_s=12.5)
    assert result.mean.shape == (7, 2)  # starts 0, 12.5, ..., 75 s; window 1600 samples
    np.testing.assert_allclose(result.mean[1, 0], x[800:2400, 0].mean(), atol=1e-12)
    # a window with 1600 - 1200 finite samples of 1600 is kept (>= 50 %), fewer is NaN
    assert np.isnan(result.variance[:4, 1]).all()  # windows starting before 3200 samples
    valid = ~np.isnan(x[2400:4000, 1])
    assert valid.sum() == 0 and np.isnan(result.variance[3, 1])
    np.testing.assert_allclose(result.variance[5, 1], np.nanvar(x[4000:5600, 1]), rtol=1e-10)
    frame = result.to_frame(["a", "b"])
    assert list(frame.columns) == [
        "start_s",
        "channel",
        "n_valid",
        "mean",
        "variance",
        "skewness",
        "kurtosis",
    ]
    assert len(frame) == 14


def _healthy(rng: np.random.Generator, n_channels: int = 8) -> np.ndarray:
    n = int(RATE * 1200)
    scale = rng.uniform(0.005, 0.02, n_channels)
    return rng.standard_normal((n, n_channels)) * scale


def test_faulty_channels_finds_spikes_nan_runs_flat_and_outliers():
    rng = np.random.default_rng(2)
    x = _healthy(rng)
    x[rng.choice(len(x), 20, replace=False), 1] += 0.5  # spikes of ~50 sd
    x[1000 : 1000 + int(60 * RATE), 2] = np.nan  # one-minute dropout
    x[:, 3] = 0.003  # stuck sensor
    x[:, 4] *= 1000.0  # a sensor 1000x too loud (z = ln(1e6) / spread)
    x[rng.random(len(x)) < 0.08, 5] = np.nan  # 8 % scattered dropouts
    x[:, 6] = np.nan  # dead
    report = faulty_channels(x, RATE, [f"c{j}" for j in range(8)])
    assert list(report.columns) == [
        "channel",
        "faulty",
        "reason",
        "nan_fraction",
        "longest_nan_run_s",
        "variance",
        "kurtosis",
        "variance_z",
        "kurtosis_z",
        "coherent",
    ]
    faulty = dict(zip(report["channel"], report["faulty"], strict=True))
    reasons = dict(zip(report["channel"], report["reason"], strict=True))
    assert faulty == {f"c{j}": j in (1, 2, 3, 4, 5, 6) for j in range(8)}
    assert reasons["c1"].startswith("kurtosis ") and "> 10" in reasons["c1"]
    assert reasons["c2"] == "nan run 60.0 s"
    assert reasons["c3"] == "flat (variance 0)"
    # the loud sensor records noise of its own: no coherence with any other channel
    assert reasons["c4"].startswith("variance z ") and "no coherence" in reasons["c4"]
    assert reasons["c5"].startswith("nan fraction 8.")
    assert reasons["c6"] == "no data (all NaN)"
    assert reasons["c0"] == reasons["c7"] == ""
    assert report.loc[report["channel"] == "c0", "kurtosis"].item() == pytest.approx(3.0, abs=0.15)


def test_faulty_channels_low_kurtosis_and_options():
    n = int(RATE * 600)
    t = np.arange(n) / RATE
    rng = np.random.default_rng(3)
    x = np.column_stack(
        [np.sign(np.sin(2 * np.pi * 3 * t)) * 0.01, rng.standard_normal((n, 3)) * 0.01]
    )  # a square wave (clipping): kurtosis 1
    report = faulty_channels(x, RATE)
    assert report["faulty"].tolist() == [True, False, False, False]
    assert report["reason"].iloc[0] == "kurtosis 1.00 < 1.3"
    relaxed = faulty_channels(x, RATE, options=ChannelCheckOptions(kurtosis_limits=(0.5, 10.0)))
    assert not relaxed["faulty"].any()
    with pytest.raises(ValueError, match="channel names"):
        faulty_channels(x, RATE, ["a"])


def _structure(rng, n_channels=6, impulsive=False, seconds=600.0):
    """Accelerations of a 3-mode structure at *n_channels* points, excited by white noise
    or (impulsive=True) by sparse impacts that every channel sees, plus 5 % sensor noise."""
    from scipy import signal

    n = int(RATE * seconds)
    if impulsive:  # ice impacts: a few hundred large impulses over low-level noise
        force = 0.05 * rng.standard_normal(n)
        hits = rng.choice(n, int(seconds / 3), replace=False)
        force[hits] += rng.standard_normal(hits.size) * 30.0
    else:
        force = rng.standard_normal(n)
    response = np.zeros((n, n_channels))
    points = np.linspace(0.1, 0.9, n_channels)
    for m, (f, zeta) in enumerate(((2.0, 0.01), (4.5, 0.015), (7.0, 0.02)), start=1):
        w = 2 * np.pi * f
        system = signal.cont2discrete(([w**2], [1, 2 * zeta * w, w**2]), 1 / RATE)
        modal = signal.lfilter(np.ravel(system[0]), system[1], force)
        response += np.outer(modal, np.sin(m * np.pi * points))
    response /= response.std()
    return response + 0.05 * rng.standard_normal(response.shape)


def test_impulsive_excitation_is_not_a_fault_but_a_spiking_sensor_is():
    """Impacts seen by every channel raise every kurtosis (here 8-40): no channel is
    faulty. Spikes of one sensor alone make that sensor faulty."""
    rng = np.random.default_rng(7)
    x = _structure(rng, impulsive=True)
    report = faulty_channels(x, RATE)
    assert (report["kurtosis"] > 6).all()
    assert not report["faulty"].any(), report["reason"].tolist()
    # the former absolute rule takes the excitation for faults
    absolute = faulty_channels(x, RATE, options=ChannelCheckOptions(max_kurtosis_z=-np.inf))
    assert absolute["faulty"].sum() >= 1
    spiky = x.copy()
    spiky[rng.choice(len(x), 40, replace=False), 2] += 60 * x[:, 2].std()
    report = faulty_channels(spiky, RATE)
    assert report["faulty"].tolist() == [j == 2 for j in range(6)]
    assert report["reason"].iloc[2].startswith("kurtosis ")


def test_variance_outlier_kept_when_coherent_dropped_when_not():
    """A channel in other units (1000x the others, like an accelerometer among velocity
    channels) sees the same modes: coherent, kept. A sensor that recorded only its own
    noise at that level is dropped."""
    rng = np.random.default_rng(8)
    x = _structure(rng)
    x[:, 1] *= 1000.0
    report = faulty_channels(x, RATE)
    assert report["variance_z"].iloc[1] > 6 and report["coherent"].iloc[1] == 1.0
    assert not report["faulty"].any()
    x[:, 1] = rng.standard_normal(len(x)) * 1000.0
    report = faulty_channels(x, RATE)
    assert report["faulty"].tolist() == [j == 1 for j in range(6)]
    assert report["coherent"].iloc[1] == 0.0
    # without the coherence test a variance outlier is dropped on its z-score alone
    x = _structure(rng)
    x[:, 1] *= 1000.0
    assert faulty_channels(x, RATE, options=ChannelCheckOptions(coherence_check=False))[
        "faulty"
    ].iloc[1]


def test_coherence_of_independent_noise_is_not_significant():
    """Zero-coherence test: with independent white noise channels the false-alarm rate
    over 50 trials stays near its design level (0.1 % per compared channel)."""
    from workbench.signals.moments import coherent_with_others

    rng = np.random.default_rng(9)
    alarms = 0
    for _ in range(50):
        x = rng.standard_normal((int(RATE * 120), 4))
        alarms += int(coherent_with_others(x, RATE, [0])[0])
    assert alarms <= 1
