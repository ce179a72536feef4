"""``workbench health``: files written, exit statuses 0 / 1 (bad data) / 2 (usage)."""

from __future__ import annotations

import pytest

from data_contracts import ALARMS, FORECAST, HEALTH, read_table, write_table
from workbench.cli import main
from workbench.simulate import law_forecast, simulate_health_voyage


@pytest.fixture(scope="module")
def forecast_file(tmp_path_factory):
    voyage = simulate_health_voyage(
        24, seed=0, damaged_mode=3, stiffness_loss=0.02, damage_after_hours=16
    )
    path = tmp_path_factory.mktemp("health") / "forecast.csv"
    return write_table(law_forecast(voyage), path, FORECAST)


def test_health_writes_tables_and_summary(forecast_file, tmp_path, capsys):
    out = tmp_path / "out"
    status = main(
        ["health", "--forecast", str(forecast_file), "--reference-hours", "12",
         "--reference-start-block", "0", "--out", str(out)]
    )  # fmt: skip
    assert status == 0
    health = read_table(out / "health.csv", HEALTH)
    alarms = read_table(out / "alarms.csv", ALARMS)
    assert (health["phase"] == "reference").sum() == 144
    assert alarms["top_mode"].iloc[-1] == 3
    assert "alarm episode" in capsys.readouterr().out


def test_health_reports_bad_data_and_usage_in_one_line(forecast_file, tmp_path, capsys):
    too_long = ["--reference-hours", "30", "--out", str(tmp_path)]
    assert main(["health", "--forecast", str(forecast_file), *too_long]) == 1
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "forecast.csv" in error and "360 blocks" in error
    bad_lambda = ["--ewma-lambda", "2", "--out", str(tmp_path)]
    assert main(["health", "--forecast", str(forecast_file), *bad_lambda]) == 2
    assert "--ewma-lambda 2.0 must be in (0, 1]" in capsys.readouterr().err
    assert main(["health", "--forecast", str(tmp_path / "none.csv"), "--out", "x"]) == 1


@pytest.mark.parametrize(
    "flag, value, says",
    [
        ("--false-alarms-per-day", "inf", "--false-alarms-per-day inf must be finite"),
        ("--false-alarms-per-day", "nan", "--false-alarms-per-day nan must be finite"),
        ("--reference-start-block", "-5", "--reference-start-block -5 must be a block number"),
    ],
)
def test_health_refuses_a_chart_option_without_meaning(
    forecast_file, tmp_path, capsys, flag, value, says
):
    # an infinite false-alarm rate has no limit to read, and a reference period that
    # starts before block 0 would quietly start at the first block instead
    out = tmp_path / "out"
    assert main(["health", "--forecast", str(forecast_file), flag, value, "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and says in error
    assert not out.exists()


def test_health_fits_its_own_model_from_modal_and_predictors(tmp_path, capsys):
    from data_contracts import MODAL, PREDICTORS

    voyage = simulate_health_voyage(24, seed=1)
    modal = write_table(voyage.modal, tmp_path / "modal.csv", MODAL)
    predictors = write_table(voyage.predictors, tmp_path / "predictors.csv", PREDICTORS)
    out = tmp_path / "out"
    status = main(
        ["health", "--modal", str(modal), "--predictors", str(predictors),
         "--train-hours", "12", "--reference-hours", "6", "--out", str(out)]
    )  # fmt: skip
    assert status == 0
    health = read_table(out / "health.csv", HEALTH)
    # 12 h of training (144 blocks), then 6 h of reference (72 blocks)
    assert health["block"].iloc[0] == 144
    assert (health["phase"] == "reference").sum() == 72
    assert "modes charted: 1, 2, 3, 4, 5, 6, 7" in capsys.readouterr().out
    assert main(["health", "--modal", str(modal), "--out", str(out)]) == 2
    assert "--modal needs --predictors and --train-hours" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("flags", "options"),
    [
        (["--statistic", "mewma"], {"statistic": "mewma"}),
        (["--baseline-hours", "24"], {"baseline_hours": 24.0}),
    ],
)
def test_health_flags_reach_the_chart(forecast_file, tmp_path, flags, options):
    """--statistic and --baseline-hours give the chart the library computes with the same
    options (and a chart that differs from the default one)."""
    from workbench.shm import HealthOptions
    from workbench.stages import health

    common = {"reference_blocks": 144, "reference_start_block": 0}
    out = tmp_path / "out"
    argv = ["health", "--forecast", str(forecast_file), "--reference-hours", "12",
            "--reference-start-block", "0", *flags, "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    written = read_table(out / "health.csv", HEALTH)
    forecast = read_table(forecast_file, FORECAST)
    expected = health(forecast, options=HealthOptions(**common, **options)).table
    default = health(forecast, options=HealthOptions(**common)).table
    assert written["statistic"].to_numpy() == pytest.approx(
        expected["statistic"].to_numpy(), rel=1e-9, nan_ok=True
    )
    assert written["statistic"].to_numpy() != pytest.approx(
        default["statistic"].to_numpy(), rel=1e-6, nan_ok=True
    )


def test_health_refuses_a_baseline_that_is_not_positive(forecast_file, tmp_path, capsys):
    argv = ["health", "--forecast", str(forecast_file), "--baseline-hours", "-1",
            "--out", str(tmp_path)]  # fmt: skip
    assert main(argv) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "--baseline-hours -1.0 must be positive" in error
