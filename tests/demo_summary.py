"""Numerical summary of the tables a short ``workbench demo`` run writes.

``tests/data/demo_summary.json`` holds the summary of the demo run of ``tests/test_demo.py``
(6 h, seed 0, synchronous scheduler); ``test_demo_tables_match_the_recorded_summary``
compares a fresh run with it, so a refactoring that changes any number of the demo's
tables fails. Record it again, from code whose numbers are known to be right, with::

    python tests/demo_summary.py OUT_DIR      # OUT_DIR: a finished demo folder

(run ``workbench demo --out OUT_DIR --hours 6 --scheduler synchronous --quiet`` first).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

SUMMARY = Path(__file__).resolve().parent / "data" / "demo_summary.json"

#: The demo's tables, relative to its output folder.
TABLES = (
    "identify/selected.parquet",
    "tracked_modal.csv",
    "predictors.csv",
    "correlation/correlation.csv",
    "fit/coefficients.csv",
    "fit/fit_statistics.csv",
    "fit/case_models.csv",
    "fit/case_coefficients.csv",
    "forecast.csv",
    "evaluation.csv",
)

QUANTILES = (0.0, 0.1, 0.5, 0.9, 1.0)


def _read(path: Path) -> pd.DataFrame:
    return pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)


def _number(value) -> float | None:
    value = float(value)
    return None if math.isnan(value) else value


def summarise_table(frame: pd.DataFrame) -> dict:
    """Rows, columns and, per column, a numerical or categorical fingerprint."""
    columns = {}
    for name in frame.columns:
        column = frame[name]
        if pd.api.types.is_bool_dtype(column):
            columns[name] = {"true": int(column.sum()), "count": int(column.notna().sum())}
        elif pd.api.types.is_numeric_dtype(column):
            values = column.to_numpy(dtype=float, na_value=np.nan)
            finite = values[np.isfinite(values)]
            columns[name] = {
                "count": int(finite.size),
                "sum": float(finite.sum()) if finite.size else 0.0,
                "abs_sum": float(np.abs(finite).sum()) if finite.size else 0.0,
                "quantiles": [_number(q) for q in np.quantile(finite, QUANTILES)]
                if finite.size
                else [],
            }
        else:
            text = column.astype("string").fillna("<NA>")
            counts = text.value_counts().sort_index()
            columns[name] = {"values": {str(k): int(v) for k, v in counts.items()}}
    return {"rows": len(frame), "columns": list(map(str, frame.columns)), "summary": columns}


def summarise(out_dir: str | Path) -> dict:
    out_dir = Path(out_dir)
    return {name: summarise_table(_read(out_dir / name)) for name in TABLES}


def compare(actual: dict, expected: dict, *, rtol: float = 1e-9) -> list[str]:
    """Differences between two summaries (empty when they agree).

    A number agrees when it is within *rtol* of the expected value, relative to the larger
    of the value and the column's sum of absolute values divided by its count (so sums of
    residuals near zero compare on the scale of the residuals).
    """
    problems = []
    for table, want in expected.items():
        got = actual.get(table)
        if got is None:
            problems.append(f"{table}: missing")
            continue
        if got["rows"] != want["rows"] or got["columns"] != want["columns"]:
            problems.append(
                f"{table}: {got['rows']} rows {got['columns']}, "
                f"expected {want['rows']} rows {want['columns']}"
            )
            continue
        for column, spec in want["summary"].items():
            have = got["summary"][column]
            if "quantiles" not in spec:
                if have != spec:
                    problems.append(f"{table}:{column}: {have} != {spec}")
                continue
            if have["count"] != spec["count"]:
                problems.append(f"{table}:{column}: count {have['count']} != {spec['count']}")
                continue
            scale = spec["abs_sum"] / max(spec["count"], 1)
            pairs = [
                ("sum", have["sum"], spec["sum"]),
                ("abs_sum", have["abs_sum"], spec["abs_sum"]),
            ]
            if spec["count"]:  # a column without a finite value has no quantiles
                pairs += [
                    (f"q{q:g}", a, b)
                    for q, a, b in zip(QUANTILES, have["quantiles"], spec["quantiles"], strict=True)
                ]
            for label, a, b in pairs:
                if a is None or b is None:
                    if a is not b:
                        problems.append(f"{table}:{column}: {label} {a} != {b}")
                    continue
                tolerance = rtol * max(abs(b), scale * (spec["count"] if "sum" in label else 1))
                if abs(a - b) > tolerance:
                    problems.append(f"{table}:{column}: {label} {a!r} != {b!r}")
    return problems


if __name__ == "__main__":  # pragma: no cover
    summary = summarise(sys.argv[1])
    SUMMARY.parent.mkdir(parents=True, exist_ok=True)
    SUMMARY.write_text(json.dumps(summary, indent=1, sort_keys=False) + "\n", encoding="utf-8")
    print(f"wrote {SUMMARY}")
