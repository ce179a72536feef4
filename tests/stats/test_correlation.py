"""Tests for workbench.stats.correlation: r and p against scipy, NaN handling, cases."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats
from statsmodels.stats.multitest import multipletests

from workbench.stats.correlation import (
    adjust_p_values,
    case_masks,
    correlation_table,
    modal_wide,
    pairwise_pearson,
    read_cases,
)

START = pd.Timestamp("2024-03-01T00:00:00Z")


def block_tables(n_blocks=60, seed=0, modes=(1, 2)):
    """Predictor and modal tables on a 5-minute block grid with known dependences."""
    rng = np.random.default_rng(seed)
    block = np.arange(n_blocks)
    start = START + pd.to_timedelta(block * 5, unit="min")
    speed = 10 + 3 * np.sin(block / 7) + rng.normal(0, 0.3, n_blocks)
    water = 4 + 0.02 * block + rng.normal(0, 0.05, n_blocks)
    predictors = pd.DataFrame(
        {
            "block": block,
            "block_start": start,
            "block_end": start + pd.Timedelta(minutes=20),
            "speed_kn": speed,
            "water_temp_c": water,
            "wind_speed_ms": rng.gamma(4, 2, n_blocks),
        }
    )
    rows = []
    for mode in modes:
        frequency = 2.9 * mode - 0.01 * speed + rng.normal(0, 0.005, n_blocks)
        damping = 0.012 + 0.0005 * speed * (mode == 1) + rng.normal(0, 0.001, n_blocks)
        rows.append(
            pd.DataFrame(
                {
                    "block": block,
                    "block_start": start,
                    "mode": mode,
                    "frequency_hz": frequency,
                    "damping_ratio": damping,
                }
            )
        )
    return pd.concat(rows, ignore_index=True), predictors


def scipy_pair(x, y):
    valid = np.isfinite(x) & np.isfinite(y)
    result = stats.pearsonr(x[valid], y[valid])
    return result.statistic, result.pvalue, int(valid.sum())


@settings(max_examples=40, deadline=None)
@given(
    st.integers(0, 2**31 - 1),
    st.integers(4, 60),
    st.floats(0.0, 0.4),
    st.floats(-0.99, 0.99),
)
def test_pairwise_pearson_matches_scipy_with_missing_values(seed, n_rows, missing, rho):
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n_rows, 3))
    b = rho * a[:, :2] + np.sqrt(1 - rho**2) * rng.standard_normal((n_rows, 2)) + 1e3
    a[rng.random(a.shape) < missing] = np.nan
    b[rng.random(b.shape) < missing] = np.nan
    r, p, n = pairwise_pearson(a, b)
    for i in range(3):
        for j in range(2):
            valid = np.isfinite(a[:, i]) & np.isfinite(b[:, j])
            assert n[i, j] == valid.sum()
            if valid.sum() < 3:
                assert np.isnan(r[i, j]) and np.isnan(p[i, j])
                continue
            expected_r, expected_p, _ = scipy_pair(a[:, i], b[:, j])
            assert r[i, j] == pytest.approx(expected_r, abs=1e-10)
            assert p[i, j] == pytest.approx(expected_p, rel=1e-6, abs=1e-12)


def test_pairwise_pearson_constant_column_and_perfect_correlation():
    x = np.arange(10.0)
    data = np.column_stack([x, 2 * x + 1, np.full(10, 3.0)])
    r, p, n = pairwise_pearson(data, data)
    assert r[0, 1] == pytest.approx(1.0) and p[0, 1] == 0.0
    assert np.isnan(r[0, 2]) and np.isnan(p[0, 2])  # constant: r undefined
    assert n[0, 2] == 10


def test_adjusted_p_values_match_statsmodels():
    rng = np.random.default_rng(1)
    p = rng.uniform(0, 0.2, 25)
    p[[3, 11]] = np.nan
    finite = np.isfinite(p)
    for method in ("holm", "fdr_bh"):
        ours = adjust_p_values(p, method)
        theirs = multipletests(p[finite], method=method)[1]
        np.testing.assert_allclose(ours[finite], theirs, rtol=1e-12)
        assert np.isnan(ours[~finite]).all()
    np.testing.assert_array_equal(adjust_p_values(p, None), p)
    with pytest.raises(ValueError, match="correction='bonferroni'"):
        adjust_p_values(p, "bonferroni")


def test_modal_wide_columns_and_duplicates():
    modal, _ = block_tables(n_blocks=5)
    modal = modal[~((modal["mode"] == 2) & (modal["block"] == 3))]  # mode 2 lost in block 3
    wide = modal_wide(modal)
    assert list(wide.columns) == [
        "mode1_frequency_hz",
        "mode1_damping_ratio",
        "mode2_frequency_hz",
        "mode2_damping_ratio",
    ]
    assert wide.index.tolist() == [0, 1, 2, 3, 4]
    assert np.isnan(wide.loc[3, "mode2_frequency_hz"])
    with pytest.raises(ValueError, match="block 0, mode 1"):
        modal_wide(pd.concat([modal, modal.iloc[:1]]))
    with pytest.raises(ValueError, match="no column 'damping_ratio'"):
        modal_wide(modal.drop(columns="damping_ratio"))


def test_correlation_table_values_flags_and_layout():
    modal, predictors = block_tables()
    predictors.loc[[5, 6, 7], "speed_kn"] = np.nan
    modal.loc[(modal["mode"] == 1) & modal["block"].isin([10, 11]), "frequency_hz"] = np.nan
    table = correlation_table(modal, predictors)
    assert list(table.columns) == [
        "x",
        "y",
        "case",
        "r",
        "p_value",
        "p_adjusted",
        "n",
        "significant",
        "useful",
    ]
    # 4 mode quantities x 3 predictors + 3 predictor pairs
    assert len(table) == 4 * 3 + 3
    assert set(table["case"]) == {"all"}
    row = table[(table["x"] == "speed_kn") & (table["y"] == "mode1_frequency_hz")].iloc[0]
    wide = modal_wide(modal)
    expected_r, expected_p, expected_n = scipy_pair(
        predictors["speed_kn"].to_numpy(), wide["mode1_frequency_hz"].to_numpy()
    )
    assert row["n"] == expected_n == 55
    assert row["r"] == pytest.approx(expected_r, abs=1e-12)
    assert row["p_value"] == pytest.approx(expected_p, rel=1e-8)
    assert row["r"] < -0.9 and row["significant"] and row["useful"]
    wind = table[(table["x"] == "wind_speed_ms") & (table["y"] == "mode2_frequency_hz")].iloc[0]
    assert abs(wind["r"]) < 0.5 and not wind["useful"]
    pairs = table[~table["y"].str.startswith("mode")]
    assert pairs[["x", "y"]].values.tolist() == [
        ["speed_kn", "water_temp_c"],
        ["speed_kn", "wind_speed_ms"],
        ["water_temp_c", "wind_speed_ms"],
    ]
    assert (table["useful"] <= table["significant"]).all()


def test_correction_makes_fewer_significant():
    modal, predictors = block_tables(n_blocks=25, seed=3)
    plain = correlation_table(modal, predictors)
    holm = correlation_table(modal, predictors, correction="holm")
    assert (holm["p_adjusted"] >= holm["p_value"] - 1e-15).all()
    assert holm["significant"].sum() <= plain["significant"].sum()
    assert (holm["significant"] <= plain["significant"]).all()


def test_cases_from_time_ranges_csv(tmp_path):
    modal, predictors = block_tables(n_blocks=48)  # 4 h of 5-minute blocks
    path = tmp_path / "cases.csv"
    path.write_text(
        "case,start,end\n"
        "harbour,2024-03-01T00:00:00Z,2024-03-01T01:00:00Z\n"
        "transit,2024-03-01T01:00:00Z,2024-03-01T03:00:00Z\n"
        "harbour,2024-03-01T03:00:00,2024-03-01T04:00:00\n"  # no offset: UTC
    )
    cases = read_cases(path)
    assert cases["case"].tolist() == ["harbour", "transit", "harbour"]
    assert str(cases["start"].dt.tz) == "UTC"
    table = correlation_table(modal, predictors, cases=path)
    assert table["case"].unique().tolist() == ["all", "harbour", "transit"]
    counts = table[(table["x"] == "speed_kn") & (table["y"] == "water_temp_c")].set_index("case")
    # a 20-minute block lies inside a 1-hour range when it starts in its first 40 minutes
    assert counts.loc["harbour", "n"] == 9 + 9
    assert counts.loc["transit", "n"] == 21
    assert counts.loc["all", "n"] == 9 + 21 + 9
    mask = dict(case_masks(predictors, cases))
    assert mask["harbour"][:9].all() and not mask["harbour"][9:12].any()


def test_cases_from_a_column():
    modal, predictors = block_tables(n_blocks=40)
    predictors["case"] = np.where(predictors["block"] < 20, "slow", "fast")
    predictors.loc[0, "case"] = None  # not in any case
    table = correlation_table(modal, predictors, cases="case")
    assert table["case"].unique().tolist() == ["all", "slow", "fast"]
    n = table[(table["x"] == "speed_kn") & (table["y"] == "water_temp_c")].set_index("case")["n"]
    assert n.to_dict() == {"all": 39, "slow": 19, "fast": 20}


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("name,start,end\nx,2024-03-01,2024-03-02\n", "missing column 'case'"),
        ("case,start,end\n", "header only"),
        ("case,start,end\nx,yesterday,2024-03-02\n", "line 2: start 'yesterday' is not a time"),
        ("case,start,end\nx,2024-03-02,2024-03-01\n", "line 2: end 2024-03-01 is not after"),
        ("case,start,end\n,2024-03-01,2024-03-02\n", "line 2: empty case name"),
    ],
)
def test_read_cases_errors_name_file_and_line(tmp_path, content, match):
    path = tmp_path / "cases.csv"
    path.write_text(content)
    with pytest.raises(ValueError, match=match) as error:
        read_cases(path)
    assert str(path) in str(error.value)


def test_bad_input_errors():
    modal, predictors = block_tables(n_blocks=10)
    with pytest.raises(ValueError, match="neither a column of the block table nor a file"):
        correlation_table(modal, predictors, cases="voyage_phase")
    with pytest.raises(ValueError, match="no such cases file"):
        read_cases("/nonexistent/cases.csv")
    with pytest.raises(ValueError, match="predictor table has no column 'heading_deg'"):
        correlation_table(modal, predictors, predictors_used=["heading_deg"])
    with pytest.raises(ValueError, match="alpha=1.5"):
        correlation_table(modal, predictors, alpha=1.5)
    with pytest.raises(ValueError, match="more than one row for block 2"):
        correlation_table(modal, pd.concat([predictors, predictors.iloc[[2]]]))
