"""Tests for workbench.stats.stepwise: the Hald path, OLS agreement, the search rules."""

from __future__ import annotations

import json
import math
from decimal import Decimal

import numpy as np
import pandas as pd
import pytest
import statsmodels.api as sm
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from sklearn.base import clone
from sklearn.model_selection import KFold, cross_val_score
from sklearn.utils.estimator_checks import parametrize_with_checks

from workbench.stats import StepwiseFit, StepwiseRegressor, parse_terms, stepwise

# --------------------------------------------------------------------------- Hald cement data
#: Hald cement data: heat evolved [cal/g] while 13 cement samples harden, against the
#: percentages of four ingredients (x1 tricalcium aluminate, x2 tricalcium silicate,
#: x3 tetracalcium alumino ferrite, x4 dicalcium silicate). H. Woods, H. H. Steinour,
#: H. R. Starke, "Effect of composition of Portland cement on heat evolved during
#: hardening", Ind. Eng. Chem. 24(11), 1207-1214, 1932, doi:10.1021/ie50275a002; as
#: tabulated in N. R. Draper, H. Smith, Applied Regression Analysis (Appendix 15A) and
#: shipped with MATLAB as hald.mat (ingredients, heat).
HALD_X = np.array(
    [
        [7, 26, 6, 60],
        [1, 29, 15, 52],
        [11, 56, 8, 20],
        [11, 31, 8, 47],
        [7, 52, 6, 33],
        [11, 55, 9, 22],
        [3, 71, 17, 6],
        [1, 31, 22, 44],
        [2, 54, 18, 22],
        [21, 47, 4, 26],
        [1, 40, 23, 34],
        [11, 66, 9, 12],
        [10, 68, 8, 12],
    ],
    dtype=float,
)
HALD_Y = np.array(
    [78.5, 74.3, 104.3, 87.6, 95.9, 109.2, 102.7, 72.5, 93.1, 115.9, 83.8, 113.3, 109.4]
)

#: MATLAB documentation of stepwiselm, example "Stepwise regression with the Hald data":
#: mdl = stepwiselm(ingredients, heat, "PEnter", 0.06) prints these steps (values as printed)
#: and the final model y ~ 1 + x1 + x2 with estimates 52.577, 1.4683, 0.66225.
HALD_STEPS = [
    ("add", "x4", "22.7985", "0.000576232"),
    ("add", "x1", "108.2239", "1.105281e-06"),
    ("add", "x2", "5.0259", "0.051687"),
    ("remove", "x4", "1.8633", "0.2054"),
]
HALD_COEFFICIENTS = {"(Intercept)": "52.577", "x1": "1.4683", "x2": "0.66225"}


def assert_printed(value: float, printed: str) -> None:
    """*value* rounds to *printed*: within half a unit of its last printed digit."""
    reference = Decimal(printed)
    half_unit = Decimal(1).scaleb(reference.as_tuple().exponent) / 2
    assert abs(Decimal(repr(float(value))) - reference) <= half_unit, (value, printed)


def test_hald_path_matches_matlab_documentation():
    fit = stepwise(HALD_X, HALD_Y, p_enter=0.06)
    steps = fit.steps
    assert steps["action"].tolist() == [s[0] for s in HALD_STEPS]
    assert steps["term"].tolist() == [s[1] for s in HALD_STEPS]
    for (_, _, f_printed, p_printed), f_stat, p_value in zip(
        HALD_STEPS, steps["f_stat"], steps["p_value"], strict=True
    ):
        assert_printed(f_stat, f_printed)
        assert_printed(p_value, p_printed)
    assert fit.terms == ("x1", "x2")
    assert fit.formula == "y ~ 1 + x1 + x2"
    for term, printed in HALD_COEFFICIENTS.items():
        assert_printed(fit.coefficients.loc[term, "estimate"], printed)
    assert fit.n_obs == 13 and fit.dfe == 10


def test_hald_default_threshold_stops_before_x2():
    # x2's p-value 0.051687 is above the default p_enter 0.05: the search ends at x1 + x4
    fit = stepwise(HALD_X, HALD_Y)
    assert fit.steps["term"].tolist() == ["x4", "x1"]
    assert fit.terms == ("x1", "x4")


