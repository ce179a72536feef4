"""MATLAB parity of workbench.stats.stepwise beyond the Hald path: categorical terms,
squares, per-candidate missing rows, the exact-fit guard, raw-unit offsets, the R²
criteria and the 'Lower' model.

Published values are quoted as printed on the cited MathWorks documentation pages and
compared to print precision (half a unit of the last printed digit, ``assert_printed``).
The data are MATLAB's carbig/carsmall, rebuilt from the UCI Auto MPG data in
``tests/reference/carbig.csv`` (source and reconstruction in its header; carsmall is the
model years 70, 76 and 82 of carbig). The reconstruction is checked by MATLAB's own
fitlm output before anything else relies on it.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm

from workbench.stats import stepwise

REFERENCE = Path(__file__).resolve().parents[1] / "reference"

# the Hald data and the print-precision check live beside the Hald path test
_spec = importlib.util.spec_from_file_location(
    "_stepwise_tests", Path(__file__).with_name("test_stepwise.py")
)
_hald = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_hald)
HALD_X, HALD_Y, assert_printed = _hald.HALD_X, _hald.HALD_Y, _hald.assert_printed


@pytest.fixture(scope="module")
def carbig() -> pd.DataFrame:
    return pd.read_csv(REFERENCE / "carbig.csv", comment="#")


@pytest.fixture(scope="module")
def carsmall(carbig) -> pd.DataFrame:
    return carbig[carbig["Model_Year"].isin([70, 76, 82])].reset_index(drop=True)


# --------------------------------------------------------------------------- fitlm
def test_carsmall_reconstruction_matches_matlab_fitlm(carsmall):
    # https://mathworks.com/help/stats/fitlm.html, "Fit Linear Regression Using Data in
    # Matrix": mdl = fitlm([Weight,Horsepower,Acceleration], MPG) prints
    assert len(carsmall) == 100
    X = carsmall[["Weight", "Horsepower", "Acceleration"]].to_numpy()
    fit = stepwise(X, carsmall["MPG"], start="linear", upper="linear", max_steps=0)
    printed = [
        ("47.977", "3.8785", "12.37", "4.8957e-21"),
        ("-0.0065416", "0.0011274", "-5.8023", "9.8742e-08"),
        ("-0.042943", "0.024313", "-1.7663", "0.08078"),
        ("-0.011583", "0.19333", "-0.059913", "0.95236"),
    ]
    for (_, row), values in zip(fit.coefficients.iterrows(), printed, strict=True):
        for value, text in zip(row, values, strict=True):
            assert_printed(value, text)
    assert fit.n_obs == 93 and fit.dfe == 89
    assert_printed(fit.rmse, "4.09")
    assert_printed(fit.r_squared, "0.752")
    assert_printed(fit.adj_r_squared, "0.744")
    assert_printed(fit.f_stat, "90")


# --------------------------------------------------------------------------- step, categorical
def _year_table(carsmall):
    table = pd.DataFrame(
        {"Weight": carsmall["Weight"], "Year": pd.Categorical(carsmall["Model_Year"])}
    )
    return table, carsmall["MPG"].rename("MPG")


def test_matlab_step_example_with_categorical_year_and_square(carsmall):
    # https://mathworks.com/help/stats/linearmodel.step.html, "Modify Linear Regression
    # Model Using step": mdl1 = fitlm(tbl1,'MPG ~ Weight') with Year = categorical(Model_Year),
    # NewMdl1 = step(mdl1,'Upper','quadratic','NSteps',5) prints
    #   1. Adding Year, FStat = 47.5136, pValue = 8.22836e-15
    #   2. Adding Weight^2, FStat = 9.9164, pValue = 0.0022303   (evaluation line, Verbose 2)
    # and the model MPG ~ 1 + Weight + Year + Weight^2 with (Intercept) 54.206, SE 4.7117,
    # tStat 11.505, pValue 2.6648e-19.
    table, mpg = _year_table(carsmall)
    fit = stepwise(table, mpg, start="MPG ~ Weight", upper="quadratic", max_steps=5)
    steps = fit.steps
    assert steps["term"].tolist() == ["Year", "Weight^2"]
    assert steps["df"].tolist() == [2, 1]  # Year: one term of 2 indicator columns
    assert_printed(steps["f_stat"][0], "47.5136")
    assert_printed(steps["p_value"][0], "8.22836e-15")
    assert_printed(steps["f_stat"][1], "9.9164")
    assert_printed(steps["p_value"][1], "0.0022303")
    assert fit.formula == "MPG ~ 1 + Weight + Year + Weight^2"
    table_out = fit.coefficients
    assert table_out.index.tolist() == ["(Intercept)", "Weight", "Year_76", "Year_82", "Weight^2"]
    printed = ("54.206", "4.7117", "11.505", "2.6648e-19")
    for column, text in zip(table_out.columns, printed, strict=True):
        assert_printed(table_out.loc["(Intercept)", column], text)
    assert fit.n_obs == 94
    # the same model by statsmodels OLS with MATLAB's dummy coding (reference level 70)
    rows = mpg.notna()
    design = np.column_stack(
        [
            np.ones(rows.sum()),
            table["Weight"][rows],
            (table["Year"][rows] == 76).astype(float),
            (table["Year"][rows] == 82).astype(float),
            table["Weight"][rows] ** 2,
        ]
    )
    ols = sm.OLS(mpg[rows].to_numpy(), design).fit()
    np.testing.assert_allclose(table_out["estimate"], ols.params, rtol=1e-9)
    np.testing.assert_allclose(table_out["se"], ols.bse, rtol=1e-9)


def test_matlab_step_evaluation_of_the_other_candidates(carsmall):
    # same page, Verbose 2 evaluation lines: "pValue for adding Weight^2 is 0.15454" (step 1)
    # and "pValue for adding Weight:Year is 0.0071637" (step 2, a 2-df interaction)
    table, mpg = _year_table(carsmall)
    options = {"max_steps": 1, "p_enter": 0.5, "p_remove": 0.6}
    square = stepwise(table, mpg, start="MPG ~ Weight", upper="MPG ~ Weight + Weight^2", **options)
    assert_printed(square.steps["p_value"][0], "0.15454")
    interaction = stepwise(
        table, mpg, start="MPG ~ Weight + Year", upper="MPG ~ Weight*Year", **options
    )
    assert interaction.steps["term"].tolist() == ["Weight:Year"]
    assert interaction.steps["df"][0] == 2
    assert_printed(interaction.steps["p_value"][0], "0.0071637")
    assert interaction.coefficients.index[-2:].tolist() == ["Weight:Year_76", "Weight:Year_82"]


def test_numeric_year_is_another_model_and_categorical_option(carsmall):
    # Year as a number enters with one df (the F 76.81); categorical= restores
    # MATLAB's coding for a numeric column
    table = carsmall[["Weight", "Model_Year"]]
    numeric = stepwise(table, carsmall["MPG"], start="y ~ Weight", upper="linear", max_steps=1)
    assert numeric.steps["df"][0] == 1
    assert numeric.steps["f_stat"][0] == pytest.approx(76.81, abs=0.005)
    coded = stepwise(
        table,
        carsmall["MPG"],
        start="y ~ Weight",
        upper="linear",
        max_steps=1,
        categorical=["Model_Year"],
    )
    assert_printed(coded.steps["f_stat"][0], "47.5136")
    new = pd.DataFrame({"Weight": [3000.0, 3000.0], "Model_Year": [76, 82]})
    prediction = coded.predict(new)
    estimates = coded.coefficients["estimate"]
    expected = estimates["(Intercept)"] + 3000 * estimates["Weight"]
    np.testing.assert_allclose(
        prediction,
        [expected + estimates["Model_Year_76"], expected + estimates["Model_Year_82"]],
        rtol=1e-12,
    )
    with pytest.raises(ValueError, match="level '75' was not in the fitted data"):
        coded.predict(pd.DataFrame({"Weight": [3000.0], "Model_Year": [75]}))


def test_bool_and_string_predictors_are_categorical():
    rng = np.random.default_rng(3)
    n = 60
    frame = pd.DataFrame(
        {
            "speed_kn": rng.uniform(0, 12, n),
            "ice": rng.random(n) < 0.4,
            "sea_state": rng.choice(["calm", "moderate", "rough"], n),
        }
    )
    shift = {"calm": 0.0, "moderate": 0.02, "rough": 0.05}
    y = (
        2.0
        + 0.01 * frame["speed_kn"]
        + 0.08 * frame["ice"]
        + frame["sea_state"].map(shift)
        + 0.002 * rng.standard_normal(n)
    )
    fit = stepwise(frame, y, upper="linear")
    assert set(fit.terms) == {"speed_kn", "ice", "sea_state"}
    estimates = fit.coefficients["estimate"]
    assert estimates["ice_1"] == pytest.approx(0.08, abs=0.003)
    assert estimates["sea_state_moderate"] == pytest.approx(0.02, abs=0.003)
    assert estimates["sea_state_rough"] == pytest.approx(0.05, abs=0.003)
    assert fit.steps.set_index("term").loc["sea_state", "df"] == 2
    np.testing.assert_allclose(fit.predict(frame), y, atol=0.01)
    with pytest.raises(ValueError, match="cannot be squared"):
        stepwise(frame, y, upper="y ~ speed_kn + ice + ice^2")


# --------------------------------------------------------------------------- missing rows
def test_carbig_per_candidate_rows_default_and_complete_rule(carbig):
    # Issue 17 quotes MATLAB stepwiselm on carbig (Acceleration, Displacement, Horsepower,
    # Weight -> MPG): step 1 adds Weight with F 888.85 on 398 rows; with the rows that have
    # NaN in Horsepower dropped (stepwisefit's rule) it is 878.83 on 392. Both checked
    # independently with statsmodels OLS on those rows.
    X = carbig[["Acceleration", "Displacement", "Horsepower", "Weight"]]
    mpg = carbig["MPG"].rename("MPG")
    fit = stepwise(X, mpg, upper="linear")
    first = fit.steps.iloc[0]
    assert first["term"] == "Weight" and first["n_obs"] == 398
    assert_printed(first["f_stat"], "888.85")
    rows = mpg.notna()
    assert sm.OLS(mpg[rows], sm.add_constant(X["Weight"][rows])).fit().fvalue == pytest.approx(
        first["f_stat"], rel=1e-10
    )
    complete = stepwise(X, mpg, upper="linear", missing="complete")
    assert complete.steps.iloc[0]["n_obs"] == 392
    assert_printed(complete.steps.iloc[0]["f_stat"], "878.83")
    # Horsepower enters at step 2, so the final model is fitted on its 392 complete rows
    assert fit.terms == ("Horsepower", "Weight") and fit.n_obs == 392
    ols = sm.OLS(mpg, sm.add_constant(X[["Horsepower", "Weight"]]), missing="drop").fit()
    np.testing.assert_allclose(fit.coefficients["estimate"], ols.params, rtol=1e-10)


def test_unselected_predictor_with_nan_costs_no_rows():
    rng = np.random.default_rng(4)
    X = pd.DataFrame(rng.standard_normal((40, 3)), columns=["a", "b", "c"])
    y = 1.0 + 2.0 * X["a"] + 0.1 * rng.standard_normal(40)
    X.loc[:9, "c"] = np.nan  # a quarter of the rows
    fit = stepwise(X, y)
    assert fit.terms == ("a",) and fit.n_obs == 40
    ols = sm.OLS(y, sm.add_constant(X[["a"]])).fit()
    np.testing.assert_allclose(fit.coefficients["estimate"], ols.params, rtol=1e-12)
    assert stepwise(X, y, missing="complete").n_obs == 30


def test_all_nan_column_is_named():
    X = pd.DataFrame({"speed_kn": np.arange(10.0), "ice_cover": np.full(10, np.nan)})
    with pytest.raises(ValueError, match=r"column 'ice_cover' has no finite value.*all NaN"):
        stepwise(X, np.arange(10.0) * 2 + 1)


# --------------------------------------------------------------------------- exact fit
def test_exact_fit_stops_adding_terms():
    rng = np.random.default_rng(5)
    X = pd.DataFrame(rng.standard_normal((30, 5)), columns=[f"p{i}" for i in range(1, 6)])
    exact = stepwise(X, 1 + 2 * X["p1"] - X["p2"])
    assert exact.terms == ("p1", "p2")
    assert exact.skipped["reason"].str.startswith("exact fit").any()
    noisy = stepwise(X, 1 + 2 * X["p1"] - X["p2"] + 1e-9 * rng.standard_normal(30))
    assert noisy.terms == ("p1", "p2")
    np.testing.assert_allclose(exact.coefficients["estimate"], [1.0, 2.0, -1.0], atol=1e-12)


# --------------------------------------------------------------------------- raw units
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_large_offsets_do_not_change_the_selected_model(seed):
    rng = np.random.default_rng(seed)
    n = 60
    base = pd.DataFrame(rng.standard_normal((n, 3)), columns=["a", "b", "c"])
    y = 1.0 + base["a"] + base["b"] + 0.8 * base["a"] * base["b"]
    y = y + 0.1 * rng.standard_normal(n)
    reference = stepwise(base, y)
    assert "a:b" in reference.terms
    shifted = base + np.array([1e6, -3e5, 2e7])  # offset / sd >= 1e5
    fit = stepwise(shifted, y)
    assert fit.terms == reference.terms
    assert fit.r_squared == pytest.approx(reference.r_squared, rel=1e-9)
    for a, b in zip(fit.steps["f_stat"], reference.steps["f_stat"], strict=True):
        assert a == pytest.approx(b, rel=1e-6)
    # raw-unit coefficients: the slope of the interaction is unchanged, main effects
    # absorb the offsets (b_a,raw = b_a - b_ab * offset_b, ...)
    ab = reference.coefficients.loc["a:b", "estimate"]
    assert fit.coefficients.loc["a:b", "estimate"] == pytest.approx(ab, rel=1e-6)
    assert fit.coefficients.loc["a", "estimate"] == pytest.approx(
        reference.coefficients.loc["a", "estimate"] - ab * -3e5, rel=1e-6
    )
    # x - centre loses the offset's last digits: 2e7 * 2.2e-16 = 4e-9 per predictor
    np.testing.assert_allclose(fit.predict(shifted), reference.predict(base), atol=1e-8)


def test_quadratic_upper_and_square_coefficients():
    rng = np.random.default_rng(6)
    x = rng.uniform(270.0, 290.0, 50)  # kelvin: a large offset against the spread
    z = rng.standard_normal(50)
    y = 3.0 - 0.2 * (x - 280.0) + 0.05 * (x - 280.0) ** 2 + 0.01 * rng.standard_normal(50)
    fit = stepwise(pd.DataFrame({"t_k": x, "z": z}), y, upper="quadratic")
    assert fit.terms == ("t_k", "t_k^2")
    ols = sm.OLS(y, np.column_stack([np.ones(50), x, x**2])).fit()
    np.testing.assert_allclose(fit.coefficients["estimate"], ols.params, rtol=1e-7)
    np.testing.assert_allclose(fit.coefficients["se"], ols.bse, rtol=1e-6)


# --------------------------------------------------------------------------- criteria, Lower
@pytest.mark.parametrize("criterion", ["rsquared", "adjrsquared"])
def test_r_squared_criteria_on_hald(criterion):
    fit = stepwise(HALD_X, HALD_Y, criterion=criterion, upper="linear")
    # MATLAB defaults: R² enters above +0.1, adjusted R² above 0; each printed change is
    # the gain of the model after the step, checked against statsmodels
    expected = ["x4", "x1"] + (["x2"] if criterion == "adjrsquared" else [])
    assert fit.steps["term"].tolist() == expected
    attribute = "rsquared" if criterion == "rsquared" else "rsquared_adj"
    model: list[int] = []
    previous = 0.0
    for _, row in fit.steps.iterrows():
        model.append(int(row["term"][1:]) - 1)
        ols = sm.OLS(HALD_Y, sm.add_constant(HALD_X[:, sorted(model)])).fit()
        value = getattr(ols, attribute)
        assert row[criterion] == pytest.approx(value, rel=1e-10)
        assert row[f"{criterion}_change"] == pytest.approx(value - previous, rel=1e-9)
        assert row[f"{criterion}_change"] > (0.1 if criterion == "rsquared" else 0.0)
        previous = value


def test_lower_model_terms_are_never_removed():
    # from the full linear Hald model backward elimination removes x3 then x4
    # (p = 0.896, 0.205, as statsmodels gives); with Lower = y ~ x3, x3 stays
    free = stepwise(HALD_X, HALD_Y, start="linear", upper="linear")
    assert free.steps["term"].tolist() == ["x3", "x4"]
    kept = stepwise(HALD_X, HALD_Y, start="linear", upper="linear", lower="y ~ x3")
    assert "x3" in kept.terms and "x3" not in kept.steps["term"].tolist()
    with pytest.raises(ValueError, match="lower term 'x3' is not in the start model"):
        stepwise(HALD_X, HALD_Y, lower="y ~ x3")
