"""Adaptive block length (identify --block-minutes auto): the length plan, the grid of
varying length, predictors over each block's own span and excitation, the CLI's usage
errors, and tracking and forecasting of blocks of varying length."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from data_contracts import MODAL, recorded_grid, set_grid
from data_contracts.grid import grid_mismatch, grid_record
from workbench.errors import OptionError
from workbench.identification.adaptive import AdaptiveBlockOptions, plan_block_lengths

T0 = pd.Timestamp("2024-03-01T00:00:00Z")
HALF = pd.Timedelta(seconds=150)


def _conditions(power_db: np.ndarray, speed: np.ndarray) -> pd.DataFrame:
    start = T0 + HALF * np.arange(power_db.size)
    return pd.DataFrame(
        {
            "start": start,
            "end": start + HALF,
            "power": 1e-5 * 10 ** (power_db / 10),
            "speed_kn": speed,
        }
    )


def _centres_s(plan: pd.DataFrame) -> np.ndarray:
    start = (plan["block_start"] - T0).dt.total_seconds().to_numpy()
    end = (plan["block_end"] - T0).dt.total_seconds().to_numpy()
    return (start + end) / 2


def test_lengths_are_odd_multiples_of_the_step_within_the_limits():
    assert AdaptiveBlockOptions().lengths() == (2100.0, 1500.0, 900.0, 300.0)
    assert AdaptiveBlockOptions(min_length_s=600, max_length_s=1200).lengths() == (900.0,)
    with pytest.raises(OptionError, match="min_length_s=100"):
        AdaptiveBlockOptions(min_length_s=100)
    with pytest.raises(OptionError, match="holds no odd multiple"):
        AdaptiveBlockOptions(min_length_s=1000, max_length_s=1100)


def test_ice_gets_short_blocks_and_calm_water_long_ones():
    """2 h of calm open water (steady 10 kn, excitation within 0.3 dB) then 2 h of ice
    (excitation jumping by several dB from half-step to half-step, ramming 2-5 kn)."""
    rng = np.random.default_rng(3)
    n = 96  # 4 h of 2.5-min half-steps
    calm = np.arange(n) < 48
    power_db = np.where(calm, 0.3 * rng.random(n), 5.0 + 4.0 * rng.standard_normal(n))
    speed = np.where(calm, 10.0 + 0.1 * rng.standard_normal(n), 3.5 + 1.5 * rng.standard_normal(n))
    plan = plan_block_lengths(_conditions(power_db, speed), T0)
    centre = _centres_s(plan)
    # every block centred in the middle of a step: t0 + 2.5 min + k x 5 min
    np.testing.assert_allclose(centre, 150.0 + 300.0 * plan["block"].to_numpy())
    in_calm = (plan["block_end"] <= T0 + pd.Timedelta(hours=2)).to_numpy()
    in_ice = (plan["block_start"] >= T0 + pd.Timedelta(hours=2)).to_numpy()
    # calm: 35 min wherever it fits inside the data and the calm stretch
    fits = (centre >= 1050) & (centre <= 7200 - 1050)
    assert set(plan.loc[fits, "block_length_s"]) == {2100.0}
    assert plan.loc[in_calm, "excitation_range_db"].max() < 0.5
    # ice: the shortest blocks
    assert set(plan.loc[in_ice, "block_length_s"]) == {300.0}
    # the blocks reach the ends of the data (the 5-min blocks are the 5-min grid's)
    assert plan["block_start"].min() == T0
    assert plan["block_end"].max() == T0 + pd.Timedelta(hours=4)
    assert plan["block"].is_monotonic_increasing and plan["block"].is_unique


def test_speed_changes_and_state_changes_shorten_blocks():
    n = 48  # 2 h, steady excitation
    power_db = np.zeros(n)
    speed = np.where(np.arange(n) < 24, 0.0, 10.0)  # 0 -> 10 kn at 1 h
    plan = plan_block_lengths(_conditions(power_db, speed), T0)
    change = T0 + pd.Timedelta(hours=1)
    straddles = (plan["block_start"] < change) & (plan["block_end"] > change)
    assert (plan.loc[straddles, "block_length_s"] == 300.0).all()
    assert (plan.loc[straddles, "speed_range_kn"] == 10.0).all()
    # without a speed change, a change of state alone keeps blocks apart
    cases = pd.DataFrame(
        {"case": ["transit", "ice"], "start": [T0, change], "end": [change, T0 + 2 * (change - T0)]}
    )
    plan = plan_block_lengths(_conditions(power_db, np.full(n, 5.0)), T0, cases=cases)
    straddles = (plan["block_start"] < change) & (plan["block_end"] > change)
    assert (plan.loc[straddles, "block_length_s"] == 300.0).all()
    assert plan.loc[~straddles, "block_length_s"].max() == 2100.0


def test_a_varying_length_grid_checks_the_centres():
    grid = {"t0": T0, "length_s": 300.0, "step_s": 300.0, "varying_length": True}
    assert grid_record(grid)["varying_length"] is True
    assert "varying_length" not in grid_record({**grid, "varying_length": False})
    frame = pd.DataFrame(  # centres 2.5, 7.5, 17.5 min: blocks 0, 1, 3
        {
            "block": [0, 1, 3],
            "block_start": T0 + pd.to_timedelta([0, 0, 300], unit="s"),
            "block_end": T0 + pd.to_timedelta([300, 900, 1800], unit="s"),
        }
    )
    assert grid_mismatch(frame, grid) is None
    shifted = frame.assign(block_end=frame["block_end"] + pd.Timedelta(seconds=60))
    assert "block 0" in grid_mismatch(shifted, grid)
    # a fixed grid refuses the same table: its lengths differ
    assert grid_mismatch(frame, {**grid, "varying_length": False}) is not None


def test_excitation_weighted_predictors_read_the_block_as_ssi_does():
    """One 20-min block: 10 min at 0 kn with power 1, 10 min at 10 kn with power 9. The
    plain mean is 5 kn, the excitation-weighted one (0 x 1 + 10 x 9) / 10 = 9 kn."""
    from workbench.predictors import block_predictors, excitation_weighted_predictors

    seconds = np.arange(1200)
    log = pd.DataFrame(
        {
            "time": T0 + pd.to_timedelta(seconds, unit="s"),
            "speed_kn": np.where(seconds < 600, 0.0, 10.0),
            "water_temp_c": np.where(seconds < 600, 2.0, 4.0),
        }
    )
    blocks = pd.DataFrame({"block": [0], "block_start": [T0], "block_end": [T0 + 8 * HALF]})
    start = T0 + HALF * np.arange(8)
    excitation = pd.DataFrame(
        {"start": start, "end": start + HALF, "power": np.where(np.arange(8) < 4, 1.0, 9.0)}
    )
    with pytest.warns(UserWarning):  # the log lacks the other canonical columns
        plain = block_predictors(log, blocks=blocks, despike=False)
        weighted = excitation_weighted_predictors(log, blocks, excitation, despike=False)
    assert plain["speed_kn"].iat[0] == pytest.approx(5.0)
    assert weighted["speed_kn"].iat[0] == pytest.approx(9.0)
    assert weighted["water_temp_c"].iat[0] == pytest.approx((2.0 * 1 + 4.0 * 9) / 10)


def _varying_modal(n_blocks: int = 40) -> pd.DataFrame:
    """A tracked table of two modes on blocks of 5-35 min centred mid-step."""
    rng = np.random.default_rng(0)
    lengths = rng.choice([300.0, 900.0, 1500.0, 2100.0], n_blocks)
    centre = T0 + pd.to_timedelta(1050.0 + 300.0 * np.arange(n_blocks), unit="s")
    start = centre - pd.to_timedelta(lengths / 2, unit="s")
    rows = []
    for k in range(n_blocks):
        for mode, f, shape in ((1, 2.0, (1.0, 0.5, 0.0)), (2, 3.5, (0.0, -0.5, 1.0))):
            rows.append(
                {
                    **{f"shape_re_{c}": v for c, v in zip("abc", shape, strict=True)},
                    **{f"shape_im_{c}": 0.0 for c in "abc"},
                    "block": k,
                    "block_start": start[k],
                    "block_end": start[k] + pd.Timedelta(seconds=lengths[k]),
                    "mode": mode,
                    "frequency_hz": f * (1 + 0.001 * rng.standard_normal()),
                    "damping_ratio": 0.01,
                    "block_length_s": lengths[k],
                }
            )
    table = MODAL.validate(pd.DataFrame(rows))
    grid = {"t0": T0 + pd.Timedelta(seconds=900), "length_s": 300.0, "step_s": 300.0}
    return set_grid(table, {**grid, "varying_length": True})


def test_predictors_are_averaged_over_each_blocks_own_span(tmp_path):
    from workbench.predictors import load_predictors

    modal = _varying_modal()
    seconds = np.arange(0, 4 * 3600)
    speed = seconds / 600.0  # a steady ramp: a span's mean is its centre's value
    log = tmp_path / "dship.tsv"
    pd.DataFrame(
        {
            "Date/Time": (T0 + pd.to_timedelta(seconds, unit="s")).strftime("%Y-%m-%dT%H:%M:%S"),
            "Speed [kn]": speed,
            "Temp [°C]": np.where(seconds % 60 == 0, 2.0, np.nan),
        }
    ).to_csv(log, index=False, sep="\t")
    with pytest.warns(UserWarning):  # no air temperature or wind in the log
        table = load_predictors(dship=log, onto=modal, all_predictors=True)
    spans = modal.drop_duplicates("block").set_index("block")
    start = (spans["block_start"] - T0).dt.total_seconds().to_numpy()
    end = (spans["block_end"] - T0).dt.total_seconds().to_numpy()
    expected = ((start + end - 1) / 2) / 600.0  # mean of the whole seconds in [start, end)
    np.testing.assert_allclose(table.set_index("block")["speed_kn"].to_numpy(), expected)
    np.testing.assert_array_equal(table["block_end"].to_numpy(), spans["block_end"].to_numpy())
    assert recorded_grid(table)["varying_length"] is True


def test_tracking_and_forecast_take_blocks_of_varying_length():
    """Track the varying-length blocks (spans and lengths kept), then forecast them: the
    block times the forecast counts in are the regular centres."""
    from workbench.forecasting.excitation import sub_windows_per_block
    from workbench.sid.tracking import TrackingOptions, track_modes

    modal = _varying_modal()
    selected = modal.drop(columns="mode")
    selected["mpc"] = 0.95
    tracked = track_modes(selected, options=TrackingOptions())
    assert tracked["mode"].nunique() == 2
    assert len(tracked) >= 2 * 40 - 4  # every block but the first few (confirmation)
    spans = modal[["block", "block_start", "block_end", "block_length_s"]].drop_duplicates("block")
    merged = tracked.merge(spans, on="block", suffixes=("", "_in"))
    np.testing.assert_array_equal(merged["block_start"], merged["block_start_in"])
    np.testing.assert_allclose(merged["block_length_s"], merged["block_length_s_in"])
    # the forecast's overlap model needs blocks of one length: none for varying lengths
    assert sub_windows_per_block(modal.drop_duplicates("block")) is None
    fixed = modal.drop_duplicates("block").copy()
    fixed["block_start"] = T0 + pd.to_timedelta(300.0 * fixed["block"], unit="s")
    fixed["block_end"] = fixed["block_start"] + pd.Timedelta(seconds=1200)
    assert sub_windows_per_block(fixed) == 4


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--block-minutes", "abc"], "'abc' is not a number of minutes or 'auto'"),
        (["--block-minutes", "-5"], "positive number of minutes or 'auto'"),
        (["--block-minutes", "nan"], "positive number of minutes or 'auto'"),
        (["--block-minutes", "auto", "--step-minutes", "45"], "min_length_s=2700"),
        (["--cases", "cases.csv"], "--cases is used with --block-minutes auto only"),
    ],
)
def test_bad_block_minutes_are_usage_errors(tmp_path, capsys, flags, message):
    from workbench.cli import main

    code = main(["identify", str(tmp_path), "--out", str(tmp_path / "out"), *flags])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert "Traceback" not in err


def test_forecast_of_blocks_of_varying_length_follows_the_speed_law():
    """Frequencies f0 (1 - 0.003 v) with 0.05 % identification noise on blocks of 5-35 min,
    the speed averaged over each block's own span: the forecast's model and Kalman
    estimate are closer to the law than the identified frequencies (each block counted
    as one step of the regular block times)."""
    from data_contracts import PREDICTORS
    from workbench.forecasting import sliding_forecast
    from workbench.forecasting.options import ForecastOptions

    rng = np.random.default_rng(1)
    modal = _varying_modal(80)
    spans = modal.drop_duplicates("block")[["block", "block_start", "block_end"]]
    spans = spans.reset_index(drop=True)
    centre_s = ((spans["block_start"] - T0) + (spans["block_end"] - T0)).dt.total_seconds() / 2
    speed = 5.0 + 5.0 * np.sin(2 * np.pi * centre_s.to_numpy() / 5400.0)
    n = len(spans)
    predictors = spans.assign(
        speed_kn=speed,
        water_temp_c=2.0 + 0.1 * rng.standard_normal(n),
        air_temp_c=rng.standard_normal(n),
        wind_speed_ms=5.0 + rng.standard_normal(n),
        wind_dir_rel_deg=rng.uniform(0, 360, n),
    )
    predictors = PREDICTORS.validate(predictors)
    law = {1: 2.0, 2: 3.5}
    by_block = pd.Series(speed, index=spans["block"])
    for mode, f0 in law.items():
        rows = modal["mode"] == mode
        v = by_block.reindex(modal.loc[rows, "block"]).to_numpy()
        noise = 1 + 0.0005 * rng.standard_normal(rows.sum())
        modal.loc[rows, "frequency_hz"] = f0 * (1 - 0.003 * v) * noise
    options = ForecastOptions(options=("A",), scheme=2, train_blocks=20, horizon=4, model="window")
    table = sliding_forecast(modal, predictors, options).table
    table = table[table["phase"] == "forecast"]
    assert set(table["block"]) <= set(spans["block"])
    for mode, f0 in law.items():
        part = table[table["mode"] == mode]
        assert len(part) >= 20
        truth = f0 * (1 - 0.003 * by_block.reindex(part["block"]).to_numpy())
        ssi = np.median(np.abs(part["ssi_frequency_hz"] / truth - 1))
        model = np.median(np.abs(part["model_frequency_hz"] / truth - 1))
        kalman = np.median(np.abs(part["kalman_frequency_hz"] / truth - 1))
        assert model < 0.6 * ssi
        assert kalman < ssi


def test_joins_check_the_centres_of_blocks_of_varying_length():
    from workbench.errors import WorkbenchError
    from workbench.joins import check_block_grid, check_block_times

    modal = _varying_modal()
    check_block_grid(modal, "modal.csv")  # starts off any grid, centres on it
    fixed = modal.assign(block_end=modal["block_start"] + pd.Timedelta(seconds=300))
    with pytest.raises(WorkbenchError, match="off the grid") as error:
        check_block_grid(fixed, "modal.csv")
    assert "modal.csv: block" in str(error.value)
    spans = modal[["block", "block_start", "block_end"]].drop_duplicates("block")
    check_block_times(modal, "modal.csv", spans, "predictors.csv")
    shifted = spans.assign(block_end=spans["block_end"] + pd.Timedelta(seconds=600))
    with pytest.raises(WorkbenchError, match="predictors.csv: block"):
        check_block_times(modal, "modal.csv", shifted, "predictors.csv")
    # a table with starts only (a forecast) cannot be placed on a grid of varying length
    grid = {"t0": T0, "length_s": 300.0, "step_s": 300.0, "varying_length": True}
    assert grid_mismatch(spans.drop(columns="block_end"), grid) is None


def test_conditions_of_recorded_files_give_long_calm_and_short_impact_blocks(tmp_path):
    """Twelve 5-min files at 16 Hz: 40 min of steady broadband excitation, then 20 min
    of ice-like excitation whose level jumps by 6-12 dB from file to file. The half-steps
    conditioned as identify conditions blocks give 35-min blocks in the steady part and
    5-min blocks where the level jumps."""
    from data_contracts import AccelerationRecord, write_accelerations
    from workbench.identification import IdentifyOptions
    from workbench.identification.adaptive import block_conditions
    from workbench.identification.planning import acceleration_files, plan_identification

    rng = np.random.default_rng(7)
    rate, seconds = 16.0, 300
    gains = [1.0] * 8 + [2.0, 8.0, 3.0, 12.0]
    for k, gain in enumerate(gains):
        start = T0 + pd.Timedelta(seconds=k * seconds)
        data = gain * 0.01 * rng.standard_normal((int(rate * seconds), 4))
        record = AccelerationRecord(data, rate, start, ("a", "b", "c", "d"))
        write_accelerations(record, tmp_path / f"acc_{k:02d}.npz")
    options = IdentifyOptions(length_s=300.0, step_s=300.0)
    plan, resolved = plan_identification(acceleration_files([tmp_path]), options)
    conditions = block_conditions(plan, resolved)
    assert len(conditions) == 24 and conditions["speed_kn"].isna().all()
    ratio = conditions["power"].iloc[20] / conditions["power"].iloc[2]  # 3rd ice file vs calm
    assert ratio == pytest.approx(9.0, rel=0.15)
    plan_table = plan_block_lengths(conditions, T0)
    calm = plan_table["block_end"] <= T0 + pd.Timedelta(minutes=40)
    ice = plan_table["block_start"] >= T0 + pd.Timedelta(minutes=40)
    assert plan_table.loc[calm, "block_length_s"].max() == 2100.0
    assert set(plan_table.loc[ice, "block_length_s"]) == {300.0}
    assert (plan_table.loc[ice, "excitation_range_db"] < 0.5).all()  # one file each


def _write_voyage(folder, gains, rate=16.0, seconds=300, seed=7):
    """5-min files of two resonances (2.0 and 3.1 Hz, 2 % damping) driven by white noise
    scaled by *gains* (one per file), on four channels with 5 % sensor noise."""
    from scipy.signal import lfilter

    from data_contracts import AccelerationRecord, write_accelerations

    rng = np.random.default_rng(seed)
    n = int(rate * seconds) * len(gains)
    drive = rng.standard_normal((n, 2)) * np.repeat(gains, int(rate * seconds))[:, None]
    modal = np.empty_like(drive)
    for j, f in enumerate((2.0, 3.1)):
        pole = np.exp((-0.02 + 1j) * 2 * np.pi * f / rate)
        modal[:, j] = lfilter([1.0], [1.0, -2 * pole.real, abs(pole) ** 2], drive[:, j])
    shapes = np.array([[1.0, 0.6, -0.4, 0.2], [0.3, -0.8, 0.5, 1.0]])
    data = modal @ shapes
    data += 0.05 * data.std() * rng.standard_normal(data.shape)
    per_file = int(rate * seconds)
    for k in range(len(gains)):
        record = AccelerationRecord(
            data[k * per_file : (k + 1) * per_file],
            rate,
            T0 + pd.Timedelta(seconds=k * seconds),
            ("a", "b", "c", "d"),
        )
        write_accelerations(record, folder / f"acc_{k:02d}.npz")


def test_identify_auto_end_to_end(tmp_path, capsys):
    """``workbench identify --block-minutes auto`` on 40 steady minutes and 20 minutes of
    level jumps: 35-min blocks where steady, 5-min blocks in the jumps, both resonances
    found in every block, tables merged on the varying-length grid; a rerun resumes."""
    from data_contracts import SELECTED, read_table
    from workbench.cli import main

    _write_voyage(tmp_path, [1.0] * 8 + [2.0, 8.0, 3.0, 12.0])
    out = tmp_path / "out"
    argv = ["identify", str(tmp_path), "--out", str(out), "--block-minutes", "auto"]
    argv += ["--scheduler", "synchronous", "--max-order", "16", "--band", "0.5", "6", "-q"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "block lengths (auto):" in printed
    blocks = pd.read_csv(out / "blocks.csv", parse_dates=["block_start"])
    assert (blocks["status"] == "ok").all()
    steady = blocks["block_start"] + pd.to_timedelta(blocks["block_length_s"], unit="s")
    calm = (steady <= T0 + pd.Timedelta(minutes=40)).to_numpy()
    assert blocks.loc[calm, "block_length_s"].max() == 2100.0
    jumps = (blocks["block_start"] >= T0 + pd.Timedelta(minutes=40)).to_numpy()
    assert set(blocks.loc[jumps, "block_length_s"]) == {300.0}
    selected = read_table(out / "selected.parquet", SELECTED)
    assert recorded_grid(selected)["varying_length"] is True
    for _, part in selected.groupby("block"):
        f = np.sort(part["frequency_hz"].to_numpy())
        assert np.min(np.abs(f - 2.0)) < 0.02 and np.min(np.abs(f - 3.1)) < 0.03
    np.testing.assert_allclose(
        (selected["block_end"] - selected["block_start"]).dt.total_seconds(),
        selected["block_length_s"],
    )
    assert main(argv) == 0
    assert "0 block(s) processed" in capsys.readouterr().out
