"""Tests of the sliding forecast: gaps, option B gating, no look-ahead, fallbacks, contract."""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from data_contracts import FORECAST
from workbench.forecasting import (
    ForecastOptions,
    ForecastWarning,
    NoiseOptions,
    relaxation_factor,
    sliding_forecast,
)
from workbench.forecasting.options import DEFAULT_HORIZON, DEFAULT_TRUST

START = pd.Timestamp("2024-03-01T00:00:00Z")


def _tables(n_blocks=80, n_modes=2, noise=0.002, seed=0):
    """Frequencies linear in water temperature plus noise; speed is a distractor."""
    rng = np.random.default_rng(seed)
    block = np.arange(n_blocks)
    start = START + pd.to_timedelta(block * 300, unit="s")
    water = 5.0 + 2.0 * np.sin(2 * np.pi * block / 40.0)
    speed = 10.0 + rng.normal(0, 1.0, n_blocks)
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "speed_kn": speed,
            "water_temp_c": water,
        }
    )
    base = np.array([3.0, 5.0, 7.0])[:n_modes]
    truth = base[None, :] * (1.0 - 0.004 * (water[:, None] - 5.0))
    observed = truth + rng.normal(0, noise, truth.shape)
    b = np.repeat(block, n_modes)
    m = np.tile(np.arange(n_modes), n_blocks)
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
    return modal, predictors, truth


def _quiet(modal, predictors, poles=None, option="A", **settings):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForecastWarning)
        # the reference configuration (20-block window, trust, single window) unless a test
        # says otherwise
        options = ForecastOptions(
            **{"model": "window", "scheme": 1, "options": (option,), **settings}
        )
        return sliding_forecast(modal, predictors, options, poles=poles)


def test_table_validates_against_forecast_contract_options_a_and_b():
    modal, predictors, truth = _tables()
    poles = modal[["block", "frequency_hz", "damping_ratio"]].assign(model_order=20, stable=True)
    for option in ("A", "B"):
        result = _quiet(modal=modal, predictors=predictors, poles=poles, option=option, horizon=40)
        table = FORECAST.validate(result.table)
        assert len(table) == 2 * 60  # 20 train + 40 forecast blocks, 2 modes
        assert set(table["phase"]) == {"train", "forecast"}
        assert (table["option"] == option).all()
        assert (table["model_lower_hz"] <= table["model_upper_hz"]).all()
        assert (table["window_end_block"] == 19).all()
    assert {"selected_model_order", "selected_damping_ratio", "warning"} <= set(result.table)


def test_model_follows_the_law_and_kalman_beats_raw_observations():
    modal, predictors, truth = _tables(noise=0.004)
    result = _quiet(modal=modal, predictors=predictors, horizon=60, trust=None)
    models = [m for m in result.models if m.mode == 1]
    assert models[0].kind == "stepwise"
    assert any("water_temp_c" in term for term in models[0].terms)
    table = result.table[(result.table["mode"] == 1) & (result.table["phase"] == "forecast")]
    true_hz = truth[table["block"].to_numpy(), 0]
    kalman_error = np.abs(table["kalman_frequency_hz"].to_numpy() - true_hz).sum()
    ssi_error = np.abs(table["ssi_frequency_hz"].to_numpy() - true_hz).sum()
    assert kalman_error < 0.7 * ssi_error


def test_trust_sets_the_steady_state_gain():
    modal, predictors, _ = _tables()
    result = _quiet(modal=modal, predictors=predictors, horizon=20, trust=0.65)
    phi = relaxation_factor(36.0)
    for model in result.models:
        q, r = model.process_variance, model.measurement_variance
        # Q = K R (1/(1-K) - φ²) with K = 0.65
        assert q == pytest.approx(0.65 * r * (1 / 0.35 - phi**2), rel=1e-12)
    # far from the start, the posterior std is sqrt(P⁺) = sqrt(K R) (steady state)
    row = result.table[(result.table["mode"] == 1)].iloc[-1]
    r = result.models[0].measurement_variance
    assert row["kalman_std_hz"] == pytest.approx(math.sqrt(0.65 * r), rel=1e-9)


