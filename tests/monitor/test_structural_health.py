"""The monitor's health chart: the operational model fitted on the first hours, charted."""

from __future__ import annotations

import dataclasses

import pandas as pd
import pytest

from workbench.monitor.outlook import ForecastSettings
from workbench.monitor.structural_health import operational_health
from workbench.simulate import detection_delay_hours, simulate_health_voyage

#: 24 h model, 12 h reference: the chart starts 36 h into the voyage
SETTINGS = ForecastSettings(health_train_hours=24.0, reference_hours=12.0)


@pytest.fixture(scope="module")
def damaged():
    # 2 % stiffness loss on mode 3 at 44 h, 8 h after the chart starts
    return simulate_health_voyage(
        48, seed=2, damaged_mode=3, stiffness_loss=0.02, damage_after_hours=44
    )


def test_learning_first_then_the_chart_finds_the_loss_with_and_without_fuel(damaged):
    short = damaged.modal[damaged.modal["block"] < 300]
    health, alarms, notes = operational_health(short, damaged.predictors, SETTINGS, 300.0)
    assert health is None and alarms is None
    start = damaged.modal["block_start"].min() + pd.Timedelta(hours=36)
    assert notes == [
        f"health: the chart starts at block 432 ({start:%Y-%m-%d %H:%M}Z), after this "
        "voyage's 24-h model and 12-h reference; with a saved baseline (monitor --baseline) it "
        "starts at the first block",
        "health: learning, 300 of 433 blocks",
    ]

    # with the tank soundings: fuel is a model term, the baseline stays fixed
    health, alarms, notes = operational_health(damaged.modal, damaged.predictors, SETTINGS, 300.0)
    assert health["block"].min() == 288 and (health["phase"] == "reference").sum() == 144
    assert health.loc[health["phase"] == "monitor", "block"].min() == 432
    assert notes[0].startswith("health: charting from block 432 (")
    assert not any("fuel_on_board_t" in n for n in notes)
    delay = detection_delay_hours(damaged, health)
    assert delay <= 2.0  # 1.08 h when written (the goal: within 2 h)
    assert alarms["top_mode"].iloc[0] == 3
    before = health[health["block_start"] < damaged.damage_time]
    assert not before["alarm"].any()

    # no soundings in the log: the 24-h baseline follows the fuel burn, the loss is found
    no_fuel = damaged.predictors.drop(columns="fuel_on_board_t")
    health, alarms, notes = operational_health(damaged.modal, no_fuel, SETTINGS, 300.0)
    assert (
        "health: no fuel_on_board_t in the ship log; the fuel burn is followed by a 24-h baseline"
        in notes
    )
    assert detection_delay_hours(damaged, health) <= 3.0
    assert alarms["top_mode"].iloc[0] == 3
    assert not health.loc[health["block_start"] < damaged.damage_time, "alarm"].any()


def test_settings_are_checked():
    with pytest.raises(ValueError, match="health_model='stepwise'"):
        ForecastSettings(health_model="stepwise")
    with pytest.raises(ValueError, match="baseline_hours=-1"):
        dataclasses.replace(SETTINGS, baseline_hours=-1.0)
