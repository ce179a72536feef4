"""``workbench monitor --baseline``: a health baseline of another ship is refused at the
start, in one line naming the file (issue 29)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from data_contracts import MODAL, shapes_to_frame
from workbench.shm import HealthBaseline, HealthOptions, fit_operational_model, health_chart
from workbench.simulate import simulate_health_voyage

from .conftest import IDENTIFY, MONITOR_FAST, cli


def _other_ship(fuel: bool) -> HealthBaseline:
    """A baseline of a ship with sensors acc01..acc08 (the monitored voyage has acc01,
    acc04, acc08, acc12, acc15 and acc18), with or without tank soundings in its log (the
    monitored voyage's log has none)."""
    voyage = simulate_health_voyage(24, seed=1)
    predictors = voyage.predictors if fuel else voyage.predictors.drop(columns="fuel_on_board_t")
    channels = [f"acc{k:02d}" for k in range(1, 9)]
    x = (np.arange(8) + 0.5) / 8
    shapes = np.array([np.cos(m * np.pi * x) for m in voyage.modal["mode"]], dtype=complex)
    modal = MODAL.validate(
        pd.concat([voyage.modal, shapes_to_frame(channels, shapes)], axis=1).assign(mac=1.0)
    )
    model = fit_operational_model(modal, predictors, train_blocks=144)
    forecast = model.forecast(modal, predictors, reference_start_block=144, reference_blocks=72)
    chart = health_chart(forecast, HealthOptions(reference_blocks=72, reference_start_block=144))
    return HealthBaseline.from_chart(modal, predictors, model, chart, step_s=300.0)


def _once(voyage, state, *extra) -> int:
    return cli(
        "monitor", "--watch", voyage / "accelerations", "--state", state,
        "--dship", voyage / "dship.tsv", *IDENTIFY, *MONITOR_FAST, "--once", *extra,
    )  # fmt: skip


def test_a_baseline_of_another_ship_is_refused_in_one_line(voyage, tmp_path, capsys):
    # its model needs the fuel on board, which this ship's log does not have
    path = _other_ship(fuel=True).save(tmp_path / "fuel.baseline.json")
    assert _once(voyage, tmp_path / "state", "--baseline", path) == 1
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1
    assert f"{path}: model term 'fuel_on_board_t' needs column 'fuel_on_board_t'" in error
    # other sensors: refused when the first file fixes the voyage's channels
    other_ship = _other_ship(fuel=False)
    path = other_ship.save(tmp_path / "other.baseline.json")
    assert _once(voyage, tmp_path / "state1", "--baseline", path) == 1
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and f"{path}: channels differ" in error
    assert "baseline only: acc02,acc03,acc05,acc06,acc07; " in error
    assert not (tmp_path / "state1" / "store" / "blocks").exists()  # nothing identified
    # a damaged file: the field is named, nothing started
    content = other_ship.to_json()
    content["model"]["residual_std"] = "0.01"
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps(content))
    assert _once(voyage, tmp_path / "state2", "--baseline", broken) == 1
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and f"{broken}: field 'model.residual_std'" in error
