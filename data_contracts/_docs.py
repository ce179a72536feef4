"""Render ``data_contracts/README.md`` from the contracts themselves.

Run ``python -m data_contracts._docs > data_contracts/README.md`` after changing a contract;
a test checks that the README is in sync.
"""

from __future__ import annotations

from ._core import TableContract
from .dship import DSHIP_LOG
from .dship_names import DSHIP_NAMES
from .geometry import SENSOR_GEOMETRY
from .health import ALARMS, HEALTH
from .tables import FORECAST, MODAL, POLES, PREDICTORS, SELECTED

_INTRO = """\
# Data contracts

Every stage of workbench reads and writes the tables below. Schemas are code (this page is
generated from them by `python -m data_contracts._docs`); each validates lazily and raises
one `ContractError` listing every violation as `file: column 'x', rows 3, 7: reason`.

Conventions: units are part of column names; times are UTC (tz-aware in pandas, ISO-8601 with
`Z` in CSV; a time written in a recognised form has every digit of its last field, its
minutes and seconds: `2026-03-01T00:1` is refused, not read as 00:01, while an unpadded day,
month or hour that another field follows reads, `13/3/2026 0:05`); damping ratios are
fractions (1.2 % is `0.012`); tables are read and written as CSV or Parquet (chosen by suffix) with `read_table(path, CONTRACT)` / `write_table(df, path,
CONTRACT)`, which validate, write atomically (temporary file + rename) and round-trip exactly.
Columns not listed are kept (extra predictors, diagnostics).

**Blocks.** A voyage's block grid is anchored at `t0`, the first data time floored to the
block step. Block `k` covers `[t0 + k·step, t0 + k·step + length)`; by default `length` is
20 min with 75 % overlap, so `step` is 5 min. `block` is the integer `k`.
Every block-level table records its grid, so later stages use it instead of guessing it
from the block starts (a table of one block cannot tell its step): `read_table` attaches it
as `frame.attrs["block_grid"]` (`{"t0": ISO-8601 UTC, "length_s": s, "step_s": s}`) and
`write_table` stores it in the Parquet key-value metadata (`workbench.block_grid`, the same
JSON) or, beside a CSV file, in a sidecar `<file name>.grid.json` (the CSV stays a plain
table). Files without a recorded grid read as before; a recorded grid that contradicts the
`block`/`block_start`/`block_end` columns is ignored with a warning.

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

`read_accelerations(path, layout=...)` also reads, by suffix (module `data_contracts.formats`;
`layout` is an `AccelerationLayout` or a dict of its fields, CLI flags in brackets):

| suffix | layout |
|---|---|
| `.mat` | v5 (SciPy) or v7.3 (h5py); variables found under their usual names (`data`, `fs`, `t0`, `chanNames`, ...) or named (`variables`, `--variables acceleration=X,...`); `t0` as text, MATLAB datenum or datevec |
| `.csv`, `.tsv`, `.txt` | a time column (`time`, `Timestamp`, `Time [s]`, ... or `time_column`) in ISO-8601, `yyyy/mm/dd`, `dd.mm.yyyy`, `dd-mmm-yyyy` (MATLAB `datestr`), slash dates whose days tell day and month apart, a `time_format` (strptime or MATLAB symbols), or relative seconds plus `start_time` (a time, or `filename` for the time in the file name); separator and decimal comma detected; the header row is found below an acquisition system's metadata lines (NI, Dewesoft, catman exports; a units row below it is read), whose `Start time`, `Sample rate`, `Sampling Rate (Hz)`, `dt` lines are used; one column per channel |
| `.h5`, `.hdf5` | the 2-D dataset (or a group of one 1-D dataset per channel), rate, start and channel names as datasets beside it or attributes, or named (`variables`) |
| `.uff`, `.unv` | dataset 58 time responses (function type 1) via `pyuff`; channels named by node and direction (`101+Z`); start from the ID lines or `start_time`; every record complete (a file ending inside a record is refused), evenly spaced with a positive increment, its declared number of points equal to its values, at least 16 samples |

Units come from `units` (one for all channels or per channel), else from the headers or
HDF5/UFF unit labels (`acc01 [g]`, `[mm/s^2]`), else m/s²; g, mg, mm/s², cm/s², gal and
ft/s² are converted to m/s². A file that cannot be read is reported with what it contains
(columns, variables, datasets).
Checks: 2-D real numeric array (complex and boolean values refused), one unique name per channel,
positive sampling rate, a start time that is a time (ISO-8601 text or a datetime; a number
is refused, not read as nanoseconds since 1970), no infinite values, |a| below 500 m/s²
(larger values mean wrong units). Text-file times must increase strictly (shuffled or
duplicated rows are refused), every step must lie within half a sample of the sampling
interval (a gap inside a file would shift the later samples: split the file there) and a
given sampling rate must agree with the times.

**Files that read other files or memory they do not hold.** One rule for every container
format (HDF5 `.h5`/`.hdf5`, MATLAB v7.3, any future one; `data_contracts.formats.containers`):
a file must hold its own data. A file with an HDF5 external link, user-defined link,
external storage or virtual dataset anywhere is refused before any value is read (such a
file could make the reader open any local file and show its bytes in a message or a
table); soft links resolve inside the file; every dataset read is checked again. Before an
array is allocated, its declared size is checked (`data_contracts.limits`) against the
bytes the file stores for it (at most 1100:1, deflate's ceiling) and against the memory
budget of one array, 4 GiB as float64 unless the environment variable
`WORKBENCH_MAX_ARRAY_BYTES` sets another (`8G`, `500M`, bytes): `.npz`, `.mat` (v5 and
v7.3) and `.h5` alike. No file may have more than 1024 channels (a text file's header line
is counted before it is parsed). A file that is not an `.npz` archive of numeric arrays is
one line, `not a valid .npz acceleration file (...)`; pickled objects are never loaded.

## Raw ship log (`dship`)

Delimited text as exported by the ship's data system (DSHIP) or PANGAEA: an optional
`/* ... */` description block, a header line with units in brackets (`Speed [kn]`,
`TTT [°C]`) or up to three header rows (name, description, unit), DSHIP channel names
`DEVICE.SENSOR.PARAMETER` (`SYS.STR.SOG`), a time column (ISO-8601, `yyyy/mm/dd HH:MM:SS`
or day-first `dd.mm.yyyy HH:MM:SS`; UTC unless an offset is given), tab or `;`
separators, decimal points or commas, empty cells for missing values, UTF-8 or latin-1.
`read_dship(path, mapping=...)` (CLI: `--dship-columns speed_kn=NAME,...`) maps source
columns to the canonical columns below, converting units (m/s ↔ kn, K → °C, km/h), sorts
by time (warning), keeps the first of duplicate time stamps (warning) and keeps every other
numeric column under a snake_case name with its unit (`dd [deg]` → `dd_deg`). Canonical
columns without a source column are NaN (warning). Without a relative wind direction but
with the true wind, heading, course and speed, the relative (apparent) wind is derived:
direction the wind comes from, clockwise from the bow, and its speed.

Default names (case, spaces and underscores ignored, with or without the bracketed unit; a
name also matches the last part of a dotted DSHIP name, and two such matches are refused
rather than guessed). `wind_dir_true_deg`, `wind_speed_true_ms`, `heading_deg` and
`course_deg` are read only to derive the relative wind; `shaft_rpm` (shaft or propeller
speed, rpm) is kept in the canonical log but is not a predictor: `workbench identify
--dship` draws the shaft and blade-pass orders from it and keeps them out of the modes.
Each column is also found under its canonical name (last, after the names below), so a
log written with these names needs no mapping.

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
            limits = f"{'(' if column.exclusive_minimum else '['}{low}, {high}]"
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


_MODAL_LAYOUTS = """

