"""HealthMonitor: block-by-block updates and JSON state give the batch chart's tables."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from data_contracts import ALARMS
from workbench.shm import HealthMonitor, HealthOptions, health_chart
from workbench.simulate import law_forecast, simulate_health_voyage

#: 6-h reference from the first block; 16-h voyage, 3 % stiffness loss on mode 3 at 11 h
#: (large enough that every variant, the 4-h following baseline too, raises an episode)
OPTIONS = HealthOptions(reference_blocks=72, reference_start_block=0)


@pytest.fixture(scope="module")
def damaged_forecast():
    voyage = simulate_health_voyage(
        16, seed=0, damaged_mode=3, stiffness_loss=0.03, damage_after_hours=11
    )
    return law_forecast(voyage)


def _feed(forecast, options, tmp_path, restart_every=None):
    monitor = HealthMonitor(options)
    health, alarms = [], {}
    for k, (_, rows) in enumerate(forecast.groupby("block")):
        if restart_every and k % restart_every == 0:
            # a restart from the saved state, as after a kill of the live monitor
            monitor = HealthMonitor.load_state(monitor.save_state(tmp_path / "state.json"))
        update = monitor.update(rows)
        health.append(update.health)
        for row in update.alarms.to_dict("records"):
            alarms[row["alarm"]] = row
    table = pd.concat([h for h in health if len(h)], ignore_index=True)
    return monitor, table, ALARMS.validate(pd.DataFrame(list(alarms.values())))


@pytest.mark.parametrize(
    "options",
    [
        OPTIONS,  # per-mode CUSUM, fixed reference location
        dataclasses.replace(OPTIONS, baseline_hours=4.0),  # CUSUM, following baseline
        dataclasses.replace(OPTIONS, statistic="mewma"),  # MEWMA T²
    ],
    ids=["cusum", "cusum-baseline", "mewma"],
)
def test_block_by_block_with_restarts_gives_the_batch_tables(damaged_forecast, tmp_path, options):
    batch = health_chart(damaged_forecast, options)
    assert len(batch.alarms) >= 1  # the test must see an episode grow and close
    assert batch.alarms["top_mode"].iloc[0] == 3
    monitor, table, alarms = _feed(damaged_forecast, options, tmp_path, restart_every=7)
    # the reference is learned from the same blocks with the same seeded bootstrap
    assert monitor.reference.limit == batch.reference.limit
    np.testing.assert_array_equal(monitor.reference.location, batch.reference.location)
    # one row per block, in order; the T² of one row and of the whole matrix may differ
    # in the last bits (matrix products are summed in another order)
    pd.testing.assert_frame_equal(table, batch.table, check_exact=False, rtol=1e-12, atol=0)
    assert table["alarm"].tolist() == batch.table["alarm"].tolist()
    pd.testing.assert_frame_equal(
        alarms.reset_index(drop=True), batch.alarms, check_exact=False, rtol=1e-12
    )


def test_state_is_plain_json_and_rows_come_once_in_order(damaged_forecast, tmp_path):
    blocks = damaged_forecast.groupby("block")
    monitor = HealthMonitor(OPTIONS)
    first = monitor.update(pd.concat([blocks.get_group(b) for b in range(50)]))
    assert first.health.empty  # reference (72 blocks) not complete yet
    path = monitor.save_state(tmp_path / "state.json")
    state = json.loads(path.read_text())  # strict JSON: no NaN tokens, no pickle
    assert state["reference"] is None and len(state["pending"]) == 50
    monitor = HealthMonitor.load_state(path)
    second = monitor.update(pd.concat([blocks.get_group(b) for b in range(50, 80)]))
    assert second.health["block"].tolist() == list(range(80))
    assert (second.health["phase"] == "reference").sum() == 72
    with pytest.raises(ValueError, match="block 60 arrives after block 79"):
        monitor.update(blocks.get_group(60))
    (tmp_path / "bad.json").write_text('{"version": 99}')
    with pytest.raises(ValueError, match="version 99"):
        HealthMonitor.load_state(tmp_path / "bad.json")
