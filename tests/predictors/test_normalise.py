"""Tests for the z-score Normaliser (parameters kept for new data)."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.predictors import Normaliser, PredictorWarning


def _frame() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "block": [0, 1, 2, 3],
            "speed_kn": [0.0, 5.0, 10.0, np.nan],
            "water_temp_c": [1.0, 2.0, 3.0, 4.0],
        }
    )


def test_fit_and_transform():
    frame = _frame()
    scaler = Normaliser.fit(frame)
    assert scaler.columns == ("speed_kn", "water_temp_c")  # block is not a predictor
    assert scaler.mean == (5.0, 2.5)
    # sample standard deviation (ddof=1): speed sqrt(25) = 5, water sqrt(5/3)
    assert scaler.std == pytest.approx((5.0, np.sqrt(5 / 3)))
    z = scaler.transform(frame)
    assert z["block"].tolist() == [0, 1, 2, 3]
    np.testing.assert_allclose(z["speed_kn"], [-1.0, 0.0, 1.0, np.nan])
    assert z["water_temp_c"].std() == pytest.approx(1.0)
    # new data are scaled with the training parameters, not their own
    new = pd.DataFrame({"speed_kn": [15.0], "water_temp_c": [2.5], "extra": ["x"]})
    scaled = scaler.transform(new)
    assert scaled["speed_kn"].item() == 2.0 and scaled["water_temp_c"].item() == 0.0
    assert scaled["extra"].item() == "x"
    pd.testing.assert_frame_equal(scaler.inverse_transform(z), frame.astype({"block": "int64"}))


def test_json_round_trip():
    scaler = Normaliser.fit(_frame(), columns=["water_temp_c", "speed_kn"])
    text = json.dumps(scaler.to_dict())
    again = Normaliser.from_dict(json.loads(text))
    assert again.columns == scaler.columns and again.mean == scaler.mean
    assert again.std == scaler.std and again.ddof == 1
    pd.testing.assert_frame_equal(again.transform(_frame()), scaler.transform(_frame()))
    with pytest.raises(ValueError, match="'std'"):
        Normaliser.from_dict({"columns": ["a"], "mean": [0.0]})


def test_constant_and_empty_columns():
    frame = pd.DataFrame({"a": [3.0, 3.0, 3.0], "b": [np.nan, np.nan, 1.0], "c": [1.0, 2.0, 3.0]})
    with pytest.warns(PredictorWarning) as caught:
        scaler = Normaliser.fit(frame)
    messages = [str(w.message) for w in caught]
    assert any("a are constant" in m for m in messages)
    assert any("b have too few values" in m for m in messages)
    assert scaler.std[0] == 0.0
    z = scaler.transform(pd.DataFrame({"a": [3.0, 4.0, np.nan], "b": [1.0] * 3, "c": [2.0] * 3}))
    np.testing.assert_array_equal(z["a"], [0.0, 0.0, np.nan])
    assert z["b"].isna().all()
    restored = scaler.inverse_transform(z)
    np.testing.assert_array_equal(restored["a"], [3.0, 3.0, np.nan])
    # NaN parameters survive JSON as null
    data = scaler.to_dict()
    assert data["std"][1] is None
    assert np.isnan(Normaliser.from_dict(json.loads(json.dumps(data))).std[1])


def test_missing_columns_are_errors():
    scaler = Normaliser.fit(_frame())
    with pytest.raises(ValueError, match="water_temp_c"):
        scaler.transform(pd.DataFrame({"speed_kn": [1.0]}))
    with pytest.raises(ValueError, match="wind"):
        Normaliser.fit(_frame(), columns=["wind_speed_ms"])


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-1e6, 1e6, allow_nan=False, allow_subnormal=False), min_size=3, max_size=30)
)
def test_inverse_undoes_transform(values):
    frame = pd.DataFrame({"x": values})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PredictorWarning)
        scaler = Normaliser.fit(frame)
    restored = scaler.inverse_transform(scaler.transform(frame))
    if scaler.std[0] > 0:
        np.testing.assert_allclose(restored["x"], frame["x"], rtol=1e-9, atol=1e-6)
    else:
        np.testing.assert_allclose(restored["x"], scaler.mean[0])