def test_gap_is_predict_only_model_plus_decaying_correction_and_recovers():
    modal, predictors, _ = _tables(n_blocks=90)
    gap = (modal["mode"] == 1) & modal["block"].between(40, 59)
    modal = modal[~gap]
    tau = 10.0
    result = _quiet(
        modal=modal, predictors=predictors, horizon=70, correction_time_blocks=tau, trust=0.65
    )
    table = result.table[result.table["mode"] == 1].set_index("block")
    assert table.loc[40:59, "ssi_frequency_hz"].isna().all()
    correction = table["kalman_frequency_hz"] - table["model_frequency_hz"]
    phi = math.exp(-1.0 / tau)
    # inside the gap the correction decays geometrically: c_k = φ^(k - 39) c_39
    expected = correction.loc[39] * phi ** np.arange(1, 21)
    assert np.allclose(correction.loc[40:59].to_numpy(), expected, rtol=1e-9, atol=1e-12)
    std = table["kalman_std_hz"]
    assert np.all(np.diff(std.loc[39:59].to_numpy()) > 0)  # P grows through the gap
    assert std.loc[60] < std.loc[59]  # first measurement back shrinks it
    assert std.loc[75] == pytest.approx(std.loc[30], rel=1e-6)  # back to steady state
    assert "predict-only" in table.loc[55, "warning"]
    assert "predict-only" not in table.loc[30, "warning"]


def _poles_for(modal, rng):
    rows = []
    for block, freq in modal.loc[modal["mode"] == 1, ["block", "frequency_hz"]].itertuples(
        index=False
    ):
        rows.append((block, 10, freq, 0.011, True))
        rows.append((block, 12, freq + 0.5, 0.02, True))  # another mode, far away
    return pd.DataFrame(
        rows, columns=["block", "model_order", "frequency_hz", "damping_ratio", "stable"]
    )


def test_option_b_picks_nearest_pole_in_gate_prefers_stable_and_gates_out():
    modal, predictors, _ = _tables(n_modes=1)
    rng = np.random.default_rng(1)
    poles = _poles_for(modal, rng)
    # block 30: an unstable pole nearer than the stable one, both inside the gate
    near = modal.loc[modal["block"] == 30, "frequency_hz"].iloc[0]
    poles.loc[(poles["block"] == 30) & (poles["model_order"] == 10), "frequency_hz"] = near + 1e-3
    poles = pd.concat(
        [
            poles,
            pd.DataFrame(
                {
                    "block": [30, 31],
                    "model_order": [14, 16],
                    "frequency_hz": [near, near + 2e-4],
                    "damping_ratio": [0.03, 0.012],
                    "stable": [False, True],
                }
            ),
        ],
        ignore_index=True,
    )
    # block 35: every pole far outside the gate -> predict-only
    far = poles["block"] == 35
    poles.loc[far, "frequency_hz"] += 1.0
    result = _quiet(modal=modal, predictors=predictors, poles=poles, option="B", horizon=30)
    table = result.table.set_index("block")
    assert table.loc[30, "selected_model_order"] == 10  # stable preferred over unstable
    assert table.loc[30, "ssi_frequency_hz"] == pytest.approx(near + 1e-3)
    assert table.loc[31, "selected_model_order"] in (10, 16)
    pole_31 = poles[poles["block"] == 31]
    prior_31 = table.loc[31, "model_frequency_hz"]
    nearest = pole_31.loc[(pole_31["frequency_hz"] - prior_31).abs().idxmin()]
    assert table.loc[31, "ssi_frequency_hz"] == pytest.approx(
        nearest["frequency_hz"], abs=3e-3
    )  # nearest to the a-priori (x⁻ differs from m by the small correction)
    assert np.isnan(table.loc[35, "ssi_frequency_hz"])
    assert pd.isna(table.loc[35, "selected_model_order"])
    assert table.loc[36, "selected_model_order"] == 10  # resumes
    chosen = table["selected_damping_ratio"].dropna()
    assert set(np.round(chosen, 4)) <= {0.011, 0.012, 0.03}


