"""Option B with mode shapes: MAC admissibility, re-acquisition of a lost track, fallback.

Synthetic case: one mode near 7 Hz whose frequency follows the water temperature (the model
learns that law in the first 20 blocks) and then, at block 40, drops by 0.12 Hz for a reason
the predictors do not carry (a regime change the model cannot predict). Each block's
stabilisation diagram holds the true pole at three model orders (the mode's shape plus 1 %
noise) and four *stable* spurious poles scattered within ±4 mHz of the stale model
prediction, with random complex shapes. The nearest-pole rule (no shapes) locks onto the
spurious poles; the shape-aware rule must follow the true pole.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from data_contracts import FORECAST, shapes_to_frame
from workbench.forecasting import ForecastOptions, ForecastWarning, ModeKalmanBank, sliding_forecast
from workbench.forecasting.pole_selection import _mac_on_common_channels
from workbench.sid.assurance import mac

START = pd.Timestamp("2024-03-01T00:00:00Z")
CHANNELS = [f"acc{c:02d}" for c in range(1, 9)]
N_BLOCKS = 70
JUMP_BLOCK = 40
JUMP_HZ = -0.12
MIS_TRACKED_BLOCK = 50  # tracked table holds a wrong (random) shape here
DEAD_CHANNEL_BLOCKS = range(55, 61)  # acc03 missing in tracked and pole shapes


def _unit(shape: np.ndarray) -> np.ndarray:
    return shape / np.linalg.norm(shape)


def _random_shape(rng) -> np.ndarray:
    return _unit(rng.normal(size=len(CHANNELS)) + 1j * rng.normal(size=len(CHANNELS)))


def _regime_change_case(seed: int = 3):
    rng = np.random.default_rng(seed)
    block = np.arange(N_BLOCKS)
    start = START + pd.to_timedelta(block * 300, unit="s")
    water = 5.0 + 2.0 * np.sin(2 * np.pi * block / 20.0)  # full period in the window
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "water_temp_c": water,
            "speed_kn": 10.0 + rng.normal(0, 1.0, N_BLOCKS),
        }
    )
    law = 7.0 * (1.0 - 0.004 * (water - 5.0))  # what the model learns (and keeps predicting)
    truth = law + np.where(block >= JUMP_BLOCK, JUMP_HZ, 0.0)
    shape = _unit(np.linspace(1.0, -0.6, len(CHANNELS)) + 0.05j * np.arange(len(CHANNELS)))

    def noisy(s):
        return _unit(s + 0.01 * (rng.normal(size=s.size) + 1j * rng.normal(size=s.size)))

    # tracked modal table: SSI frequency of the mode and its shape
    tracked_shapes = np.array([noisy(shape) for _ in block])
    tracked_shapes[MIS_TRACKED_BLOCK] = _random_shape(rng)
    modal = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "mode": 1,
            "frequency_hz": truth + rng.normal(0, 0.002, N_BLOCKS),
            "damping_ratio": 0.01,
        }
    )
    modal = pd.concat([modal, shapes_to_frame(CHANNELS, tracked_shapes)], axis=1)
    # stabilisation diagrams: true column + stable spurious poles at the stale prediction
    rows, shapes = [], []
    for k in block:
        for order in (20, 22, 24):
            rows.append((k, order, truth[k] + rng.normal(0, 0.001), 0.012, True))
            shapes.append(noisy(shape))
        for order in (26, 28, 30, 32):
            rows.append((k, order, law[k] + rng.uniform(-0.004, 0.004), 0.02, True))
            shapes.append(_random_shape(rng))
        rows.append((k, 20, 5.0 + rng.normal(0, 0.002), 0.01, True))  # another mode
        shapes.append(_random_shape(rng))
    poles = pd.DataFrame(
        rows, columns=["block", "model_order", "frequency_hz", "damping_ratio", "stable"]
    )
    poles = pd.concat([poles, shapes_to_frame(CHANNELS, np.array(shapes))], axis=1)
    dead = poles["block"].isin(DEAD_CHANNEL_BLOCKS)
    poles.loc[dead, ["shape_re_acc03", "shape_im_acc03"]] = np.nan
    dead = modal["block"].isin(DEAD_CHANNEL_BLOCKS)
    modal.loc[dead, ["shape_re_acc03", "shape_im_acc03"]] = np.nan
    return modal, predictors, poles, truth, law


def _run(modal, predictors, poles, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ForecastWarning)
        options = ForecastOptions(
            options=("B",),
            scheme=1,
            horizon=N_BLOCKS - 20,
            predictor_columns=["water_temp_c", "speed_kn"],
            **{"model": "window", **kwargs},
        )
        result = sliding_forecast(modal, predictors, options, poles=poles)
    messages = [str(w.message) for w in caught if issubclass(w.category, ForecastWarning)]
    return result.table.set_index("block"), messages


def test_option_b_follows_the_true_pole_through_a_regime_change():
    modal, predictors, poles, truth, law = _regime_change_case()
    table, messages = _run(modal, predictors, poles)
    after = table.loc[JUMP_BLOCK:]
    # the model cannot know about the drop: it keeps predicting the old law
    assert np.allclose(after["model_frequency_hz"], law[JUMP_BLOCK:], atol=0.01)
    # every block after the jump measures the true pole (column noise 1 mHz), none spurious
    measured = after["ssi_frequency_hz"].to_numpy()
    assert np.isfinite(measured).all()
    assert np.max(np.abs(measured - truth[JUMP_BLOCK:])) < 0.005
    assert (after["selected_model_order"] <= 24).all()  # orders of the true column
    assert (table["selected_mac"].dropna() >= 0.9).all()
    assert table["selected_mac"].notna().all()
    # the jump block is re-acquired outside the gate (with a row warning), then the gate
    # follows; the Kalman estimate jumps with it (inflated prior: gain ~ 1)
    assert "track re-acquired" in table.loc[JUMP_BLOCK, "warning"]
    assert any("re-acquired" in m for m in messages)
    kalman = after["kalman_frequency_hz"].to_numpy()
    assert abs(kalman[0] - truth[JUMP_BLOCK]) < 0.005
    assert np.max(np.abs(kalman - truth[JUMP_BLOCK:])) < 0.006
    # one mis-tracked shape (block 50) does not become the reference shape, and blocks with
    # a dead channel compare shapes on the channels both have
    assert abs(table.loc[MIS_TRACKED_BLOCK, "ssi_frequency_hz"] - truth[MIS_TRACKED_BLOCK]) < 5e-3
    dead = list(DEAD_CHANNEL_BLOCKS)
    assert np.max(np.abs(table.loc[dead, "ssi_frequency_hz"] - truth[dead])) < 5e-3
    FORECAST.validate(table.reset_index())


def test_without_shapes_option_b_falls_back_to_the_nearest_pole_with_a_warning():
    modal, predictors, poles, truth, law = _regime_change_case()
    no_shapes = poles[[c for c in poles.columns if not c.startswith("shape_")]]
    table, messages = _run(modal, predictors, no_shapes)
    assert any("option B without mode shapes" in m for m in messages)
    assert table["selected_mac"].isna().all()
    # the old rule: nearest stable pole to the prior, i.e. a spurious pole at the stale law
    after = table.loc[JUMP_BLOCK:]
    assert (np.abs(after["ssi_frequency_hz"] - law[JUMP_BLOCK:]) < 0.01).mean() > 0.9
    assert (after["selected_model_order"] >= 26).mean() > 0.9
    assert not table["warning"].str.contains("re-acquired").any()
    FORECAST.validate(table.reset_index())


def test_reacquire_blocks_counts_consecutive_blocks_seen_only_outside_the_gate():
    modal, predictors, poles, truth, _ = _regime_change_case()
    table, _ = _run(modal, predictors, poles, reacquire_blocks=3)
    # blocks 40 and 41: mode only outside the gate -> predict-only; block 42: re-acquired
    assert table.loc[JUMP_BLOCK : JUMP_BLOCK + 1, "ssi_frequency_hz"].isna().all()
    assert "track re-acquired" in table.loc[JUMP_BLOCK + 2, "warning"]
    assert abs(table.loc[JUMP_BLOCK + 2, "ssi_frequency_hz"] - truth[JUMP_BLOCK + 2]) < 5e-3
    later = table.loc[JUMP_BLOCK + 2 :]
    assert np.max(np.abs(later["ssi_frequency_hz"] - truth[JUMP_BLOCK + 2 :])) < 5e-3


def test_stricter_shape_threshold_than_any_pole_means_predict_only():
    modal, predictors, poles, _, _ = _regime_change_case()
    table, _ = _run(modal, predictors, poles, mac_min=0.99999)
    # 1 % shape noise keeps every MAC below 0.99999: nothing admissible, no re-acquisition
    assert table["ssi_frequency_hz"].isna().all()
    assert table["kalman_frequency_hz"].notna().all()


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("mac_min", 1.0),
        ("mac_min", -0.1),
        ("reacquire_blocks", 0),
        ("reacquire_band", 0),
    ],
)
def test_bad_option_b_parameters_raise(name, value):
    with pytest.raises(ValueError, match=name):
        ForecastOptions(options=("B",), **{name: value})


def test_mac_on_common_channels_matches_mac_of_the_shared_components():
    rng = np.random.default_rng(0)
    reference = _random_shape(rng)
    shapes = np.array([_random_shape(rng) for _ in range(5)])
    shapes[1] = (2.0 - 1.5j) * reference  # MAC(φ, cφ) = 1
    shapes[2, [0, 4]] = np.nan  # two channels missing
    shapes[3, 2:] = np.nan  # only two channels left: not comparable
    reference_missing = reference.copy()
    reference_missing[6] = np.nan
    got = _mac_on_common_channels(reference_missing, shapes)
    keep = np.isfinite(reference_missing)
    assert got[1] == pytest.approx(1.0, abs=1e-12)
    common = keep & np.isfinite(shapes[2])
    assert got[2] == pytest.approx(float(mac(reference[common], shapes[2, common])), abs=1e-12)
    assert np.isnan(got[3])
    for r in (0, 4):
        assert got[r] == pytest.approx(float(mac(reference[keep], shapes[r, keep])), abs=1e-12)
    assert np.all((got[np.isfinite(got)] >= 0) & (got[np.isfinite(got)] <= 1))


def test_inflated_prior_variance_gives_the_gain_of_the_innovation():
    bank = ModeKalmanBank(2, transition=1.0)
    bank.set_noise(np.array([1e-6, 1e-6]), np.array([4e-6, 4e-6]))
    bank.initialise(np.array([0, 1]), np.array([7.0, 5.0]))
    prior = bank.variance.copy()
    innovation = 0.1
    bank.inflate(np.array([0]), np.array([innovation**2]))
    assert bank.variance[0] == pytest.approx(innovation**2)
    assert bank.variance[1] == prior[1]  # other modes untouched
    bank.inflate(np.array([1]), np.array([0.0]))  # never lowers P⁻
    assert bank.variance[1] == prior[1]
    gain = bank.update(np.array([7.0 + innovation, np.nan]))
    # K = y² / (y² + R)
    assert gain[0] == pytest.approx(innovation**2 / (innovation**2 + 4e-6), rel=1e-12)
    assert bank.state[0] == pytest.approx(7.0 + innovation * gain[0], rel=1e-12)
    with pytest.raises(ValueError, match="prior_variance"):
        bank.inflate(np.array([0]), np.array([np.nan]))