Modal tables of other tools are read into this table by `read_modal_table(path, ...)` in
`data_contracts.modal_layout` (the commands `correlate`, `fit`, `forecast` and `evaluate`
use it): long (`time, mode, frequency, damping`, also `Frequency [Hz]`, `Damping [%]`,
`zeta`, mode labels such as `Mode 2`), wide (`f1, f2, ..., d1, d2, ...`) or indexed by
`block` (with the grid's `t0`). Times mark the start, centre or end of the analysis
window (`time_reference`, or from names such as `window_centre`; else start, with a
warning) and are placed on the block grid; times off the grid are refused by row.
Damping is a fraction unless the header (`[%]`, `_pct`) or `damping_unit` says percent;
a header that says nothing needs `damping_unit`; a table without damping leaves
`damping_ratio` empty (warning). Naive times are UTC with a warning unless
`time_zone` is given. Rows without a frequency are dropped with a warning that counts
them."""

_TITLES = {
    "predictors": "Block predictors",
    "modal": "Tracked modal table",
    "poles": "Pole table",
    "selected": "Selected modes",
    "forecast": "Forecast table",
    "sensor_geometry": "Sensor geometry",
    "health": "Structural-health chart",
    "alarms": "Structural-health alarms",
}


def render_markdown() -> str:
    """The contracts documentation as Markdown."""
    mapping = "\n".join(
        f"| `{name}` | {', '.join(f'`{s}`' for s in sources)} |"
        for name, sources in DSHIP_NAMES.items()
    )
    parts = [_INTRO.replace("{mapping}", mapping).rstrip("\n")]
    parts.append("Canonical log after parsing:\n\n" + _columns_table(DSHIP_LOG))
    for contract in (
        PREDICTORS,
        MODAL,
        POLES,
        SELECTED,
        FORECAST,
        SENSOR_GEOMETRY,
        HEALTH,
        ALARMS,
    ):
        parts.append(
            f"## {_TITLES[contract.name]} (`{contract.name}`)\n\n"
            f"{contract.description}\n\n"
            f"{_columns_table(contract)}" + (_MODAL_LAYOUTS if contract is MODAL else "")
        )
    return "\n\n".join(parts) + "\n"


if __name__ == "__main__":  # pragma: no cover
    print(render_markdown(), end="")