def test_no_look_ahead_window_model_ignores_later_predictors():
    modal, predictors, _ = _tables()
    first = _quiet(modal=modal, predictors=predictors, horizon=30)
    changed = predictors.copy()
    later = changed["block"] >= 20
    changed.loc[later, "water_temp_c"] = changed.loc[later, "water_temp_c"] * 3 + 40.0
    changed.loc[later, "speed_kn"] = 0.0
    second = _quiet(modal=modal, predictors=changed, horizon=30)
    for a, b in zip(first.models, second.models, strict=True):
        assert a.terms == b.terms
        assert a.normalisation == b.normalisation
        assert a.coefficients == pytest.approx(b.coefficients, rel=1e-12)
    train_a = first.table[first.table["phase"] == "train"]
    train_b = second.table[second.table["phase"] == "train"]
    assert np.array_equal(train_a["model_frequency_hz"], train_b["model_frequency_hz"])
    fore_a = first.table[first.table["phase"] == "forecast"]
    fore_b = second.table[second.table["phase"] == "forecast"]
    assert not np.allclose(fore_a["model_frequency_hz"], fore_b["model_frequency_hz"])


def test_method_2_slides_by_horizon_and_trains_on_kalman_estimates():
    modal, predictors, _ = _tables(n_blocks=60, n_modes=1)
    result = _quiet(modal=modal, predictors=predictors, scheme=2, horizon=4)
    table = result.table.set_index("block")
    assert table.index.tolist() == list(range(60))  # continuous
    starts = [m.window_start_block for m in result.models]
    assert starts == list(range(0, 40, 4))
    assert table.loc[20, "window_start_block"] == 0
    assert table.loc[24, "window_start_block"] == 4
    assert table.loc[59, "window_end_block"] == 55
    # the window [24, 43] trains on the Kalman estimates of blocks 24..43
    sub = result.models[6]
    assert (sub.window_start_block, sub.window_end_block) == (24, 43)
    assert sub.n_train == 20


def test_too_few_valid_blocks_falls_back_and_warns():
    modal, predictors, _ = _tables(n_modes=1)
    modal = modal[~modal["block"].between(3, 18)]  # 4 of 20 training blocks left
    with pytest.warns(ForecastWarning, match="too few valid blocks"):
        result = sliding_forecast(
            modal, predictors, ForecastOptions(horizon=30, model="window", scheme=1)
        )
    assert result.models[0].kind == "constant"
    table = result.table
    assert len(table) == 50 and table["kalman_frequency_hz"].notna().all()
    assert table["warning"].str.contains("too few valid blocks").all()
    level = modal.loc[modal["block"] < 20, "frequency_hz"].mean()
    assert table["model_frequency_hz"].to_numpy() == pytest.approx(level)
    FORECAST.validate(table)


def test_last_good_model_reused_when_a_later_window_cannot_be_fitted():
    modal, predictors, _ = _tables(n_blocks=60, n_modes=1)
    predictors.loc[predictors["block"] >= 24, ["water_temp_c", "speed_kn"]] = np.nan
    with pytest.warns(ForecastWarning):
        result = sliding_forecast(
            modal, predictors, ForecastOptions(scheme=2, horizon=4, model="window")
        )
    kinds = [m.kind for m in result.models]
    assert kinds[0] == "stepwise"
    assert "constant" in kinds or "last_good" in kinds
    table = result.table
    assert table["block"].tolist() == list(range(60))
    assert table["model_frequency_hz"].notna().all()
    nan_rows = table[table["block"] >= 24]
    assert nan_rows["warning"].str.len().gt(0).all()
    FORECAST.validate(table)


def test_constant_and_nan_predictors_are_left_out_with_warning():
    modal, predictors, _ = _tables(n_modes=1)
    predictors["speed_kn"] = 12.0  # constant
    predictors["air_temp_c"] = np.nan  # dead channel for the whole voyage
    with pytest.warns(ForecastWarning) as record:
        result = sliding_forecast(
            modal, predictors, ForecastOptions(horizon=20, model="window", scheme=1)
        )
    text = " ".join(str(w.message) for w in record)
    assert "'speed_kn' left out: constant" in text
    assert "'air_temp_c' left out" in text
    assert result.models[0].kind == "stepwise"
    assert set(result.models[0].normalisation) == {"water_temp_c"}