def test_hald_final_model_statistics_match_statsmodels():
    fit = stepwise(HALD_X, HALD_Y, p_enter=0.06)
    ols = sm.OLS(HALD_Y, sm.add_constant(HALD_X[:, :2])).fit()
    table = fit.coefficients
    np.testing.assert_allclose(table["estimate"], ols.params, rtol=1e-12)
    np.testing.assert_allclose(table["se"], ols.bse, rtol=1e-10)
    np.testing.assert_allclose(table["t_stat"], ols.tvalues, rtol=1e-10)
    np.testing.assert_allclose(table["p_value"], ols.pvalues, rtol=1e-8)
    assert fit.r_squared == pytest.approx(ols.rsquared, rel=1e-12)
    assert fit.adj_r_squared == pytest.approx(ols.rsquared_adj, rel=1e-12)
    assert fit.rmse == pytest.approx(math.sqrt(ols.scale), rel=1e-12)
    assert fit.f_stat == pytest.approx(ols.fvalue, rel=1e-10)
    assert fit.f_p_value == pytest.approx(ols.f_pvalue, rel=1e-8)
    assert fit.aic == pytest.approx(ols.aic, rel=1e-12)
    assert fit.bic == pytest.approx(ols.bic, rel=1e-12)


@pytest.mark.parametrize("criterion", ["aic", "bic"])
def test_information_criterion_paths_on_hald(criterion):
    fit = stepwise(HALD_X, HALD_Y, criterion=criterion)
    # AIC keeps x4 (dropping it raises AIC by 0.45); BIC's ln(13) = 2.56 penalty drops it
    expected = ["x4", "x1", "x2"] + (["x4"] if criterion == "bic" else [])
    assert fit.steps["term"].tolist() == expected
    assert fit.terms == (("x1", "x2", "x4") if criterion == "aic" else ("x1", "x2"))
    # the criterion printed for each step is the one of the model after the step, as
    # statsmodels computes it; the change is against the model before
    model: list[int] = []
    previous = getattr(sm.OLS(HALD_Y, np.ones(13)).fit(), criterion)
    for _, row in fit.steps.iterrows():
        column = int(row["term"][1:]) - 1
        model = model + [column] if row["action"] == "add" else [c for c in model if c != column]
        ols = sm.OLS(HALD_Y, sm.add_constant(HALD_X[:, sorted(model)])).fit()
        assert row[criterion] == pytest.approx(getattr(ols, criterion), rel=1e-10)
        change = getattr(ols, criterion) - previous
        sign = 1 if row["action"] == "add" else -1  # removal: change of adding it back
        assert row[f"{criterion}_change"] == pytest.approx(sign * change, abs=1e-9)
        previous = getattr(ols, criterion)


# --------------------------------------------------------------------------- helpers
def design(frame: pd.DataFrame, terms) -> np.ndarray:
    columns = [np.ones(len(frame))]
    for term in terms:
        parts = term.split(":")
        column = frame[parts[0]].to_numpy(dtype=float)
        for part in parts[1:]:
            column = column * frame[part].to_numpy(dtype=float)
        columns.append(column)
    return np.column_stack(columns)


@st.composite
def regression_data(draw):
    n_predictors = draw(st.integers(2, 4))
    n_obs = draw(st.integers(8, 40))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    X = pd.DataFrame(
        rng.standard_normal((n_obs, n_predictors)),
        columns=[f"p{i}" for i in range(n_predictors)],
    )
    effects = rng.choice([0.0, 0.0, 0.6, 1.5], size=n_predictors)
    y = X.to_numpy() @ effects
    y = y + rng.choice([0.0, 1.0]) * X["p0"] * X["p1"] + rng.standard_normal(n_obs)
    return X, pd.Series(y, name="response")


def ols_partial_p(X: pd.DataFrame, y: np.ndarray, small, large) -> float:
    """p-value of the partial F-test of *large* against *small* (one more term)."""
    small_fit = sm.OLS(y, design(X, small)).fit()
    large_fit = sm.OLS(y, design(X, large)).fit()
    f_stat = (small_fit.ssr - large_fit.ssr) / (large_fit.ssr / large_fit.df_resid)
    from scipy import stats

    return float(stats.f.sf(f_stat, 1, large_fit.df_resid))


