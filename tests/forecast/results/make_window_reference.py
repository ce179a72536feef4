"""Record the reference (window) forecast of a small synthetic voyage.

Run from the repository root, with the code whose results are the reference:
``python tests/forecast/results/make_window_reference.py``. window_reference.csv was
written by the window path as one function (before it was split into named steps in
:mod:`workbench.forecasting.window.forecast`), so tests/forecast/test_window_reference.py checks that
the split did not change the results: option A methods 1 and 2, option B method 2 (pole
table without shapes), 400 blocks, 3 modes.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

from make_memory_reference import COLUMNS as _MEMORY_COLUMNS  # noqa: E402
from make_memory_reference import case  # noqa: E402

#: The window model has no model-free guard (no model_probability column).
COLUMNS = [c for c in _MEMORY_COLUMNS if c != "model_probability"]

N_BLOCKS = 400
RUNS = (("A", 1), ("A", 2), ("B", 2))


def tables() -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """Modal table, predictors and a pole table (columns of poles around each estimate)."""
    modal, predictors = case()
    predictors = predictors[predictors["block"] < N_BLOCKS].reset_index(drop=True)
    modal = modal[modal["block"] < N_BLOCKS].reset_index(drop=True)
    rng = np.random.default_rng(5)
    orders = np.arange(20, 40, 2)
    rows = []
    for block, frequency in zip(modal["block"], modal["frequency_hz"], strict=True):
        f = frequency * (1 + 0.0008 * rng.standard_normal(orders.size))
        rows.append(
            pd.DataFrame(
                {
                    "block": block,
                    "model_order": orders,
                    "frequency_hz": f,
                    "damping_ratio": 0.01 * np.exp(0.1 * rng.standard_normal(orders.size)),
                    "stable": rng.random(orders.size) > 0.2,
                }
            )
        )
    for block in range(N_BLOCKS):
        n = 4
        rows.append(
            pd.DataFrame(
                {
                    "block": block,
                    "model_order": rng.choice(orders, n),
                    "frequency_hz": rng.uniform(1.5, 9.0, n),
                    "damping_ratio": rng.uniform(0.005, 0.08, n),
                    "stable": rng.random(n) < 0.3,
                }
            )
        )
    poles = pd.concat(rows, ignore_index=True).sort_values(["block", "model_order"])
    return modal, predictors, poles.reset_index(drop=True)


def forecast() -> pd.DataFrame:
    from workbench.forecasting import ForecastOptions, ForecastWarning, sliding_forecast

    modal, predictors, poles = tables()
    out = []
    for option, method in RUNS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ForecastWarning)
            table = sliding_forecast(
                modal,
                predictors,
                ForecastOptions(options=(option,), scheme=method, model="window"),
                poles=poles,
            ).table
        table = table[["block", "mode", "phase", *COLUMNS, "warning"]]
        out.append(table.assign(run=f"{option}{method}"))
    return pd.concat(out, ignore_index=True)


if __name__ == "__main__":
    target = Path(__file__).with_name("window_reference.csv")
    forecast().to_csv(target, index=False, float_format="%.17g")
    print(f"wrote {target}", file=sys.stderr)