def test_predictor_nan_for_hours_uses_constant_model_for_those_blocks():
    modal, predictors, _ = _tables(n_modes=1)
    predictors.loc[predictors["block"].between(30, 45), "water_temp_c"] = np.nan
    with pytest.warns(ForecastWarning, match="constant model"):
        result = sliding_forecast(
            modal,
            predictors,
            ForecastOptions(
                horizon=40, predictor_columns=["water_temp_c"], model="window", scheme=1
            ),
        )
    table = result.table.set_index("block")
    level = modal.loc[modal["block"] < 20, "frequency_hz"].mean()
    assert table.loc[30:45, "model_frequency_hz"].to_numpy() == pytest.approx(level)
    assert table.loc[30:45, "warning"].str.contains("predictor NaN").all()
    assert table.loc[46, "warning"] == ""
    assert np.isfinite(table["kalman_frequency_hz"]).all()


def test_mode_that_disappears_and_returns_rejoins_its_track():
    modal, predictors, truth = _tables(n_blocks=100, n_modes=2, noise=0.001)
    modal = modal[~((modal["mode"] == 2) & modal["block"].between(25, 64))]
    with pytest.warns(ForecastWarning, match="without SSI"):
        result = sliding_forecast(
            modal, predictors, ForecastOptions(horizon=80, model="window", scheme=1)
        )
    table = result.table[result.table["mode"] == 2].set_index("block")
    assert len(table) == 100
    kalman = table["kalman_frequency_hz"].to_numpy()
    assert np.max(np.abs(np.diff(kalman))) < 0.02  # no jump when estimates return
    assert abs(table.loc[80, "kalman_frequency_hz"] - truth[80, 1]) < 0.005


def test_bad_arguments_raise():
    modal, predictors, _ = _tables()
    with pytest.raises(ValueError, match="option='B' needs poles"):
        sliding_forecast(
            modal, predictors, ForecastOptions(options=("B",), model="window", scheme=1)
        )
    with pytest.raises(
        ValueError,
        match=r"window of 90 blocks and one block to forecast need at least 91 \(train_blocks=90\)",
    ):
        sliding_forecast(
            modal, predictors, ForecastOptions(train_blocks=90, model="window", scheme=1)
        )
    with pytest.raises(ValueError, match="trust=1.5"):
        sliding_forecast(modal, predictors, ForecastOptions(trust=1.5, model="window", scheme=1))
    with pytest.raises(ValueError, match="start_block=7.5"):
        sliding_forecast(
            modal, predictors, ForecastOptions(model="window", scheme=1), start_block=7.5
        )


def test_mode_without_data_at_first_starts_later_and_does_not_disturb_others():
    modal, predictors, _ = _tables(n_blocks=60, n_modes=2)
    reference = _quiet(modal=modal, predictors=predictors, scheme=2, horizon=4)
    late = modal[~((modal["mode"] == 2) & (modal["block"] < 30))]
    with pytest.warns(ForecastWarning, match="no data yet"):
        result = sliding_forecast(
            late, predictors, ForecastOptions(scheme=2, horizon=4, model="window")
        )
    mode_2 = result.table[result.table["mode"] == 2]
    assert mode_2["block"].min() >= 30 and mode_2["block"].max() == 59
    assert np.isfinite(mode_2["kalman_frequency_hz"]).all()
    mode_1 = result.table[result.table["mode"] == 1].reset_index(drop=True)
    expected = reference.table[reference.table["mode"] == 1].reset_index(drop=True)
    assert np.array_equal(mode_1["kalman_frequency_hz"], expected["kalman_frequency_hz"])
    FORECAST.validate(result.table)


# ------------------------------------------ one ForecastOptions, one set of defaults
def _forecast_parser():
    import argparse

    from workbench.cli import build_parser

    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return commands.choices["forecast"]