# --------------------------------------------------------------------------- properties
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(regression_data())
def test_final_model_agrees_with_statsmodels(data):
    X, y = data
    fit = stepwise(X, y, upper="interactions")
    ols = sm.OLS(y.to_numpy(), design(X, fit.terms)).fit()
    np.testing.assert_allclose(fit.coefficients["estimate"], ols.params, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(fit.coefficients["se"], ols.bse, rtol=1e-8, atol=1e-12)
    assert fit.sse == pytest.approx(ols.ssr, rel=1e-9, abs=1e-12)
    new = X.iloc[:5] + 0.5
    for interval, lower, upper in (
        ("confidence", "mean_ci_lower", "mean_ci_upper"),
        ("prediction", "obs_ci_lower", "obs_ci_upper"),
    ):
        ours = fit.predict(new, interval=interval, alpha=0.1)
        theirs = ols.get_prediction(design(new, fit.terms)).summary_frame(alpha=0.1)
        np.testing.assert_allclose(ours["mean"], theirs["mean"], rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(ours["lower"], theirs[lower], rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(ours["upper"], theirs[upper], rtol=1e-8, atol=1e-10)
        # standard error of the mean, the same for both intervals (statsmodels mean_se)
        np.testing.assert_allclose(ours["mean_se"], theirs["mean_se"], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(fit.predict(new), ours["mean"])
    assert fit.response_name == "response"


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(regression_data(), st.sampled_from(["constant", "linear", "interactions"]))
def test_every_step_follows_the_rules(data, start):
    """Replay the path: thresholds, hierarchy, no immediate undo, p-values vs statsmodels."""
    X, y = data
    y = y.to_numpy()
    names = list(X.columns)
    n_start = {"constant": 1, "linear": 1 + len(names), "interactions": 1 + len(names) * 3}
    assume(len(y) > n_start[start] + 1)
    fit = stepwise(X, y, start=start, p_enter=0.05, p_remove=0.10)
    start_terms = {
        "constant": [],
        "linear": names,
        "interactions": names + [f"{a}:{b}" for i, a in enumerate(names) for b in names[i + 1 :]],
    }[start]
    model = list(start_terms)
    previous = (None, None)
    for _, row in fit.steps.iterrows():
        term, action = row["term"], row["action"]
        assert term != "(Intercept)"
        if action == "add":
            assert term not in model
            assert previous != ("remove", term)
            if ":" in term:  # an interaction enters only after both main effects
                assert all(part in model for part in term.split(":"))
            assert row["p_value"] < 0.05
            expected = ols_partial_p(X, y, model, model + [term])
            model = model + [term]
        else:
            assert term in model
            assert previous != ("add", term)
            assert not any(":" in t and term in t.split(":") for t in model)  # no child in
            assert row["p_value"] > 0.10
            reduced = [t for t in model if t != term]
            expected = ols_partial_p(X, y, reduced, model)
            model = reduced
        assert row["p_value"] == pytest.approx(expected, rel=1e-7, abs=1e-12)
        previous = (action, term)
    assert sorted(fit.terms) == sorted(model)


def test_term_order_breaks_ties_and_interactions_are_named_after_columns():
    rng = np.random.default_rng(3)
    X = pd.DataFrame(rng.standard_normal((40, 3)), columns=["speed_kn", "water_temp_c", "b"])
    # identical columns: the same p-value; the first in column order enters
    X["b"] = X["speed_kn"]
    y = X["speed_kn"] * 2.0 + 0.5 * X["speed_kn"] * X["water_temp_c"] + X["water_temp_c"]
    y = y + 0.1 * rng.standard_normal(40)
    fit = stepwise(X, y)
    assert fit.steps["term"].iloc[0] == "speed_kn"
    assert "speed_kn:water_temp_c" in fit.terms
    assert "b" not in fit.terms
    assert ("b", "collinear with the model's terms") in {
        (t, r) for t, r in zip(fit.skipped["term"], fit.skipped["reason"], strict=True)
    }


def test_pure_interaction_cannot_enter_without_main_effects():
    rng = np.random.default_rng(4)
    X = pd.DataFrame(rng.standard_normal((60, 2)), columns=["a", "b"])
    X = X - X.mean()
    y = 3.0 * X["a"] * X["b"] + 0.01 * rng.standard_normal(60)
    fit = stepwise(X, y, p_enter=1e-6, p_remove=2e-6)
    # the interaction explains nearly everything but is not eligible while a, b are out
    assert "a:b" not in fit.terms
    assert "a:b" not in fit.steps["term"].tolist()


def test_main_effect_stays_while_its_interaction_is_in():
    rng = np.random.default_rng(5)
    X = pd.DataFrame(rng.standard_normal((50, 2)), columns=["a", "b"])
    y = 2.0 * X["a"] * X["b"] + 1.0 * X["b"] + 0.05 * rng.standard_normal(50)
    fit = stepwise(X, y, start="interactions")
    assert "a:b" in fit.terms
    assert "a" in fit.terms  # main effect 'a' is not significant but has a child in the model
    assert fit.coefficients.loc["a", "p_value"] > 0.10


def test_collinear_candidate_is_never_added_and_recorded():
    rng = np.random.default_rng(6)
    X = pd.DataFrame(rng.standard_normal((30, 2)), columns=["x1", "x2"])
    X["x3"] = X["x1"] - 2.0 * X["x2"]  # exact linear combination
    X["flat"] = 4.0  # collinear with the intercept
    y = 1.0 + X["x1"] + X["x2"] + 0.1 * rng.standard_normal(30)
    fit = stepwise(X, y, upper="linear", p_enter=0.5, p_remove=0.6)
    # given one of x1, x2, x3 the other two span the same space (an exact tie up to
    # rounding): two enter, the third is collinear with them
    assert len(fit.terms) == 2 and set(fit.terms) <= {"x1", "x2", "x3"}
    (left_out,) = {"x1", "x2", "x3"} - set(fit.terms)
    reasons = dict(zip(fit.skipped["term"], fit.skipped["reason"], strict=True))
    assert reasons["flat"] == "collinear with the model's terms"
    assert reasons[left_out] == "collinear with the model's terms"
    assert fit.r_squared > 0.98
    assert np.isfinite(fit.coefficients.to_numpy()).all()


def test_too_few_observations_skips_candidates_with_a_reason():
    X = np.array([[0.0, 1.0, 5.0], [1.0, 0.0, 2.0], [2.0, 2.0, 7.0], [3.0, 1.0, 1.0]])
    y = 1.0 + 2.0 * X[:, 0] + 3.0 * X[:, 1] + np.array([0.01, -0.02, 0.01, 0.0])
    fit = stepwise(X, y, upper="linear", p_enter=0.2, p_remove=0.3)
    assert fit.n_obs == 4
    assert len(fit.terms) == 2 and fit.dfe == 1
    assert fit.skipped["reason"].str.startswith("too few observations").any()
    assert "x3" in fit.skipped["term"].tolist()


def test_rows_with_nan_are_left_out_and_prediction_marks_them():
    rng = np.random.default_rng(7)
    X = pd.DataFrame(rng.standard_normal((30, 3)), columns=["a", "b", "c"])
    y = 2.0 * X["a"] + 0.1 * rng.standard_normal(30)
    y[3] = np.nan
    X.loc[5, "c"] = np.nan
    fit = stepwise(X, y, upper="linear")
    # 'c' (NaN in row 5) is never selected: the default (MATLAB stepwiselm) keeps row 5
    assert fit.n_obs == 29
    assert fit.terms == ("a",)
    # MATLAB stepwisefit's rule: a row with NaN in any candidate predictor is left out
    complete = stepwise(X, y, upper="linear", missing="complete")
    assert complete.n_obs == 28 and complete.terms == ("a",)
    assert "stepwisefit" in complete.summary() and "stepwiselm" in fit.summary()
    rows = pd.DataFrame({"a": [1.0, np.nan, 2.0], "b": [np.nan, 0.0, 0.0]}, index=[10, 11, 12])
    out = fit.predict(rows, interval="prediction")
    assert out.index.tolist() == [10, 11, 12]
    # NaN only where a predictor the model uses ('a') is NaN; 'c' may be absent entirely
    assert out["mean"].isna().tolist() == [False, True, False]
    assert (out["lower"] < out["mean"]).iloc[[0, 2]].all()
    with pytest.raises(ValueError, match="missing predictor column 'a'"):
        fit.predict(rows[["b"]])


def test_array_input_names_and_shapes():
    rng = np.random.default_rng(8)
    X = rng.standard_normal((25, 2))
    y = X[:, 1] * 3.0 + 0.1 * rng.standard_normal(25)
    fit = stepwise(X, y)
    assert fit.predictor_names == ("x1", "x2")
    assert "x2" in fit.terms
    assert fit.predict(X[:4]).shape == (4,)
    with pytest.raises(ValueError, match="2 predictor columns"):
        fit.predict(np.ones((3, 3)))


def test_max_steps_and_start_models():
    fit = stepwise(HALD_X, HALD_Y, p_enter=0.06, max_steps=2)
    assert fit.steps["term"].tolist() == ["x4", "x1"]
    full = stepwise(HALD_X, HALD_Y, start="linear", upper="linear")
    assert "remove" in full.steps["action"].tolist()
    formula = stepwise(HALD_X, HALD_Y, start="y ~ x1 + x2", upper="y ~ x1 + x2 + x3 + x4")
    assert set(formula.terms) >= {"x1", "x2"}
    assert stepwise(HALD_X, HALD_Y, max_steps=0).terms == ()


def test_summary_and_json():
    fit = stepwise(HALD_X, HALD_Y, p_enter=0.06)
    text = fit.summary()
    assert "1. Adding x4, FStat = 22.7985" in text
    assert "4. Removing x4, FStat = 1.8633" in text
    assert "y ~ 1 + x1 + x2" in text
    payload = json.loads(json.dumps(fit.to_dict(), allow_nan=False))
    assert payload["terms"] == ["x1", "x2"]
    assert payload["coefficients"]["x2"]["estimate"] == pytest.approx(0.66225, abs=5e-6)
    assert payload["steps"][3]["action"] == "remove"
    assert isinstance(fit, StepwiseFit)
    with pytest.raises(AttributeError):
        fit.terms = ()  # frozen


# --------------------------------------------------------------------------- formulas
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("y ~ x1 + x2 + x1:x2", ["x1", "x2", "x1:x2"]),
        ("x1*x2", ["x1", "x2", "x1:x2"]),
        ("y ~ 1 + x1*x3 - x1:x3", ["x1", "x3"]),
        ("  x3:x1 + x2  ", ["x2", "x1:x3"]),
        ("y ~ 1", []),
    ],
)
def test_formula_parsing(text, expected):
    names = ("x1", "x2", "x3")
    terms = parse_terms(text, names)
    assert terms[0] == ()
    assert [":".join(names[i] for i in t) for t in terms[1:]] == expected


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("__import__('os')", "unexpected character"),
        ("x1 + os.system('ls')", "unknown predictor 'os.system'|unexpected character"),
        ("y ~ x1 + x9", "unknown predictor 'x9'"),
        ("x1:x2:x3", "more than two factors"),
        ("y ~ x1 - 1", "intercept is always in the model"),
        ("y ~ 0 + x1", "intercept is always in the model"),
        ("y ~ x1 +", "ends after an operator"),
        ("y ~ x1 x2", "expected '\\+' or '-'"),
        ("y ~ x1 + 2", "only 1"),
        ("a ~ b ~ x1", "more than one '~'"),
    ],
)
def test_formula_errors(text, match):
    with pytest.raises(ValueError, match=match):
        parse_terms(text, ("x1", "x2", "x3"), parameter="start")


