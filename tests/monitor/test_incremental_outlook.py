"""The monitor's outlook resumed from update to update equals the batch forecast and health
chart (``workbench forecast`` + ``workbench health`` over the same tables), also across a
restart from the saved state and after a changed input of a committed block."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from data_contracts import MODAL, PREDICTORS
from workbench.forecasting.incremental import IncrementalMemoryForecast, NeedsFullHistory
from workbench.forecasting.options import ForecastOptions
from workbench.monitor.incremental import IncrementalOutlook, supported
from workbench.monitor.outlook import ForecastSettings, forecast_table
from workbench.monitor.structural_health import operational_health
from workbench.predictors.tables import canonical_predictors

STEP_S = 300.0
#: Health model on the first 4 h, reference the next 2 h: the chart starts at block 72.
SETTINGS = ForecastSettings(health_train_hours=4.0, reference_hours=2.0)


def voyage(
    n_blocks: int = 170, seed: int = 3, halves: bool = False
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Block-level tables of a voyage: 20-min blocks every 5 min, speed changes, three
    modes following speed and water temperature with AR(1) identification errors and
    missing estimates, a fourth seen in a fifth of the blocks (not forecast), and mode 2
    dropping 5 % from block 80 (an alarm). With *halves*, the blocks' half differences
    (identify's ``half_difference_hz``, each half twice the block's error variance) from a
    random stream of their own, and blocks that share no data (5 minutes every 5): the
    forecast's SSI guard runs there."""
    rng = np.random.default_rng(seed)
    length_s = STEP_S if halves else 4 * STEP_S
    block = np.arange(n_blocks)
    start = pd.Timestamp("2026-03-01T00:00:00Z") + pd.to_timedelta(block * STEP_S, unit="s")
    speed = np.clip(10 + np.cumsum(rng.normal(0, 0.4, n_blocks)), 2, 16)
    water = 4 + 0.5 * np.sin(block / 40.0) + rng.normal(0, 0.02, n_blocks)
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(seconds=length_s),
            "speed_kn": speed,
            "water_temp_c": water,
            "air_temp_c": 2 + rng.normal(0, 0.3, n_blocks),
            "wind_speed_ms": 8 + rng.normal(0, 1, n_blocks),
            "wind_dir_rel_deg": (90 + np.cumsum(rng.normal(0, 5, n_blocks))) % 360,
        }
    )
    rows = []
    base = {1: 2.9, 2: 4.6, 3: 5.4, 4: 7.1}
    error = np.zeros(4)
    for k in range(n_blocks):
        error = 0.65 * error + rng.normal(0, 0.003, 4)
        for j, mode in enumerate(base):
            seen = rng.random() < (0.2 if mode == 4 else 0.9)
            if not seen:
                continue
            f = base[mode] * (1 - 0.004 * (speed[k] - 10) + 0.002 * (water[k] - 4))
            if mode == 2 and k >= 80:
                f *= 0.95
            rows.append(
                {
                    "block": k,
                    "block_start": start[k],
                    "block_end": start[k] + pd.Timedelta(seconds=length_s),
                    "mode": mode,
                    "frequency_hz": f * (1 + error[j]),
                    "damping_ratio": 0.01 + 0.001 * rng.random(),
                }
            )
    modal = pd.DataFrame(rows)
    if halves:
        draw = np.random.default_rng(seed + 100).standard_normal(len(modal))
        modal["half_difference_hz"] = 2 * 0.003 * modal["frequency_hz"] * draw
    return MODAL.validate(modal), PREDICTORS.validate(predictors)


