"""The short cuts of a small stepwise fit (issue 33) give what the general paths give."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm

from workbench.stats import stepwise
from workbench.stats.design import column_labels
from workbench.stats.fit_io import model_from_dict, model_to_dict

NAMES = ["speed_kn", "water_temp_c", "air_temp_c"]


def window(seed: int = 3, n_rows: int = 20) -> tuple[pd.DataFrame, np.ndarray]:
    """Predictors and a response with a main effect and an interaction."""
    rng = np.random.default_rng(seed)
    X = pd.DataFrame(rng.standard_normal((n_rows, 3)), columns=NAMES)
    y = (
        2.9
        - 0.04 * X["speed_kn"]
        + 0.02 * X["water_temp_c"]
        + 0.03 * X["speed_kn"] * X["water_temp_c"]
        + 0.005 * rng.standard_normal(n_rows)
    )
    return X, y.to_numpy()


def test_prediction_of_a_frame_in_the_fitted_column_order_equals_the_general_path():
    X, y = window()
    fit = stepwise(X, y)
    assert fit.terms == ("speed_kn", "water_temp_c", "speed_kn:water_temp_c")
    new = X.iloc[:4] + 0.25
    fast = fit.predict(new, interval="prediction")  # columns in the fitted order
    # the general path: other column order, an extra column, an unused column absent
    general = fit.predict(
        new[["water_temp_c", "speed_kn"]].assign(wind_speed_ms=1.0), interval="prediction"
    )
    pd.testing.assert_frame_equal(fast, general, check_exact=True)
    # a column the model does not use is never read: NaN there changes nothing
    unused_nan = new.assign(air_temp_c=np.nan)
    pd.testing.assert_frame_equal(fit.predict(unused_nan, interval="prediction"), fast)
    # ... nor does text there (the frame then takes the general path)
    unused_text = new.assign(air_temp_c="n/a")
    np.testing.assert_array_equal(fit.predict(unused_text), fast["mean"].to_numpy())
    # the interval columns are the documented ones, one row per new row, its index kept
    assert fast.columns.tolist() == ["mean", "lower", "upper", "mean_se"]
    assert fast.index.tolist() == new.index.tolist()
    assert (fast["lower"] < fast["mean"]).all() and (fast["mean"] < fast["upper"]).all()


def test_raw_unit_estimates_on_first_access_equal_ols_and_survive_the_json_round_trip():
    X, y = window(seed=11)
    offset = X + np.array([10.0, 4.0, -3.0])  # raw units with offsets: centring matters
    fit = stepwise(offset, y)
    columns = [np.ones(len(y))]
    for term in fit.terms:
        column = np.ones(len(y))
        for part in term.split(":"):
            column = column * offset[part].to_numpy()
        columns.append(column)
    ols = sm.OLS(y, np.column_stack(columns)).fit()
    np.testing.assert_allclose(fit.estimates, ols.params, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fit.standard_errors, ols.bse, rtol=1e-9, atol=1e-14)
    back = model_from_dict(model_to_dict(fit))
    # recomputed from the stored model in centred units: the same numbers, bit for bit
    np.testing.assert_array_equal(back.estimates, fit.estimates)
    np.testing.assert_array_equal(back.standard_errors, fit.standard_errors)
    description = model_to_dict(fit)
    del description["design"]["search_estimates"]
    with pytest.raises(ValueError, match="search_estimates") as error:
        model_from_dict(description)
    assert "cannot predict" in str(error.value)


# the centre of a column holding ±inf is that of its finite values (it was nanmean's
# inf, with a RuntimeWarning): an error here makes the warning fail the test
@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_infinite_values_are_missing_values_whatever_their_signs():
    # the complete-data short cut tests one total: +inf and -inf in it make NaN, one sign
    # makes inf; either way the rows are treated as missing, as NaN there would be
    X, y = window(seed=5)
    nan = X.copy()
    nan.loc[[2, 7], "air_temp_c"] = np.nan
    reference = stepwise(nan, y)
    for values in ([np.inf, -np.inf], [np.inf, np.inf], [-np.inf, np.nan]):
        infinite = X.copy()
        infinite.loc[[2, 7], "air_temp_c"] = values
        fit = stepwise(infinite, y)
        assert fit.terms == reference.terms and fit.n_obs == reference.n_obs
        np.testing.assert_array_equal(fit.search_estimates, reference.search_estimates)
        pd.testing.assert_frame_equal(fit.steps, reference.steps)
    response = y.copy()
    response[4] = np.inf
    nan_response = y.copy()
    nan_response[4] = np.nan
    fit, reference = stepwise(X, response), stepwise(X, nan_response)
    assert fit.n_obs == reference.n_obs == 19
    np.testing.assert_array_equal(fit.search_estimates, reference.search_estimates)


@pytest.mark.parametrize("values", [[np.inf, np.inf], [-np.inf, np.inf], [np.inf, np.nan]])
def test_a_predictor_with_infinite_values_enters_as_with_nan(values):
    # water temperature drives the response (0.2 per unit, 40 standard errors): with two
    # rows missing it is selected, and it must be with those rows infinite too (an
    # infinite centre made its whole column non-finite: the empty model, no warning shown)
    rng = np.random.default_rng(5)
    X = pd.DataFrame(rng.standard_normal((20, 3)), columns=NAMES)
    y = (
        2.9
        - 0.04 * X["speed_kn"]
        + 0.2 * X["water_temp_c"]
        + 0.05 * X["air_temp_c"]
        + 0.005 * rng.standard_normal(20)
    ).to_numpy()
    nan, infinite = X.copy(), X.copy()
    nan.loc[[2, 7], "water_temp_c"] = np.nan
    infinite.loc[[2, 7], "water_temp_c"] = values
    reference, fit = stepwise(nan, y), stepwise(infinite, y)
    assert "water_temp_c" in reference.terms
    assert fit.terms == reference.terms and fit.n_obs == reference.n_obs == 18
    np.testing.assert_allclose(fit.search_estimates, reference.search_estimates, rtol=1e-12)


def test_column_labels_of_an_index_with_a_missing_label_are_those_of_tolist():
    with_missing = pd.DataFrame(np.zeros((2, 3)), columns=["a", None, "c"]).columns
    labels = column_labels(with_missing)
    assert labels[0] == "a" and labels[2] == "c"
    assert isinstance(labels[1], float) and np.isnan(labels[1])  # as Index.tolist() gives
    plain = pd.DataFrame(np.zeros((2, 2)), columns=["speed_kn", "water_temp_c"]).columns
    assert column_labels(plain) == ("speed_kn", "water_temp_c")
    assert column_labels(pd.Index([3, 1])) == (3, 1)