def test_term_lists_and_model_errors():
    assert parse_terms(["x2", "x1:x2", "(Intercept)"], ("x1", "x2")) == [(), (1,), (0, 1)]
    with pytest.raises(ValueError, match="unknown predictor 'x5'"):
        parse_terms(["x5"], ("x1", "x2"))
    with pytest.raises(TypeError, match="term"):
        parse_terms(42, ("x1", "x2"))
    with pytest.raises(ValueError, match="start term 'x1:x2' is not in the upper model"):
        stepwise(HALD_X, HALD_Y, start=["x1", "x2", "x1:x2"], upper="linear")
    with pytest.raises(ValueError, match="criterion='r2'"):
        stepwise(HALD_X, HALD_Y, criterion="r2")
    with pytest.raises(ValueError, match="p_enter=0.2, p_remove=0.1"):
        stepwise(HALD_X, HALD_Y, p_enter=0.2)
    with pytest.raises(ValueError, match="y has shape"):
        stepwise(HALD_X, HALD_Y[:5])
    collinear = np.column_stack([HALD_X[:, 0], 2 * HALD_X[:, 0]])
    with pytest.raises(ValueError, match="rank deficient: term 'x2'"):
        stepwise(collinear, HALD_Y, start="linear")
    with pytest.raises(ValueError, match="complete rows"):
        stepwise(HALD_X[:1], HALD_Y[:1])


