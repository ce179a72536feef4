"""The notebook front door: ``import workbench as wb; wb.fit(...)`` and the stage results.

Statistics results are checked against statsmodels' OLS on the model the stepwise search
selected (an independent implementation of the same estimator), fitted models against
their JSON round trip, and the light import in a fresh interpreter.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

import workbench as wb
from data_contracts import FORECAST, MODAL, PREDICTORS, read_table
from workbench.predictors.directions import with_direction_components

START = pd.Timestamp("2024-03-01T00:00:00Z")


@pytest.fixture(scope="module")
def tables():
    """Block tables with known dependences: mode 1 on speed, water temperature and their
    interaction, mode 2 on speed only, plus noise; 90 blocks on a 5-minute grid."""
    rng = np.random.default_rng(7)
    n = 90
    block = np.arange(n)
    start = START + pd.to_timedelta(block * 5, unit="min")
    speed = 8 + 4 * np.sin(block / 9) + rng.normal(0, 0.4, n)
    water = 4 + 1.5 * np.cos(block / 13) + rng.normal(0, 0.1, n)
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "speed_kn": speed,
            "water_temp_c": water,
            "air_temp_c": water - 3 + rng.normal(0, 0.8, n),
            "wind_speed_ms": rng.gamma(4, 2, n),
            "wind_dir_rel_deg": rng.uniform(0, 360, n),
        }
    )
    rows = []
    for mode, interaction in ((1, 0.003), (2, 0.0)):
        frequency = (
            2.9 * mode
            - 0.012 * speed
            + 0.004 * (water - 4)
            + interaction * speed * (water - 4)
            + rng.normal(0, 0.002, n)
        )
        rows.append(
            pd.DataFrame(
                {
                    "block": block,
                    "block_start": start,
                    "block_end": start + pd.Timedelta(minutes=20),
                    "mode": mode,
                    "frequency_hz": frequency,
                    "damping_ratio": 0.012 + rng.normal(0, 0.0008, n),
                }
            )
        )
    modal = pd.concat(rows, ignore_index=True)
    return MODAL.validate(modal), PREDICTORS.validate(predictors)


def _raw_design(predictors: pd.DataFrame, names) -> pd.DataFrame:
    """Raw-unit design columns of coefficient names like ``speed_kn:water_temp_c``."""
    columns = {}
    for name in names:
        if name == "(Intercept)":
            columns[name] = np.ones(len(predictors))
        else:
            columns[name] = np.prod([predictors[p].to_numpy() for p in name.split(":")], axis=0)
    return pd.DataFrame(columns, index=predictors.index)


def test_import_is_light_and_keeps_the_backend():
    code = (
        "import sys, workbench, workbench.stages\n"
        "heavy = sorted(m for m in ('pandas', 'scipy', 'matplotlib', 'statsmodels', 'dask')"
        " if m in sys.modules)\n"
        "import matplotlib\n"
        "before = matplotlib.get_backend()\n"
        "import workbench.stages.fitting, workbench.stages.correlation,"
        " workbench.stages.forecasting\n"
        "print(heavy, before == matplotlib.get_backend())\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        check=True,
        env={"MPLBACKEND": "svg", "PATH": ""},
    )
    assert done.stdout.split() == ["[]", "True"]


def test_front_door_names(tables):
    for name in ("identify", "track", "correlate", "fit", "forecast", "evaluate", "health"):
        assert callable(getattr(wb, name)), name
    assert wb.track is wb.stages.track
    # the stages are plain functions; no package shares their names (issue 31)

    for name in ("forecast", "identify", "health"):
        assert getattr(wb, name) is getattr(wb.stages, name), name
        assert f"workbench.{name}" not in sys.modules, name
    assert "Sliding forecasts" in wb.forecast.__doc__
    with pytest.raises(AttributeError, match="no_such_stage"):
        wb.no_such_stage  # noqa: B018


def test_fit_reads_like_statsmodels(tables, tmp_path):
    from statsmodels.regression.linear_model import OLS

    modal, predictors = tables
    result = wb.fit(modal, predictors, options=wb.FitOptions(min_presence=0.0))
    assert result.modes == [1, 2]
    one = result[1]
    # the interaction of mode 1 is found (it is in the simulated law)
    assert "speed_kn:water_temp_c" in one.params.index
    rows = predictors.set_index("block").loc[one.resid.index]
    ols = OLS(one.fittedvalues + one.resid, _raw_design(rows, one.params.index)).fit()
    # same estimator, two implementations: agreement to rounding of the solvers
    np.testing.assert_allclose(one.params, ols.params, rtol=1e-8)
    np.testing.assert_allclose(one.bse, ols.bse, rtol=1e-8)
    np.testing.assert_allclose(one.pvalues, ols.pvalues, rtol=1e-6, atol=1e-300)
    np.testing.assert_allclose(one.conf_int(0.1), ols.conf_int(0.1), rtol=1e-8)
    assert one.rsquared == pytest.approx(ols.rsquared, rel=1e-12)
    assert one.rsquared_adj == pytest.approx(ols.rsquared_adj, rel=1e-12)
    assert one.ssr == pytest.approx(ols.ssr, rel=1e-10)
    assert (one.nobs, one.df_resid) == (ols.nobs, ols.df_resid)
    new = predictors.iloc[:5]
    ours = one.get_prediction(new).summary_frame(alpha=0.05)
    theirs = ols.get_prediction(_raw_design(new, one.params.index)).summary_frame(alpha=0.05)
    np.testing.assert_allclose(ours.to_numpy(), theirs[ours.columns].to_numpy(), rtol=1e-8)
    # influence: statsmodels' leverage equals the h of our own prediction intervals
    influence = one.get_influence()
    mean_se = one.get_prediction(rows).se_mean
    np.testing.assert_allclose(
        influence.hat_matrix_diag, (mean_se / np.sqrt(one.mse_resid)) ** 2, rtol=1e-8
    )
    np.testing.assert_allclose(
        influence.cooks_distance[0], ols.get_influence().cooks_distance[0], rtol=1e-8
    )
    # tables across modes: NaN where a term is not in a mode's model
    assert result.params.loc[1, "speed_kn:water_temp_c"] == pytest.approx(
        one.params["speed_kn:water_temp_c"]
    )
    assert np.isnan(result.params.loc[2, "speed_kn:water_temp_c"])
    assert result.rsquared.index.tolist() == [1, 2]
    assert "Mode 1" in one.summary() and "Durbin-Watson" in one.summary()
    figure = result.plot(1)  # residual diagnostics: four panels
    assert len(figure.axes) == 4
    import matplotlib.pyplot as plt

    plt.close(figure)
    page = result._repr_html_()
    assert "<table" in page and "<th>mode</th>" in page.replace("\n", "").replace(" ", "")


def test_fit_saved_as_json_predicts_the_same(tables, tmp_path):
    modal, predictors = tables
    result = wb.fit(modal, predictors, options=wb.FitOptions(min_presence=0.0))
    paths = result.save(tmp_path / "fit", figures=False)
    assert not any(p.suffix in (".pkl", ".pickle") for p in (tmp_path / "fit").iterdir())
    json.loads(paths["json"].read_text())  # strict JSON (no NaN)
    influence = pd.read_csv(paths["influence"])
    assert set(influence["mode"]) == {1, 2}
    assert (influence["leverage"].between(0, 1)).all()
    back = wb.read_fit(tmp_path / "fit")
    assert back.modes == [1, 2]
    new = predictors.iloc[::7]
    for mode in (1, 2):
        a = result[mode].get_prediction(new).summary_frame()
        b = back[mode].get_prediction(new).summary_frame()
        pd.testing.assert_frame_equal(a, b, rtol=1e-13)
        pd.testing.assert_series_equal(result[mode].params, back[mode].params)
    with pytest.raises(ValueError, match="fitted blocks' data"):
        back[1].resid  # noqa: B018
    # the notebook's view (issue 30): modes iterate, a length, pandas out where pandas came
    # in, and a model read back says in one line what it cannot do
    assert list(back) == [1, 2] and len(back) == 2 and 2 in back and 3 not in back
    assert [mode for mode, _ in result.items()] == list(result) == [1, 2]
    predicted = back[2].predict(new)
    assert isinstance(predicted, pd.Series) and predicted.index.equals(new.index)
    np.testing.assert_allclose(predicted, result[2].predict(new), rtol=1e-13)
    # an array holds the model's own columns: the wind direction as its cosine
    inputs = with_direction_components(new)
    assert isinstance(
        back[2].predict(inputs[list(back[2].model.predictor_names)].to_numpy()), np.ndarray
    )
    from workbench.stages import FitDataMissing

    with pytest.raises(FitDataMissing) as caught:
        back[1].fittedvalues  # noqa: B018
    message = str(caught.value)
    assert "\n" not in message and message.startswith("fittedvalues of mode 1")
    assert str(tmp_path / "fit" / "fit.json") in message


def test_correlate_result(tables, tmp_path):
    modal, predictors = tables
    result = wb.correlate(modal, predictors, options=wb.CorrelateOptions(min_presence=0.0))
    r = result.r
    assert r.loc["mode2_frequency_hz", "speed_kn"] < -0.9  # the simulated speed effect
    expected = np.corrcoef(
        modal[modal["mode"] == 2]["frequency_hz"].to_numpy(), predictors["speed_kn"]
    )[0, 1]
    assert r.loc["mode2_frequency_hz", "speed_kn"] == pytest.approx(expected, rel=1e-12)
    assert "useful pairs" in result.summary()
    html = result._repr_html_()
    assert "<table" in html and "correlation" in html
    figure = result.plot("damping_ratio")
    assert figure.axes
    import matplotlib.pyplot as plt

    plt.close(figure)
    paths = result.save(tmp_path / "corr", figures=False)
    assert list(paths) == ["csv", "blocks", "state"] and paths["csv"].is_file()
    # read back as it was computed (what `workbench report` takes from a run)
    back = wb.read_correlation(tmp_path / "corr")
    pd.testing.assert_frame_equal(back.table, result.table)
    pd.testing.assert_frame_equal(back.effective(), result.effective())
    pd.testing.assert_frame_equal(back.predictors, result.predictors)
    assert back.options == result.options


def test_track_forecast_evaluate_on_a_simulated_voyage(tmp_path):
    from workbench.simulate import simulate_voyage
    from workbench.stages import relabel_truth as evaluate_truth

    voyage = simulate_voyage(tmp_path / "voyage", seed=4, hours=4, accelerations=False)
    truth = read_table(voyage.truth_modal, MODAL)
    imitated = read_table(voyage.tracked_modal, MODAL)
    tracked = wb.track(imitated.drop(columns=["mode", "mac"]))
    assert tracked.table["mode"].nunique() == 7
    assert str(tracked).startswith("7 modes tracked over")
    saved = tracked.save(tmp_path / "out")["tracked"]
    pd.testing.assert_frame_equal(read_table(saved, MODAL), tracked.table, check_dtype=False)
    predictors = wb.canonical_predictors(wb.load_predictors(predictors=voyage.truth_predictors))
    result = wb.forecast(
        tracked.table,
        predictors,
        options=wb.ForecastOptions(options=("tracked_pole",), scheme="rolling", trust=0.65),
    )
    FORECAST.validate(result.table)
    assert result.options.options == ("A",) and result.options.scheme == 2
    path = result.save(tmp_path / "out")["forecast"]
    assert path.name == "forecast.csv"
    evaluation = wb.evaluate(result.table, truth)
    assert len(evaluation.mapping) == 7
    totals = evaluation.table[["ssi_cumulative_error_hz", "kalman_cumulative_error_hz"]].sum()
    assert totals["kalman_cumulative_error_hz"] < totals["ssi_cumulative_error_hz"]
    assert "option A: cumulative |error|" in evaluation.summary()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for figure in (evaluation.plot(), tracked.plot()):
        assert len(figure.axes[0].patches) + len(figure.axes[0].lines) >= 7
        plt.close(figure)
    figure = result.plot(4, truth=evaluate_truth(truth, evaluation.mapping))
    assert figure.axes and figure.axes[0].lines
    plt.close(figure)


def test_health_stage_returns_the_charts_result(tmp_path):
    """wb.health returns the chart's own result (one type per stage): the same table as
    health_chart, its summary and tables saved."""
    from workbench.shm import HealthOptions, HealthResult, health_chart
    from workbench.simulate import law_forecast, simulate_health_voyage

    voyage = simulate_health_voyage(
        24, seed=0, damaged_mode=3, stiffness_loss=0.02, damage_after_hours=16
    )
    forecast = law_forecast(voyage)
    options = HealthOptions(reference_blocks=96)
    result = wb.health(forecast, options=options)
    assert type(result) is HealthResult
    chart = health_chart(forecast, options)
    pd.testing.assert_frame_equal(result.table, chart.table)
    assert len(result.alarms) >= 1  # the 2 % stiffness loss on mode 3
    text = str(result.summary())
    assert text.splitlines()[0].startswith("Structural-health chart") and "alarm 1:" in text
    paths = result.save(tmp_path)
    assert sorted(paths) == ["alarms", "health"] and paths["health"].is_file()


def test_forecast_options_are_checked():
    with pytest.raises(ValueError, match="option"):
        wb.ForecastOptions(options=("C",))
    with pytest.raises(ValueError, match="train_blocks"):
        wb.ForecastOptions(train_blocks=1)
    with pytest.raises(ValueError, match="p_enter"):
        wb.FitOptions(p_enter=0.2, p_remove=0.1)


def test_summary_has_a_text_and_an_html_view():
    """A summary is shown as HTML in a notebook and as text by print (issue 30: before, a
    plain string that the notebook showed quoted, newlines escaped)."""
    from workbench.stages import Summary

    table = pd.DataFrame({"r_squared": [0.95, 0.5]}, index=pd.Index([1, 2], name="mode"))
    summary = Summary("models <per mode>", ["2 modes fitted", "warning: a & b"], [("", table)])
    text = str(summary)
    assert text.splitlines()[:2] == ["2 modes fitted", "warning: a & b"]
    assert "0.95" in text and repr(summary) == text and "2 modes fitted" in summary
    page = summary._repr_html_()
    assert "models &lt;per mode&gt;" in page and "warning: a &amp; b" in page
    assert page.count("<tr") == 4  # the header, the index name row and two modes
