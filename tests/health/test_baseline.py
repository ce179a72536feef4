"""A saved health baseline: an earlier voyage's model and limits chart a new voyage from
its first block; a baseline of another ship, or a damaged file, is refused in one line.

The earlier voyage is 48 h of :func:`workbench.simulate.simulate_health_voyage` (seed 1): a
36-h model (its operating cycles at several fuel states) and a 6-h reference, as
``workbench health --train-hours 36 --reference-hours 6 --save-model`` fits them.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from data_contracts import HEALTH, MODAL, PREDICTORS, read_table, shapes_to_frame, write_table
from workbench.cli import main
from workbench.monitor.outlook import ForecastSettings
from workbench.monitor.structural_health import operational_health
from workbench.shm import (
    BaselineError,
    HealthBaseline,
    HealthOptions,
    fit_operational_model,
    health_chart,
)
from workbench.simulate import detection_delay_hours, simulate_health_voyage

CHANNELS = tuple(f"acc{k:02d}" for k in range(1, 9))
TRAIN, REFERENCE = 432, 72  # 36 h and 6 h of 5-min steps


def _with_shapes(modal: pd.DataFrame) -> pd.DataFrame:
    """*modal* with a fixed mode shape per label (the block-level voyage has none)."""
    x = (np.arange(len(CHANNELS)) + 0.5) / len(CHANNELS)
    shapes = np.array([np.cos(m * np.pi * x) for m in modal["mode"]], dtype=complex)
    table = pd.concat(
        [modal.reset_index(drop=True), shapes_to_frame(list(CHANNELS), shapes)], axis=1
    )
    return MODAL.validate(table.assign(mac=1.0))


@pytest.fixture(scope="module")
def earlier():
    voyage = simulate_health_voyage(48, seed=1)
    modal = _with_shapes(voyage.modal)
    model = fit_operational_model(modal, voyage.predictors, train_blocks=TRAIN)
    forecast = model.forecast(
        modal, voyage.predictors, reference_start_block=TRAIN, reference_blocks=REFERENCE
    )
    chart = health_chart(
        forecast, HealthOptions(reference_blocks=REFERENCE, reference_start_block=TRAIN)
    )
    baseline = HealthBaseline.from_chart(modal, voyage.predictors, model, chart, step_s=300.0)
    return voyage, modal, baseline


@pytest.fixture(scope="module")
def damaged():
    # a new voyage: 2 % stiffness loss on mode 3 six hours in
    voyage = simulate_health_voyage(
        12, seed=2, damaged_mode=3, stiffness_loss=0.02, damage_after_hours=6
    )
    return voyage, _with_shapes(voyage.modal)


def test_saved_baseline_charts_a_new_voyage_from_its_first_block(earlier, damaged, tmp_path):
    _, _, baseline = earlier
    voyage, modal = damaged
    path = baseline.save(tmp_path / "ship.baseline.json")
    loaded = HealthBaseline.load(path)
    chart = loaded.chart(loaded.forecast(modal, voyage.predictors))
    health = chart.table
    # every block charted, from the first, none spent on a model or a reference
    assert health["block"].min() == modal["block"].min() == 0
    assert health["block"].nunique() == modal["block"].nunique()
    assert set(health["phase"]) == {"monitor"}
    # the loss is found (2.58 h when written; the voyage's own chart would start at 18 h,
    # after the loss, and learn it into its model)
    assert detection_delay_hours(voyage, health) <= 3.0
    assert chart.alarms["top_mode"].iloc[0] == 3
    assert not health.loc[health["block_start"] < voyage.damage_time, "alarm"].any()
    # the file holds what the chart needs, exactly (JSON round trip)
    again = baseline.chart(baseline.forecast(modal, voyage.predictors))
    pd.testing.assert_frame_equal(again.table, health)
    np.testing.assert_array_equal(loaded.model.coefficients, baseline.model.coefficients)
    assert loaded.reference.mode_limits.tolist() == baseline.reference.mode_limits.tolist()


def test_no_false_alarm_in_a_quiet_day_with_the_baseline(earlier):
    _, _, baseline = earlier
    quiet = simulate_health_voyage(24, seed=3)
    chart = baseline.chart(baseline.forecast(_with_shapes(quiet.modal), quiet.predictors))
    assert len(chart.table) == quiet.modal["block"].nunique()
    assert chart.alarms.empty


def test_the_monitor_charts_from_block_one_with_a_baseline(earlier, damaged, tmp_path):
    _, _, baseline = earlier
    voyage, modal = damaged
    path = str(baseline.save(tmp_path / "ship.baseline.json"))
    settings = ForecastSettings(health_baseline=path)
    # the first hour, as the monitor has it then (the ship log averaged onto its blocks)
    first_hour = modal[modal["block"] < 12]
    log = voyage.predictors[voyage.predictors["block"] < 12]
    health, alarms, notes = operational_health(first_hour, log, settings, 300.0)
    assert health["block"].tolist() == list(range(12)) and alarms.empty
    assert notes[0].startswith("health: charting from block 0 (20") and path in notes[0]
    # without it: learning, and the note says when the chart starts (12 h + 6 h)
    own = ForecastSettings()
    health, _, notes = operational_health(first_hour, log, own, 300.0)
    start = modal["block_start"].min() + pd.Timedelta(hours=18)
    assert health is None
    assert f"the chart starts at block 216 ({start:%Y-%m-%d %H:%M}Z)" in notes[0]
    assert notes[1] == "health: learning, 12 of 217 blocks"


def test_a_baseline_of_another_ship_is_refused_in_one_line(earlier, damaged, tmp_path):
    _, _, baseline = earlier
    voyage, modal = damaged
    path = baseline.save(tmp_path / "ship.baseline.json")
    loaded = HealthBaseline.load(path)
    # other modes: every frequency 15 % higher
    other = modal.assign(frequency_hz=modal["frequency_hz"] * 1.15)
    with pytest.raises(BaselineError) as caught:
        loaded.check_modes(other, "other.parquet")
    message = str(caught.value)
    assert message.startswith(f"{path}: mode 1 is ") and "other.parquet" in message
    # labels that are none of the baseline's
    with pytest.raises(BaselineError, match="none of the baseline's modes 1, 2, 3"):
        loaded.check_modes(modal.assign(mode=modal["mode"] + 20), "other.parquet")
    # a ship log without a column the model needs
    with pytest.raises(BaselineError, match="'fuel_on_board_t', which log.tsv does not"):
        loaded.check_predictors(voyage.predictors.drop(columns="fuel_on_board_t"), "log.tsv")
    # other sensors
    with pytest.raises(BaselineError, match=r"baseline only: acc08; ship2 only: acc09"):
        loaded.check_channels([*CHANNELS[:-1], "acc09"], "ship2")
    for error in (caught.value,):
        assert "\n" not in str(error)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda c: c.update(version=2), "'version': 2; this workbench reads version 1"),
        (lambda c: c.update(schema="x"), "'schema': 'x'"),
        (lambda c: c["model"].pop("coefficients"), "'model.coefficients': missing"),
        (lambda c: c["model"]["coefficients"].pop(), "'model.coefficients': shape (6, 7)"),
        (lambda c: c["model"].update(modes=[1, 2, 99]), "'model.modes': mode(s) [99]"),
        (lambda c: c["modes"][0].update(frequency_hz="2.9"), "'modes[0].frequency_hz'"),
        (lambda c: c["chart"]["options"].update(ewma_lambda=3), "'chart.options': ewma_lambda"),
        (lambda c: c["chart"]["reference"].pop("limit"), "'chart.reference.limit': missing"),
        (lambda c: c["grid"].update(step_s=-300), "'grid.step_s': must be a positive"),
    ],
)
def test_a_damaged_baseline_file_names_the_field(earlier, tmp_path, edit, field):
    _, _, baseline = earlier
    content = baseline.to_json()
    edit(content)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(content))
    with pytest.raises(BaselineError) as caught:
        HealthBaseline.load(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: field ") and field in message
    assert "\n" not in message


def test_cli_save_model_then_chart_a_new_voyage_from_block_one(earlier, damaged, tmp_path, capsys):
    old, old_modal, _ = earlier
    voyage, modal = damaged
    files = {
        "old_modal": write_table(old_modal, tmp_path / "old_modal.parquet", MODAL),
        "old_predictors": write_table(old.predictors, tmp_path / "old_pred.csv", PREDICTORS),
        "modal": write_table(modal, tmp_path / "modal.parquet", MODAL),
        "predictors": write_table(voyage.predictors, tmp_path / "pred.csv", PREDICTORS),
    }
    saved = tmp_path / "ship.baseline.json"
    status = main(
        ["health", "--modal", str(files["old_modal"]), "--predictors", str(files["old_predictors"]),
         "--train-hours", "36", "--reference-hours", "6", "--save-model", str(saved),
         "--out", str(tmp_path / "old")]
    )  # fmt: skip
    assert status == 0 and json.loads(saved.read_text())["schema"] == "workbench.shm.baseline"
    capsys.readouterr()
    out = tmp_path / "new"
    status = main(
        ["health", "--baseline", str(saved), "--modal", str(files["modal"]),
         "--predictors", str(files["predictors"]), "--out", str(out)]
    )  # fmt: skip
    assert status == 0
    health = read_table(out / "health.csv", HEALTH)
    assert health["block"].iloc[0] == 0 and set(health["phase"]) == {"monitor"}
    assert "charting from block 0" in capsys.readouterr().out
    # another ship's modes: exit 1, one line naming the baseline
    other = write_table(
        modal.assign(frequency_hz=modal["frequency_hz"] * 1.15), tmp_path / "o.parquet", MODAL
    )
    status = main(
        ["health", "--baseline", str(saved), "--modal", str(other),
         "--predictors", str(files["predictors"]), "--out", str(out)]
    )  # fmt: skip
    error = capsys.readouterr().err.strip()
    assert status == 1 and len(error.splitlines()) == 1 and str(saved) in error
    # usage: the baseline fixes the training hours
    status = main(
        ["health", "--baseline", str(saved), "--modal", str(files["modal"]),
         "--predictors", str(files["predictors"]), "--train-hours", "12", "--out", str(out)]
    )  # fmt: skip
    assert status == 2 and "--train-hours cannot be used with --baseline" in capsys.readouterr().err


def test_live_tracking_from_the_baseline_modes_equals_batch_track(earlier, damaged, tmp_path):
    """The monitor's tracker starts from the baseline's modes (labels kept): block by
    block it equals ``workbench track --reference-modes BASELINE.json``."""
    from workbench.monitor.tracking import IncrementalTracking
    from workbench.sid.tracking import TrackingOptions
    from workbench.stages import track

    _, _, baseline = earlier
    voyage, modal = damaged
    path = baseline.save(tmp_path / "ship.baseline.json")
    # the new voyage's selected modes, in another order than the baseline's labels
    selected = modal.drop(columns=["mode", "mac"]).sample(frac=1.0, random_state=4)
    live = IncrementalTracking(TrackingOptions(), HealthBaseline.load(path).modes)
    blocks = sorted(selected["block"].unique())
    for block in blocks:
        live.add(int(block), selected[selected["block"] == block])
    live.advance({int(b) for b in blocks})
    table = live.table()
    batch = track(selected, reference_modes=path).table
    pd.testing.assert_frame_equal(table, batch.reset_index(drop=True), check_like=False)
    # the labels are the earlier voyage's: each within 2 % of the baseline's frequency
    # (other operating conditions; mode 3 is 1 % lower after its stiffness loss), while
    # neighbouring modes are 5 % or more apart
    medians = table.groupby("mode")["frequency_hz"].median()
    known = baseline.modes.set_index("mode")["frequency_hz"]
    assert sorted(medians.index) == list(range(1, 8))
    assert np.allclose(medians / known[medians.index], 1.0, atol=0.02)
    assert [e["labelled_block"] for e in live.shown_labels()] == [-1] * 7