# --------------------------------------------------------------------------- scikit-learn
def test_sklearn_estimator_clone_and_cross_validation():
    rng = np.random.default_rng(9)
    X = pd.DataFrame(rng.standard_normal((60, 3)), columns=["speed_kn", "water_temp_c", "wind"])
    y = 1.0 + 0.8 * X["speed_kn"] - 0.5 * X["water_temp_c"] + 0.1 * rng.standard_normal(60)
    estimator = StepwiseRegressor(upper="linear", p_enter=0.01, p_remove=0.02)
    assert estimator.get_params()["p_enter"] == 0.01
    copy = clone(estimator).set_params(criterion="bic", p_enter=None, p_remove=None)
    assert copy.get_params()["criterion"] == "bic" and estimator.criterion == "sse"
    scores = cross_val_score(estimator, X, y, cv=KFold(5, shuffle=True, random_state=0))
    assert scores.shape == (5,) and scores.min() > 0.9
    scores_array = cross_val_score(clone(estimator), X.to_numpy(), y.to_numpy(), cv=5)
    assert scores_array.min() > 0.9
    fitted = estimator.fit(X, y)
    assert fitted is estimator
    assert list(estimator.feature_names_in_) == list(X.columns)
    assert estimator.terms_ == ("speed_kn", "water_temp_c")
    with pytest.warns(UserWarning, match="valid feature names"):  # sklearn's own warning
        from_array = estimator.predict(X.to_numpy())
    np.testing.assert_allclose(from_array, estimator.predict(X))
    assert estimator.score(X, y) == pytest.approx(estimator.result_.r_squared, rel=1e-12)


