"""Tests for detrend, decimation, band-pass and NaN-run interpolation.

Expected values are analytic: the gain of a zero-phase (forward-backward) filter is
|H(f)|², computed independently here with scipy.signal.sosfreqz for the same design, and a
Butterworth pass has |H| = 1/sqrt(2) at its edges.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import signal

from workbench.signals import (
    SignalWarning,
    bandpass,
    decimate,
    decimation_stages,
    detrend,
    interpolate_nan_runs,
)


def _fit_tone(y: np.ndarray, t: np.ndarray, frequency_hz: float) -> tuple[float, float]:
    """Amplitude and phase of the sine at *frequency_hz* in *y* (least squares)."""
    design = np.column_stack(
        [np.sin(2 * np.pi * frequency_hz * t), np.cos(2 * np.pi * frequency_hz * t)]
    )
    (a, b), *_ = np.linalg.lstsq(design, y, rcond=None)
    return float(np.hypot(a, b)), float(np.arctan2(b, a))


def _zero_phase_gain(
    stages: list[int], order: int, ripple_db: float, rate: float, f: float
) -> float:
    """|H(f)|² of each forward-backward Chebyshev stage, multiplied."""
    gain = 1.0
    for q in stages:
        sos = signal.cheby1(order, ripple_db, 0.8 / q, output="sos")
        _, h = signal.sosfreqz(sos, worN=[f], fs=rate)
        gain *= abs(h[0]) ** 2
        rate /= q
    return gain


RATE = 2048.0
SECONDS = 60.0
T = np.arange(int(RATE * SECONDS)) / RATE


def test_decimation_stages():
    assert decimation_stages(32) == [8, 4]
    assert decimation_stages(12) == [6, 2]
    assert decimation_stages(100) == [10, 10]
    assert decimation_stages(13) == [13]
    assert decimation_stages(1) == []


def test_decimate_matches_scipy_for_one_stage():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((4000, 3))
    ours = decimate(x, 800.0, 100.0)
    reference = signal.decimate(x, 8, ftype="iir", zero_phase=True, axis=0)
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-12)


def test_decimate_keeps_a_3_hz_sine_and_its_phase():
    phase = 0.7
    x = 0.05 * np.sin(2 * np.pi * 3.0 * T + phase)
    middle = slice(64 * 10, 64 * 50)  # away from the edge transients
    # default design: the gain is exactly the analytic zero-phase gain of the two stages
    y = decimate(x, RATE, 64.0)
    t = T[::32]
    amplitude, fitted_phase = _fit_tone(y[middle], t[middle], 3.0)
    expected = 0.05 * _zero_phase_gain([8, 4], 8, 0.05, RATE, 3.0)
    assert amplitude == pytest.approx(expected, rel=1e-5)
    # documented bound: each of the 2 stages within 2 x 0.05 dB below 1
    assert 0.05 * 10 ** (-0.2 / 20) <= amplitude <= 0.05
    assert fitted_phase == pytest.approx(phase, abs=1e-5)  # zero phase
    # ripple_db=0.002 (documented choice for 0.1 % accuracy): within 0.1 % and 0.1 % of a cycle
    fine = decimate(x, RATE, 64.0, ripple_db=0.002)
    amplitude, fitted_phase = _fit_tone(fine[middle], t[middle], 3.0)
    assert abs(amplitude / 0.05 - 1) < 1e-3
    assert abs(fitted_phase - phase) < 2 * np.pi * 1e-3


@pytest.mark.parametrize(("ripple_db", "min_db"), [(0.05, 80.0), (0.002, 60.0)])
def test_decimate_removes_a_40_hz_tone(ripple_db, min_db):
    """40 Hz would alias to 24 Hz at 64 Hz; the anti-alias filter must remove it."""
    x = np.sin(2 * np.pi * 40.0 * T)
    y = decimate(x, RATE, 64.0, ripple_db=ripple_db)
    middle = slice(64 * 10, 64 * 50)
    rms = np.sqrt(np.mean(y[middle] ** 2))
    attenuation_db = -20 * np.log10(rms / np.sqrt(0.5))
    assert attenuation_db > min_db
    analytic_db = -10 * np.log10(_zero_phase_gain([8, 4], 8, ripple_db, RATE, 40.0))
    # the measured level sits at the analytic gain or below (round-off floor ~1e-6)
    assert attenuation_db > min(analytic_db - 1.0, 110.0)


def test_decimate_rejects_non_integer_factors():
    with pytest.raises(ValueError, match="whole number"):
        decimate(np.zeros(1000), 2048.0, 100.0)
    with pytest.raises(ValueError, match="target_rate_hz"):
        decimate(np.zeros(1000), 64.0, -1.0)


def test_decimate_handles_nan_runs():
    n = 2048 * 30
    x = np.column_stack([np.sin(2 * np.pi * 3.0 * T[:n]), np.sin(2 * np.pi * 3.0 * T[:n])])
    x[1000:1100, 0] = np.nan  # 0.05 s: bridged
    x[2000 : 2000 + 2048 * 11, 1] = np.nan  # 11 s > 10 s: a faulty channel
    with pytest.warns(SignalWarning, match="channel"):
        y = decimate(x, RATE, 64.0)
    assert np.isfinite(y[:, 0]).all()
    assert np.isnan(y[:, 1]).all()


def test_bandpass_passband_edges_and_stopband():
    rate = 64.0
    t = np.arange(int(rate * 600)) / rate
    middle = slice(int(rate * 60), int(rate * 540))
    sos = signal.butter(4, [2.0, 12.0], "bandpass", fs=rate, output="sos")
    for frequency, check in [
        (6.0, lambda g: abs(g - 1) < 2e-3),  # passband
        (2.0, lambda g: abs(g - 0.5) < 2e-3),  # edges: (1/sqrt 2)² = 1/2
        (12.0, lambda g: abs(g - 0.5) < 2e-3),
        (0.3, lambda g: g < 1e-5),  # stopband: below -100 dB
        (25.0, lambda g: g < 1e-3),  # below -60 dB
    ]:
        y = bandpass(np.sin(2 * np.pi * frequency * t), rate, 2.0, 12.0)
        gain, _ = _fit_tone(y[middle], t[middle], frequency)
        _, h = signal.sosfreqz(sos, worN=[frequency], fs=rate)
        assert gain == pytest.approx(abs(h[0]) ** 2, abs=2e-6), frequency
        assert check(gain), (frequency, gain)


def test_bandpass_one_sided_and_errors():
    rate = 64.0
    t = np.arange(6400) / rate
    x = np.sin(2 * np.pi * 1.0 * t) + np.sin(2 * np.pi * 20.0 * t)
    low = bandpass(x, rate, None, 5.0)
    gain_1, _ = _fit_tone(low[640:-640], t[640:-640], 1.0)
    gain_20, _ = _fit_tone(low[640:-640], t[640:-640], 20.0)
    assert gain_1 == pytest.approx(1.0, abs=1e-3) and gain_20 < 1e-4
    with pytest.raises(ValueError, match="high_hz"):
        bandpass(x, rate, 2.0, 40.0)
    with pytest.raises(ValueError, match="below"):
        bandpass(x, rate, 12.0, 2.0)


def test_detrend_removes_the_least_squares_line_ignoring_nan():
    rng = np.random.default_rng(2)
    n = 500
    t = np.arange(n)
    x = np.column_stack(
        [3.0 + 0.01 * t + rng.standard_normal(n), -2.0 * np.ones(n), rng.standard_normal(n)]
    )
    x[50:80, 0] = np.nan
    x[:, 2] = np.nan
    y = detrend(x)
    finite = ~np.isnan(x[:, 0])
    slope, intercept = np.polyfit(t[finite], x[finite, 0], 1)
    np.testing.assert_allclose(
        y[finite, 0], x[finite, 0] - (intercept + slope * t[finite]), atol=1e-10
    )
    assert np.isnan(y[50:80, 0]).all()
    np.testing.assert_allclose(y[:, 1], 0.0, atol=1e-12)
    assert np.isnan(y[:, 2]).all()
    # 1-D in, 1-D out; input untouched
    assert detrend(x[:, 1]).shape == (n,) and x[0, 1] == -2.0


def test_interpolate_nan_runs():
    x = np.arange(20, dtype=float)
    x[3:5] = np.nan  # 2 samples = 0.2 s at 10 Hz: bridged exactly (a straight line)
    x[10:16] = np.nan  # 0.6 s: too long for max_run_s=0.5
    x[0] = np.nan  # edge: nearest value
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        y = interpolate_nan_runs(x, 10.0, max_run_s=0.5)
    np.testing.assert_allclose(y[3:5], [3.0, 4.0])
    assert np.isnan(y[10:16]).all()
    assert y[0] == 1.0
    assert np.isnan(x[3])  # input untouched