def test_the_command_line_the_stage_and_sliding_forecast_share_one_set_of_defaults():
    options = ForecastOptions()
    parser = _forecast_parser()
    # the command line's defaults are the options' (scheme by name, option by name)
    assert parser.get_default("scheme") == "rolling" and options.scheme == 2
    assert parser.get_default("option") == "tracked-pole" and options.options == ("A",)
    assert parser.get_default("model") == options.model == "memory"
    assert parser.get_default("train_blocks") == options.train_blocks == 20
    assert parser.get_default("mac_min") == options.mac_min == 0.9
    assert parser.get_default("workers") == options.n_workers == 1
    assert options.horizon_blocks == DEFAULT_HORIZON[2] == 4
    assert replace(options, scheme="single_window").horizon_blocks == DEFAULT_HORIZON[1] == 34
    # a window model with trust "auto" takes the documented default weight on SSI
    assert ForecastOptions(model="window").window_trust == DEFAULT_TRUST == 0.65
    # sliding_forecast without options runs ForecastOptions(): the memory model, rolling
    modal, predictors, _ = _tables(n_blocks=60, n_modes=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plain = sliding_forecast(modal, predictors).table
        explicit = sliding_forecast(modal, predictors, ForecastOptions()).table
    pd.testing.assert_frame_equal(plain, explicit)
    assert "model_probability" in plain.columns  # only the memory model writes it
    # rolling scheme, horizon 4: the last forecast block is the last block of the data
    assert plain["block"].max() == 59


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("train_blocks", 3),
        ("horizon", 0),
        ("trust", 1.5),
        ("gate_sigma", 0.0),
        ("mac_min", 1.0),
        ("reacquire_blocks", 0),
        ("reacquire_band", -0.1),
        ("max_gate", 0.0),
        ("alpha", 1.0),
        ("extrapolation_limit", 0.0),
        ("memory_blocks", 0.0),
        ("selection_blocks", 4),
        ("reselect_blocks", 0),
        ("min_presence", 1.5),
        ("n_workers", 0),
        ("model", "ridge"),
        ("scheme", 3),
    ],
)
def test_a_bad_setting_is_refused_naming_it(name, value):
    with pytest.raises(ValueError) as error:
        ForecastOptions(**{name: value})
    assert str(error.value).startswith(f"{name}={value!r}")


def test_trust_only_for_the_window_model():
    with pytest.raises(ValueError) as error:
        ForecastOptions(model="memory", trust=0.5)
    assert "model='window'" in str(error.value)
    # a number or None given without a model: the window model, the one that takes it
    assert ForecastOptions(trust=0.5).model == "window"
    assert ForecastOptions(trust=None).model == "window"


def test_each_measurement_option_runs_in_turn_into_one_result():
    modal, predictors, _ = _tables(n_blocks=60)
    poles = modal[["block", "frequency_hz", "damping_ratio"]].assign(model_order=20, stable=True)
    both = ForecastOptions(options=("A", "B"), model="window", scheme=1, horizon=40)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        together = sliding_forecast(modal, predictors, both, poles=poles)
        alone = [
            sliding_forecast(modal, predictors, replace(both, options=(o,)), poles=poles)
            for o in ("A", "B")
        ]
    expected = pd.concat([r.table for r in alone], ignore_index=True)
    pd.testing.assert_frame_equal(together.table, expected)
    assert list(together.table["option"].unique()) == ["A", "B"]
    assert len(together.models) == sum(len(r.models) for r in alone) == 4  # 2 modes x 2


def test_the_stage_passes_its_options_to_the_filter_unchanged(monkeypatch):
    """workbench.forecast hands sliding_forecast the caller's ForecastOptions, narrowed to
    one measurement option at a time, not a dict of keywords rebuilt on the way."""
    from workbench.stages import forecast
    from workbench.stages import forecasting as stage

    seen = []
    real = stage.sliding_forecast

    def spy(modal, predictors, options, **run):
        seen.append(options)
        return real(modal, predictors, options, **run)

    monkeypatch.setattr(stage, "sliding_forecast", spy)
    modal, predictors, _ = _tables(n_blocks=60)
    poles = modal[["block", "frequency_hz", "damping_ratio"]].assign(model_order=20, stable=True)
    given = ForecastOptions(
        options=("A", "B"),
        model="window",
        scheme="rolling",
        train_blocks=24,
        gate_sigma=2.5,
        noise=NoiseOptions(huber_sigma=3.0),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = forecast(modal, predictors, poles=poles, options=given)
    assert seen == [replace(given, options=("A",)), replace(given, options=("B",))]
    assert result.options is given
    assert set(result.table["option"]) == {"A", "B"}