def test_raw_units_with_large_offsets_agree_with_statsmodels():
    """Interactions of uncentred predictors (temperature in kelvin) are ill-conditioned;
    the centred, scaled search still matches a QR-based OLS to ~1e-9."""
    rng = np.random.default_rng(2)
    n = 40
    X = pd.DataFrame(
        {
            "temp_k": 280 + rng.normal(0, 0.5, n),
            "speed_kn": 12 + rng.normal(0, 2, n),
            "wind": rng.gamma(3, 2, n),
        }
    )
    y = (
        3
        - 0.02 * (X["temp_k"] - 280)
        + 0.01 * X["speed_kn"]
        + 0.004 * (X["temp_k"] - 280) * (X["speed_kn"] - 12)
        + rng.normal(0, 0.002, n)
    )
    fit = stepwise(X, y, p_enter=0.1, p_remove=0.15)
    assert fit.terms == ("temp_k", "speed_kn", "temp_k:speed_kn")
    ols = sm.OLS(y.to_numpy(), design(X, fit.terms)).fit()
    np.testing.assert_allclose(fit.coefficients["estimate"], ols.params, rtol=1e-8)
    np.testing.assert_allclose(fit.coefficients["se"], ols.bse, rtol=1e-8)
    new = X.iloc[:3] + 0.1
    ours = fit.predict(new, interval="confidence")
    theirs = ols.get_prediction(design(new, fit.terms)).summary_frame()
    np.testing.assert_allclose(ours["lower"], theirs["mean_ci_lower"], rtol=1e-9)


@parametrize_with_checks([StepwiseRegressor()])
def test_sklearn_estimator_checks(estimator, check):
    """scikit-learn's own estimator checks (API conventions, input validation, cloning)."""
    check(estimator)