def batch(modal: pd.DataFrame, predictors: pd.DataFrame):
    """What ``update_outlook`` recomputed at every update (the batch stages)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        forecast, _ = forecast_table(modal, canonical_predictors(predictors), SETTINGS)
        health, alarms, _ = operational_health(modal, predictors, SETTINGS, STEP_S)
    return forecast, health, alarms


def feed(outlook, modal, predictors, last, final_through):
    """One update with the tables up to block *last*, from the block the state needs."""
    start = outlook.inputs_from
    part = predictors[predictors["block"] <= last]
    try:
        return outlook.update(
            modal[modal["block"] <= last],
            part if start is None else part[part["block"] >= start],
            first_block=0,
            final_through=final_through,
        )
    except NeedsFullHistory:
        return outlook.update(
            modal[modal["block"] <= last], part, first_block=0, final_through=final_through
        )


def assert_equal_to_batch(found, modal, predictors) -> None:
    forecast, health, alarms = batch(modal, predictors)
    # round-off only: the state carries the same arithmetic, in the same order
    pd.testing.assert_frame_equal(found.forecast, forecast, rtol=1e-9)
    pd.testing.assert_frame_equal(found.health.reset_index(drop=True), health, rtol=1e-9)
    pd.testing.assert_frame_equal(found.alarms.reset_index(drop=True), alarms, rtol=1e-9)


@pytest.mark.parametrize("halves", [False, True])
def test_resumed_outlook_equals_batch_with_restart_and_changed_input(tmp_path, halves):
    modal, predictors = voyage(halves=halves)
    outlook = IncrementalOutlook(SETTINGS, STEP_S)
    found = None
    for last in range(30, 170, 11):
        found = feed(outlook, modal, predictors, last, final_through=last - 2)
        if last == 107:  # the monitor stops and starts again: the state is read back
            assert outlook.save(tmp_path / "outlook")
            outlook = IncrementalOutlook.load(
                tmp_path / "outlook",
                SETTINGS,
                STEP_S,
                forecast=found.forecast,
                health=found.health,
            )
            assert outlook.inputs_from is not None and outlook.inputs_from > 60
        if last == 140:  # a committed block's estimate changes (a late assignment)
            row = modal.index[(modal["block"] == 134) & (modal["mode"] == 1)][0]
            modal.loc[row, "frequency_hz"] *= 1.002
    found = feed(outlook, modal, predictors, 169, final_through=169)
    assert outlook.forecast.rollbacks >= 1  # the change took the state back, not to block 0
    assert set(found.forecast["mode"]) == {1, 2, 3}  # mode 4: seen in too few blocks
    assert len(found.alarms) >= 1  # mode 2's drop is charted
    assert_equal_to_batch(found, modal, predictors)
    if halves:  # the guard ran, and drew some estimates toward SSI
        weight = found.forecast["guard_weight"]
        assert weight.notna().all() and (weight < 1).any()
    else:
        assert found.forecast["guard_weight"].isna().all()


def test_every_block_and_partial_windows_equal_batch():
    modal, predictors = voyage(100, seed=5)
    outlook = IncrementalOutlook(SETTINGS, STEP_S)
    found = feed(outlook, modal, predictors, 70, final_through=None)  # nothing final yet
    for last in range(71, 100):  # one block at a time, the newest predictors provisional
        found = feed(outlook, modal, predictors, last, final_through=last - 1)
        if last in (80, 99):
            assert_equal_to_batch(
                found, modal[modal["block"] <= last], predictors[predictors["block"] <= last]
            )


def test_state_needs_the_first_blocks_to_start_over():
    modal, predictors = voyage(60)
    engine = IncrementalMemoryForecast(ForecastOptions(train_blocks=20))
    engine.update(modal, predictors, modes=[1, 2, 3], final_through=59)
    assert engine.inputs_from is not None and engine.inputs_from > 20
    late = predictors[predictors["block"] >= 40]
    with pytest.raises(NeedsFullHistory) as caught:
        engine.update(modal, late, modes=[1, 3], final_through=59)  # another set of modes
    assert "block 0" in str(caught.value)


def test_settings_carried_or_batch():
    assert supported(ForecastSettings())
    assert not supported(ForecastSettings(forecast=ForecastOptions(options=("A", "B"))))
    assert not supported(ForecastSettings(forecast=ForecastOptions(model="window", trust=0.65)))
    assert not supported(ForecastSettings(health_model="forecast"))
    with pytest.raises(ValueError, match="batch"):
        IncrementalOutlook(ForecastSettings(forecast=ForecastOptions(scheme=1)), STEP_S)


def _worker_restarted(voyage, batch, state, monkeypatch, before_restart=None):
    """``update_outlook`` (the monitor's worker) over *state* with the tracked table up to
    block 12, then, as a new worker process (after *before_restart* of *state*, if given),
    with the whole table; the second update's report."""
    from data_contracts import write_table
    from workbench.blocks import BlockGrid
    from workbench.monitor import outlook as worker
    from workbench.monitor.outlook import update_outlook

    monkeypatch.setattr(worker, "FINAL_AFTER_S", 0.0)  # a 1.5-h log: commit what it covers
    tracked = MODAL.validate(batch["tracked"])
    first = tracked[tracked["block"] == tracked["block"].min()].iloc[0]
    length = (first["block_end"] - first["block_start"]).total_seconds()
    grid = BlockGrid(first["block_start"], length, 300.0)
    settings = ForecastSettings(forecast=ForecastOptions(train_blocks=6))
    state.mkdir()
    for last in (12, int(tracked["block"].max())):  # a restart between the two
        worker._OUTLOOKS.clear()  # a new worker process
        worker._WRITERS.clear()
        if last > 12 and before_restart is not None:
            before_restart(state)
        write_table(tracked[tracked["block"] <= last], state / "tracked.parquet", MODAL)
        report = update_outlook(state, voyage / "dship.tsv", settings, grid)
        assert report.written and report.forecast_rows > 0
    return report


def test_update_outlook_takes_up_the_saved_state_after_a_restart(
    voyage, batch, tmp_path, monkeypatch
):
    """``update_outlook`` (the monitor's worker) over a state folder, stopped and started
    again: the second process takes up ``<state>/outlook/`` and the forecast equals the
    batch ``workbench forecast`` of the whole tracked table."""
    loads = []
    real_load = IncrementalOutlook.load.__func__

    def counted(cls, *args, **kwargs):
        outlook = real_load(cls, *args, **kwargs)
        loads.append(outlook.forecast.inputs_from)  # where the loaded state resumes
        return outlook

    monkeypatch.setattr(IncrementalOutlook, "load", classmethod(counted))
    state = tmp_path / "state"
    _worker_restarted(voyage, batch, state, monkeypatch)
    # the saved state taken up: the forecast resumed from its newest committed window
    assert len(loads) == 1 and loads[0] is not None and loads[0] > 6
    forecast = pd.read_parquet(state / "forecast.parquet")
    pd.testing.assert_frame_equal(forecast, batch["forecast"], rtol=1e-9)


def test_forecast_equals_batch_after_the_oldest_rows_are_dropped():
    """With a short memory (history 60 blocks) the state drops its oldest rows as the voyage
    grows (constant size); the forecast still equals the batch memory forecast."""
    from workbench.forecasting.memory.forecast import memory_forecast
    from workbench.forecasting.options import NoiseOptions

    modal, predictors = voyage(400, seed=3)
    options = ForecastOptions(
        train_blocks=20,
        memory_blocks=10.0,
        selection_blocks=40,
        reselect_blocks=12,
        noise=NoiseOptions(noise_blocks=40),
    )
    engine = IncrementalMemoryForecast(options, snapshots=4)
    modes = [1, 2, 3]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for last in (*range(30, 400, 7), 399):
            start = engine.inputs_from or 0
            part = predictors[(predictors["block"] <= last) & (predictors["block"] >= start)]
            table, _ = engine.update(
                modal[modal["block"] <= last], part, modes=modes, final_through=last - 1
            )
        expected = memory_forecast(
            modal, predictors, options, poles=None, modes=modes, start_block=None, end_block=None
        ).table
    assert engine._core.base_block > 100  # the rows before it were dropped
    assert engine.inputs_from > 350  # the last update was given its newest 50 blocks only
    expected = expected.sort_values(["block", "mode"], kind="stable").reset_index(drop=True)
    assert len(table) == 1200
    pd.testing.assert_frame_equal(table, expected, rtol=1e-9)


def test_forecast_equals_batch_when_the_speed_never_changes():
    """A voyage held at one speed: the batch leaves the excitation term out (no block has
    a within-block speed variance), the resumed forecast carries it with zero variance,
    which gives it no weight: the same table."""
    from workbench.forecasting.memory.forecast import memory_forecast

    modal, predictors = voyage(120, seed=5)
    predictors = predictors.assign(speed_kn=11.0)
    options = ForecastOptions(train_blocks=20)
    engine = IncrementalMemoryForecast(options)
    modes = [1, 2, 3]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for last in (*range(30, 120, 9), 119):
            table, _ = engine.update(
                modal[modal["block"] <= last],
                predictors[predictors["block"] <= last],
                modes=modes,
                final_through=last - 1,
            )
        expected = memory_forecast(
            modal, predictors, options, poles=None, modes=modes, start_block=None, end_block=None
        ).table
    assert engine._core.has_speed_var  # the resumed run kept the term
    expected = expected.sort_values(["block", "mode"], kind="stable").reset_index(drop=True)
    assert len(table) == 3 * 120
    pd.testing.assert_frame_equal(table, expected, rtol=1e-9)


@pytest.mark.parametrize("step", [1, 5])
def test_forecast_equals_batch_across_a_log_outage(step):
    """A 40-min outage of every log column (blocks 99-105 without predictors, 97-98 and
    106-107 logged by 75 % / 50 %; the wind speed's own shares differ: 98 and 106 by
    75 %, 107 fully): the partly logged blocks at its edges get a model variance from
    the blocks that share data with them, the newer ones included, so an update whose new
    blocks miss a predictor takes the state back to before the partly logged blocks the
    batch widens: the resumed forecast equals the batch one, with the same edge rows and
    each column's own share in their warnings (the checkpoint keeps them per column)."""
    from workbench.forecasting.memory.forecast import memory_forecast

    modal, predictors = voyage(170, seed=3)
    columns = ["speed_kn", "water_temp_c", "air_temp_c", "wind_speed_ms", "wind_dir_rel_deg"]
    predictors.loc[predictors["block"].between(99, 105), columns] = np.nan
    coverage = pd.Series(1.0, index=predictors.index)
    for block, share in ((97, 0.75), (98, 0.5), (106, 0.5), (107, 0.75)):
        coverage[predictors["block"] == block] = share
    coverage[predictors["block"].between(99, 105)] = 0.25
    shares = {f"log_coverage_{c}": coverage for c in columns}
    wind = coverage.copy()
    for block, share in ((98, 0.75), (106, 0.75), (107, 1.0)):
        wind[predictors["block"] == block] = share
    shares["log_coverage_wind_speed_ms"] = wind
    least = pd.concat(shares, axis=1).min(axis=1)
    predictors = PREDICTORS.validate(predictors.assign(log_coverage=least, **shares))
    options = ForecastOptions(train_blocks=20)
    engine = IncrementalMemoryForecast(options)
    modes = [1, 2, 3]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for last in (*range(30, 170, step), 169):
            start = engine.inputs_from or 0
            part = predictors[(predictors["block"] <= last) & (predictors["block"] >= start)]
            table, _ = engine.update(
                modal[modal["block"] <= last], part, modes=modes, final_through=last - 1
            )
        expected = memory_forecast(
            modal, predictors, options, poles=None, modes=modes, start_block=None, end_block=None
        ).table
    expected = expected.sort_values(["block", "mode"], kind="stable").reset_index(drop=True)
    edges = expected["warning"].fillna("").str.contains("edge of a log outage")
    assert set(expected.loc[edges, "block"]) == {97, 98, 106, 107}
    # each partly logged column the model uses named with its own share, and the least
    # share (mode 3: the speed and, by chance, the wind speed - the wind direction before it
    # entered as its cosine; 107's wind speed fully logged)
    third = expected[expected["mode"] == 3].set_index("block")["warning"]
    for block, named in (
        (97, "speed_kn 75%, wind_speed_ms 75%; log_coverage 75%"),
        (98, "speed_kn 50%, wind_speed_ms 75%; log_coverage 50%"),
        (106, "speed_kn 50%, wind_speed_ms 75%; log_coverage 50%"),
        (107, "speed_kn 75%; log_coverage 75%"),
    ):
        assert f"partly logged ({named})" in third.loc[block], (block, third.loc[block])
    assert engine.rollbacks >= 1  # the outage's first missing block took the state back
    # (the resumed table carries the log's coverage, memory_forecast's does not)
    pd.testing.assert_frame_equal(table.drop(columns="log_coverage"), expected, rtol=1e-9)


def test_update_outlook_computes_again_over_a_checkpoint_of_an_older_layout(
    voyage, batch, tmp_path, monkeypatch
):
    """A saved outlook of an older checkpoint layout (/5 kept one ``log_coverage`` per
    block, not one per column) is not
    half-read: the worker says so and computes the forecast again from the first block,
    equal to the batch forecast."""
    import json

    from workbench.forecasting.incremental import CHECKPOINT_SCHEMA

    def older_layout(state):  # the state as a monitor of the previous layout left it
        saved = state / "outlook" / "outlook.json"
        document = json.loads(saved.read_text())
        assert document["schema"] == CHECKPOINT_SCHEMA
        document["schema"] = "workbench.forecasting.incremental/5"
        saved.write_text(json.dumps(document))

    state = tmp_path / "state"
    report = _worker_restarted(voyage, batch, state, monkeypatch, older_layout)
    assert any(
        "incremental/5" in m and "computed again from the first block" in m for m in report.messages
    ), report.messages
    forecast = pd.read_parquet(state / "forecast.parquet")
    pd.testing.assert_frame_equal(forecast, batch["forecast"], rtol=1e-9)


def test_resumed_outlook_forecasts_across_a_hole_in_the_accelerations():
    """A recorder off for 7.5 h (blocks 75-164 of 170 without data: no tracked row, after
    the health chart's reference period) leaves modes 1-3 in about 90 % of the 80 tracked
    blocks but 42 % of the grid: the forecast counts presence over the tracked blocks, as
    the batch forecast does (main: no mode measured in 50 % of the blocks, no forecast)."""
    modal, predictors = voyage()
    hole = (modal["block"] >= 75) & (modal["block"] < 165)
    modal = modal[~hole].reset_index(drop=True)
    assert modal["block"].nunique() == 80
    assert modal.groupby("mode")["block"].nunique().max() / 170 < 0.5
    outlook = IncrementalOutlook(SETTINGS, STEP_S)
    for last in (30, 74, 100, 166):
        feed(outlook, modal, predictors, last, final_through=last - 2)
    found = feed(outlook, modal, predictors, 169, final_through=169)
    assert not [m for m in found.messages if "no mode is measured" in m]
    assert set(found.forecast["mode"]) == {1, 2, 3}  # mode 4: seen in too few blocks
    # the hole's blocks are predict-only rows, then the forecast goes on with SSI
    inside = found.forecast[found.forecast["block"].between(75, 164)]
    assert len(inside) == 3 * 90 and inside["ssi_frequency_hz"].isna().all()
    assert found.forecast["block"].max() == 169
    assert_equal_to_batch(found, modal, predictors)
