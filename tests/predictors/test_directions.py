"""A direction predictor is an angle on a circle: where the circle is cut changes nothing.

A ship steaming into the wind has its relative wind direction swinging across 0°; the same
voyage with the wind from astern (every direction turned by 180°) swings across 180° and
never wraps. Models in the direction's cosine see the second voyage as the first with the
column's sign flipped, so their forecasts, fits and |r| are the same; taken as a number in
degrees (main before the change) the head-wind voyage's direction jumped between about 0
and 360 from block to block and the two voyages gave other models.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from data_contracts import PREDICTORS
from workbench.forecasting import ForecastOptions, sliding_forecast
from workbench.forecasting.predictor_grid import block_column_coverage, predictor_matrix
from workbench.predictors.directions import (
    component_columns,
    model_columns,
    with_direction_components,
)
from workbench.stats import correlation_table, fit_modes

START = pd.Timestamp("2024-03-01T00:00:00Z")


def _voyage(about_deg: float, n_blocks: int = 160, seed: int = 3):
    """Three modes falling with speed and with the wind speed (0.2 % per m/s), none with
    the direction; the relative wind swings ±30° about *about_deg* (0: across the bow)."""
    rng = np.random.default_rng(seed)
    block = np.arange(n_blocks)
    start = START + pd.to_timedelta(block * 300, unit="s")
    speed = 9.0 + 4.0 * np.sin(2 * np.pi * block / 70.0) + rng.normal(0, 0.3, n_blocks)
    wind = 8.0 + 3.0 * np.sin(2 * np.pi * block / 45.0 + 1.0)
    swing = 30.0 * np.sin(2 * np.pi * block / 11.0) + rng.normal(0, 4.0, n_blocks)
    base = np.array([0.9, 1.7, 2.6])[None, :]
    truth = base * (1.0 - 0.003 * speed[:, None]) * (1.0 - 0.002 * (wind[:, None] - 8.0))
    observed = truth * (1.0 + rng.normal(0, 0.002, truth.shape))
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "speed_kn": speed,
            "water_temp_c": 4.0 + 0.2 * rng.normal(size=n_blocks),
            "air_temp_c": -2.0 + 0.5 * rng.normal(size=n_blocks),
            "wind_speed_ms": wind,
            "wind_dir_rel_deg": np.mod(about_deg + swing, 360.0),
        }
    )
    b = np.repeat(block, 3)
    m = np.tile(np.arange(3), n_blocks)
    modal = pd.DataFrame(
        {
            "block": b,
            "block_start": start[b],
            "block_end": start[b] + pd.Timedelta(minutes=20),
            "mode": m + 1,
            "frequency_hz": observed[b, m],
            "damping_ratio": 0.01,
        }
    )
    return modal, PREDICTORS.validate(predictors)


def test_the_head_wind_voyage_wraps_and_the_following_one_does_not():
    """The premise: the same swing is a jump of about 300° per block across the bow."""
    head = _voyage(0.0)[1]["wind_dir_rel_deg"].to_numpy()
    follow = _voyage(180.0)[1]["wind_dir_rel_deg"].to_numpy()
    assert (np.abs(np.diff(head)) > 180).sum() >= 25
    assert (np.abs(np.diff(follow)) > 180).sum() == 0


def test_the_forecast_does_not_depend_on_where_the_circle_is_cut():
    """Memory model, options A and B's measurement (A here: no poles), method 2: the
    estimates of the head-wind voyage and of the following-wind one agree to 1e-9 Hz (main:
    108 of the 480 rows apart, by up to 1.3e-3 Hz: the head-wind direction's jumps in the
    models)."""
    tables = []
    for about in (0.0, 180.0):
        modal, predictors = _voyage(about)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            result = sliding_forecast(modal, predictors, ForecastOptions(options=("A",), scheme=2))
        tables.append(result.table)
    head, follow = tables
    assert len(head) == len(follow) > 300
    for column in ("model_frequency_hz", "kalman_frequency_hz", "kalman_std_hz"):
        np.testing.assert_allclose(head[column], follow[column], rtol=0, atol=1e-9)
    assert head["warning"].fillna("").tolist() == follow["warning"].fillna("").tolist()


def test_a_mirrored_wind_and_a_full_turn_leave_the_forecast_as_it_is():
    """Wind from port in place of starboard (θ -> 360 - θ: 350° <-> 10°) and every direction
    written one turn on (θ + 360, outside the table's 0-360, so straight to the forecast's
    matrix): the same model inputs."""
    _, predictors = _voyage(0.0)
    mirrored = predictors.assign(
        wind_dir_rel_deg=np.mod(360.0 - predictors["wind_dir_rel_deg"], 360)
    )
    turned = predictors.assign(wind_dir_rel_deg=predictors["wind_dir_rel_deg"] + 360.0)
    _, _, _, columns, X = predictor_matrix(predictors, None)
    _, _, _, _, X_mirrored = predictor_matrix(mirrored, None)
    _, _, _, _, X_turned = predictor_matrix(turned, None)
    assert "wind_dir_rel_cos" in columns and "wind_dir_rel_deg" not in columns
    np.testing.assert_allclose(X_turned, X, atol=1e-12)
    np.testing.assert_allclose(X_mirrored, X, atol=1e-12)


def test_the_stepwise_fits_and_correlations_do_not_depend_on_the_cut():
    """fit_modes (stepwise, MATLAB's defaults) and the correlation table: the same terms
    (a direction's coefficient with the opposite sign), the same fitted values and |r|
    (main: the direction's |r| with the modes differ, the wrapped column's against the
    unwrapped one's)."""
    (modal_h, pred_h), (modal_f, pred_f) = _voyage(0.0), _voyage(180.0)
    fits_h, fits_f = fit_modes(modal_h, pred_h), fit_modes(modal_f, pred_f)
    assert list(fits_h) == list(fits_f) == [1, 2, 3]
    for mode in fits_h:
        assert fits_h[mode].fit.terms == fits_f[mode].fit.terms
        assert "wind_speed_ms" in fits_h[mode].fit.terms
        np.testing.assert_allclose(fits_h[mode].fitted, fits_f[mode].fitted, rtol=0, atol=1e-12)
    r_h = correlation_table(modal_h, pred_h).set_index(["x", "y", "case"])["r"]
    r_f = correlation_table(modal_f, pred_f).set_index(["x", "y", "case"])["r"]
    np.testing.assert_allclose(np.abs(r_h), np.abs(r_f.loc[r_h.index]), rtol=0, atol=1e-12)
    assert "wind_dir_rel_deg" not in set(r_h.index.get_level_values("x"))


def test_components_and_names():
    """The cosine where the direction stood, with the log's coverage of the direction; a
    missing direction NaN."""
    assert component_columns("wind_dir_rel_deg") == ("wind_dir_rel_cos",)
    assert model_columns(["speed_kn", "wind_dir_rel_deg", "wind_speed_ms"]) == [
        "speed_kn",
        "wind_dir_rel_cos",
        "wind_speed_ms",
    ]
    frame = pd.DataFrame(
        {
            "block": [0, 1, 2],
            "wind_dir_rel_deg": [0.0, 90.0, np.nan],
            "log_coverage": [1.0, 1.0, 0.0],
            "log_coverage_wind_dir_rel_deg": [1.0, 0.5, 0.0],
        }
    )
    out = with_direction_components(frame)
    assert list(out.columns) == [
        "block",
        "wind_dir_rel_cos",
        "log_coverage",
        "log_coverage_wind_dir_rel_deg",
    ]
    np.testing.assert_allclose(out["wind_dir_rel_cos"], [1.0, 0.0, np.nan], atol=1e-15)
    coverage = block_column_coverage(frame, ["wind_dir_rel_cos"])
    np.testing.assert_allclose(coverage, [[1.0], [0.5], [0.0]])


@pytest.mark.parametrize("given", [["wind_dir_rel_deg"], ["wind_dir_rel_cos"]])
def test_named_predictor_columns(given):
    """A forecast told to use the direction (in degrees or as its cosine) gets the cosine."""
    _, predictors = _voyage(0.0)
    _, _, _, columns, X = predictor_matrix(predictors, given)
    assert columns == model_columns(given)
    assert np.nanmax(np.abs(X)) <= 1.0
