"""Render ``data_contracts/README.md`` from the contracts themselves.

Run ``python -m data_contracts._docs > data_contracts/README.md`` after changing a contract;
a test checks that the README is in sync.
"""

from __future__ import annotations

from ._core import TableContract
from .dship import DEFAULT_DSHIP_MAPPING, DSHIP_LOG
from .health import ALARMS, HEALTH
from .tables import FORECAST, MODAL, POLES, PREDICTORS

_INTRO = """\
# Data contracts

Every stage of workbench reads and writes the tables below. Schemas are code (this page is
generated from them by `python -m data_contracts._docs`); each validates lazily and raises
one `ContractError` listing every violation as `file: column 'x', rows 3, 7: reason`.

Conventions: units are part of column names; times are UTC (tz-aware in pandas, ISO-8601 with
`Z` in CSV); damping ratios are fractions (1.2 % is `0.012`); tables are read and written as
CSV or Parquet (chosen by suffix) with `read_table(path, CONTRACT)` / `write_table(df, path,
CONTRACT)`, which validate, write atomically (temporary file + rename) and round-trip exactly.
Columns not listed are kept (extra predictors, diagnostics).

**Blocks.** A voyage's block grid is anchored at `t0`, the first data time floored to the
block step. Block `k` covers `[t0 + k·step, t0 + k·step + length)`; by default `length` is
20 min with 75 % overlap, so `step` is 5 min. `block` is the integer `k`.

**Mode shapes.** One pair of float columns per channel `c`: `shape_re_<c>` and
`shape_im_<c>` (real and imaginary part). Shapes have unit Euclidean norm with the largest
component real and positive. `shapes_to_frame(channels, shapes)` and
`shapes_from_frame(df)` convert between columns and complex arrays.

## Accelerations (`accelerations`)

One file per acquisition interval (typically 5 minutes). Canonical format: NumPy `.npz`
written by `write_accelerations(record, path)`:

| array | shape / type | meaning |
|---|---|---|
| `acceleration` | float64, n_samples × n_channels | accelerations [m/s²]; NaN marks dropouts |
| `sampling_rate_hz` | float64 scalar | sampling rate [Hz] |
| `start_time` | string | time of the first sample, ISO-8601 UTC (`2026-01-01T00:00:00.000000Z`) |
| `channels` | string array, n_channels | unique channel names |

`read_accelerations(path)` also reads MATLAB `.mat` files (v5 via SciPy, v7.3/HDF5 via
h5py; variable names configurable with `mat_variables={"acceleration": "acc", ...}`; the
longer dimension is taken as samples unless `mat_orientation` says otherwise) and CSV files
(an ISO-8601 `time` column, one column per channel, the rate from the median time step).
Checks: 2-D numeric array, one unique name per channel, positive sampling rate, a valid
start time, no infinite values, |a| below 500 m/s² (larger values mean wrong units).

## Raw ship log (`dship`)

Delimited text as exported by the ship's data system (DSHIP) or PANGAEA: an optional
`/* ... */` description block, a header line with units in brackets (`Speed [kn]`,
`TTT [°C]`) or three header rows (name, sensor, unit), a `Date/Time` column, tab or `;`
separators, empty cells for missing values, UTF-8 or latin-1. `read_dship(path,
mapping=...)` maps source columns to the canonical columns below, converting units
(m/s ↔ kn, K → °C, km/h), sorts by time (warning), keeps the first of duplicate time stamps
(warning) and keeps every other numeric column under a snake_case name with its unit
(`dd [deg]` → `dd_deg`). Canonical columns without a source column are NaN (warning).

Default mapping (case-insensitive source names, with or without the bracketed unit):

| canonical column | source names tried |
|---|---|
{mapping}

"""


def _columns_table(contract: TableContract) -> str:
    lines = [
        "| column | type | unit | required | missing allowed | range / values | meaning |",
        "|---|---|---|---|---|---|---|",
    ]
    for column in contract.columns:
        if column.allowed is not None:
            limits = ", ".join(f"`{a}`" for a in column.allowed)
        elif column.minimum is not None or column.maximum is not None:
            low = "−∞" if column.minimum is None else f"{column.minimum:g}"
            high = "∞" if column.maximum is None else f"{column.maximum:g}"
            limits = f"[{low}, {high}]"
        else:
            limits = ""
        lines.append(
            f"| `{column.name}` | {column.kind} | {column.unit or ''} | "
            f"{'yes' if column.required else 'no'} | {'yes' if column.nullable else 'no'} | "
            f"{limits} | {column.description} |"
        )
    for pattern in contract.patterns:
        shown = (
            "`shape_re_<c>`, `shape_im_<c>`"
            if "shape" in pattern.regex
            else f"`{pattern.regex}`".replace("|", "\\|")
        )
        lines.append(
            f"| {shown} | {pattern.kind} | | no | "
            f"{'yes' if pattern.nullable else 'no'} | | {pattern.description} |"
        )
    text = "\n".join(lines)
    if contract.unique:
        text += f"\n\nUnique key: ({', '.join(f'`{c}`' for c in contract.unique)})."
    return text


_TITLES = {
    "predictors": "Block predictors",
    "modal": "Tracked modal table",
    "poles": "Pole table",
    "forecast": "Forecast table",
    "health": "Structural-health chart",
    "alarms": "Structural-health alarms",
}


def render_markdown() -> str:
    """The contracts documentation as Markdown."""
    mapping = "\n".join(
        f"| `{name}` | {', '.join(f'`{s}`' for s in sources)} |"
        for name, sources in DEFAULT_DSHIP_MAPPING.items()
    )
    parts = [_INTRO.replace("{mapping}", mapping).rstrip("\n")]
    parts.append("Canonical log after parsing:\n\n" + _columns_table(DSHIP_LOG))
    for contract in (PREDICTORS, MODAL, POLES, FORECAST, HEALTH, ALARMS):
        parts.append(
            f"## {_TITLES[contract.name]} (`{contract.name}`)\n\n"
            f"{contract.description}\n\n"
            f"{_columns_table(contract)}"
        )
    return "\n\n".join(parts) + "\n"


if __name__ == "__main__":  # pragma: no cover
    print(render_markdown(), end="")
