"""The block-level tables every stage reads and writes.

Contracts: :data:`PREDICTORS` (block-averaged ship log), :data:`MODAL` (tracked modal table),
:data:`POLES` (stabilisation diagrams), :data:`SELECTED` (the modes selected automatically in
each block, input of tracking), :data:`FORECAST` (sliding-model and Kalman estimates). Each
is a :class:`~data_contracts._core.TableContract`; read and write them with
:func:`read_table` / :func:`write_table`, which validate, use CSV or Parquet by suffix and
carry the block grid the table was computed on (:mod:`data_contracts.grid`).

Mode shapes are stored as two float columns per channel, ``shape_re_<channel>`` and
``shape_im_<channel>``; :func:`shapes_to_frame` and :func:`shapes_from_frame` convert.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from . import grid as _grid
from ._core import (
    CSV_READ_OPTIONS,
    Column,
    ColumnPattern,
    ContractError,
    TableContract,
    Violation,
    atomic_path,
)
from .csv_layout import decode_text, ends_mid_row, sniff_layout

__all__ = [
    "CANONICAL_PREDICTORS",
    "FORECAST",
    "OPTIONAL_PREDICTORS",
    "MODAL",
    "POLES",
    "PREDICTORS",
    "SELECTED",
    "CONTRACTS",
    "read_table",
    "shape_columns",
    "shapes_from_frame",
    "shapes_to_frame",
    "write_table",
]

SHAPE_REGEX = r"shape_(re|im)_(.+)"
_SHAPES = ColumnPattern(
    SHAPE_REGEX,
    "float",
    "Mode-shape component at a channel: real (`shape_re_<channel>`) and imaginary "
    "(`shape_im_<channel>`) part. Shapes are normalised to unit Euclidean norm with the "
    "largest component real and positive.",
)

_BLOCK = Column(
    "block",
    "int",
    "Block number k on the voyage's block grid (block k starts at t0 + k * step).",
    minimum=0,
)
_BLOCK_START = Column("block_start", "time", "Start of the block (inclusive), UTC.", unit="UTC")
_BLOCK_END = Column("block_end", "time", "End of the block (exclusive), UTC.", unit="UTC")
_MODE = Column(
    "mode",
    "int",
    "Mode label, stable across blocks after tracking: an identifier, any integer (0 and "
    "negative labels included).",
)
_FREQUENCY = Column(
    "frequency_hz",
    "float",
    "Frequency of the pole; a real pole (no oscillation) is at 0 Hz.",
    unit="Hz",
    minimum=0.0,
    maximum=1.0e4,
)
#: A mode's natural frequency: above 0 Hz (a row at 0 Hz is no mode; the poles at 0 Hz of a
#: stabilisation diagram are real poles, which selection leaves out, ζ = 1 > its limit).
_NATURAL_FREQUENCY = Column(
    "frequency_hz",
    "float",
    "Natural frequency.",
    unit="Hz",
    minimum=0.0,
    maximum=1.0e4,
    exclusive_minimum=True,
    hint="a natural frequency lies above 0 Hz",
)
_DAMPING = Column(
    "damping_ratio",
    "float",
    "Viscous damping ratio as a fraction of critical damping.",
    minimum=-1.0,
    maximum=1.0,
    hint="damping ratios are fractions: 1.2 % is 0.012",
)

_HARMONIC = Column(
    "harmonic",
    "float",
    "Shaft order the row is (1 = the shaft rate, the blade count for the blade pass), from "
    "the logged shaft speed; 0: a harmonic found from the data (frequency following the "
    "speed with a fixed shape), order unknown; NaN: not a harmonic. Tracking keeps marked "
    "rows out of the modes (workbench.sid.harmonics).",
    required=False,
    nullable=True,
    minimum=0.0,
)

_MPC = Column(
    "mpc",
    "float",
    "Modal phase collinearity of the shape (1 = real mode).",
    required=False,
    nullable=True,
    minimum=0.0,
    maximum=1.0 + 1e-9,
)

#: Canonical predictor columns, with their physical bounds used for plausibility checks.
CANONICAL_PREDICTORS: tuple[Column, ...] = (
    Column(
        "speed_kn",
        "float",
        "Ship speed through water or over ground.",
        unit="kn",
        nullable=True,
        minimum=-5.0,
        maximum=40.0,
        hint="speed is in knots; 1 m/s = 1.944 kn",
    ),
    Column(
        "water_temp_c",
        "float",
        "Sea-water temperature.",
        unit="°C",
        nullable=True,
        minimum=-3.0,
        maximum=40.0,
        hint="temperatures are in °C, not K",
    ),
    Column(
        "air_temp_c",
        "float",
        "Air temperature.",
        unit="°C",
        nullable=True,
        minimum=-70.0,
        maximum=60.0,
        hint="temperatures are in °C, not K",
    ),
    Column(
        "wind_speed_ms",
        "float",
        "Wind speed.",
        unit="m/s",
        nullable=True,
        minimum=0.0,
        maximum=100.0,
        hint="wind speed is in m/s; 1 kn = 0.514 m/s",
    ),
    Column(
        "wind_dir_rel_deg",
        "float",
        "Wind direction relative to the bow, clockwise.",
        unit="deg",
        nullable=True,
        minimum=0.0,
        maximum=360.0,
    ),
)

#: Canonical predictors that are angles on a circle (0 and 360 the same direction): a
#: block's value is the circular mean of the log's readings, and models, correlations and
#: range checks take the angle's cosine (:mod:`workbench.predictors.directions`),
#: never the angle as a number (359° and 1° are 2° apart, not 358°).
DIRECTION_PREDICTORS: tuple[str, ...] = ("wind_dir_rel_deg",)

#: Optional predictor columns: read from the ship log when it carries them, never filled
#: with NaN when it does not, and not among the canonical predictors the forecast and
#: correlation stages use by default (the structural-health model uses them).
OPTIONAL_PREDICTORS: tuple[Column, ...] = (
    Column(
        "fuel_on_board_t",
        "float",
        "Fuel on board, the sum of the fuel tanks' soundings (consumption lowers the hull's "
        "mass and so raises its natural frequencies).",
        unit="t",
        required=False,
        nullable=True,
        minimum=0.0,
        maximum=1.0e6,
        hint="fuel on board is in tonnes (1 t = 1000 kg)",
    ),
)


#: How much of a block the ship log covers. Not a predictor: a quality mark of the
#: block's predictors, kept beside them and never used as a regression term.
LOG_COVERAGE = Column(
    "log_coverage",
    "float",
    "Share of the block the ship log covers, the least over the canonical predictors the "
    "log carries (1: every reading there; below 1 the block's predictors are means of its "
    "logged part; below the averaging's minimum coverage they are NaN). Not a predictor.",
    required=False,
    nullable=True,
    minimum=0.0,
    maximum=1.0,
)


def column_log_coverage_name(column: str) -> str:
    """The predictor table's column holding the log's coverage of each block by *column*
    (``log_coverage_speed_kn`` for ``speed_kn``)."""
    return f"{LOG_COVERAGE.name}_{column}"


#: How much of a block the ship log covers, per canonical predictor: the share of the block
#: that column's readings cover. ``log_coverage`` is their least. Not predictors.
COLUMN_LOG_COVERAGE: tuple[Column, ...] = tuple(
    Column(
        column_log_coverage_name(predictor.name),
        "float",
        f"Share of the block the ship log's {predictor.name} readings cover (1: every "
        "reading there; below 1 the block's value of the column is the mean of its logged "
        "part; below the averaging's minimum coverage it is NaN); NaN when the log has no "
        f"reading of {predictor.name}. Not a predictor.",
        required=False,
        nullable=True,
        minimum=0.0,
        maximum=1.0,
    )
    for predictor in CANONICAL_PREDICTORS
)

#: Columns of a predictor table that are not predictors: the block keys and the log's
#: coverage of the block (the least and per canonical column).
PREDICTOR_KEYS: tuple[str, ...] = (
    "block",
    "block_start",
    "block_end",
    LOG_COVERAGE.name,
    *(c.name for c in COLUMN_LOG_COVERAGE),
)


def _end_after_start(frame: pd.DataFrame) -> list[Violation]:
    bad = (frame["block_end"] <= frame["block_start"]).to_numpy(dtype=bool, na_value=False)
    if not bad.any():
        return []
    rows = tuple(frame.index[bad][:5].tolist())
    return [Violation("block_end", "block_end must be after block_start", rows, int(bad.sum()))]


def _one_start_per_block(frame: pd.DataFrame) -> list[Violation]:
    starts = frame.groupby("block")["block_start"].nunique()
    bad_blocks = starts.index[starts > 1]
    if len(bad_blocks) == 0:
        return []
    rows_mask = frame["block"].isin(bad_blocks).to_numpy()
    rows = tuple(frame.index[rows_mask][:5].tolist())
    return [
        Violation("block_start", "one block has several start times", rows, int(rows_mask.sum()))
    ]


def _interval_contains_model(frame: pd.DataFrame) -> list[Violation]:
    lower = frame["model_lower_hz"].to_numpy(dtype=float)
    mean = frame["model_frequency_hz"].to_numpy(dtype=float)
    upper = frame["model_upper_hz"].to_numpy(dtype=float)
    tol = 1e-9 * np.maximum(1.0, np.abs(mean))
    with np.errstate(invalid="ignore"):
        bad = (lower > mean + tol) | (mean > upper + tol)
    if not bad.any():
        return []
    rows = tuple(frame.index[bad][:5].tolist())
    return [
        Violation(
            "model_lower_hz, model_upper_hz",
            "prediction interval must contain model_frequency_hz",
            rows,
            int(bad.sum()),
        )
    ]


def _window_order(frame: pd.DataFrame) -> list[Violation]:
    bad = (frame["window_end_block"] < frame["window_start_block"]).to_numpy(
        dtype=bool, na_value=False
    )
    if not bad.any():
        return []
    rows = tuple(frame.index[bad][:5].tolist())
    return [Violation("window_end_block", "window ends before it starts", rows, int(bad.sum()))]


#: The combined modal model of identify --cross-check (SSI and LSCF of one block, see
#: workbench.sid.combined): optional in the selected and the tracked modal tables.
_COMBINED = (
    Column(
        "combined_frequency_hz",
        "float",
        "Inverse-variance mean of the methods' frequencies of this mode (SSI and LSCF with "
        "--cross-check; the method's own where the other has no such mode).",
        unit="Hz",
        required=False,
        nullable=True,
        minimum=0.0,
    ),
    Column(
        "combined_frequency_std_hz",
        "float",
        "Uncertainty of combined_frequency_hz: each method's scatter over its model orders "
        "and their disagreement. The forecast's per-block measurement noise when present.",
        unit="Hz",
        required=False,
        nullable=True,
        minimum=0.0,
    ),
    Column(
        "combined_damping_ratio",
        "float",
        "Combined damping ratio (as combined_frequency_hz).",
        required=False,
        nullable=True,
    ),
    Column(
        "combined_damping_std",
        "float",
        "Uncertainty of combined_damping_ratio.",
        required=False,
        nullable=True,
        minimum=0.0,
    ),
    Column(
        "combined_methods",
        "nullable_int",
        "Number of methods that found the mode (2: SSI and LSCF agree on it); missing, "
        "with the other combined columns, where the combined model leaves the mode out (a "
        "second-look mode the other method does not confirm).",
        required=False,
        nullable=True,
        minimum=1,
    ),
)

#: The block's own uncertainty, from SSI on each half of the block: optional in the selected
#: and the tracked modal tables.
_HALVES = (
    Column(
        "half_difference_hz",
        "float",
        "The mode's frequency in the first half of the block minus that in the second "
        "(SSI on each half; missing where a half does not show the mode, and for LSCF). "
        "(difference / 2)² estimates the variance of frequency_hz; the forecast's guard "
        "measures its distance from SSI against it.",
        unit="Hz",
        required=False,
        nullable=True,
    ),
)

#: Adaptive block length (identify --block-minutes auto): optional in the selected and the
#: tracked modal tables (and in blocks.csv).
_ADAPTIVE = (
    Column(
        "block_length_s",
        "float",
        "Length of the block the mode was identified in (block_end - block_start); with "
        "--block-minutes auto it differs from block to block.",
        unit="s",
        required=False,
        nullable=True,
        minimum=0.0,
    ),
    Column(
        "excitation_range_db",
        "float",
        "Stationarity of the block: ratio of the largest to the smallest excitation power "
        "(median over channels of the conditioned accelerations' variance) over the "
        "block's half-steps, in dB (0: steady excitation).",
        unit="dB",
        required=False,
        nullable=True,
        minimum=0.0,
    ),
    Column(
        "speed_range_kn",
        "float",
        "Range of the ship's speed over the block (largest minus smallest half-step mean of "
        "the ship log); NaN without a log.",
        unit="kn",
        required=False,
        nullable=True,
        minimum=0.0,
    ),
)

PREDICTORS = TableContract(
    name="predictors",
    description="Ship-log predictors averaged over the blocks of the voyage's block grid, "
    "one row per block. NaN where a block had too little valid data.",
    columns=(
        _BLOCK,
        _BLOCK_START,
        _BLOCK_END,
        LOG_COVERAGE,
        *COLUMN_LOG_COVERAGE,
        *CANONICAL_PREDICTORS,
        *OPTIONAL_PREDICTORS,
    ),
    unique=("block",),
    checks=(_end_after_start,),
)

MODAL = TableContract(
    name="modal",
    description="Tracked modal table, long format: one row per block and tracked mode.",
    columns=(
        _BLOCK,
        _BLOCK_START,
        _BLOCK_END,
        _MODE,
        _NATURAL_FREQUENCY,
        Column(
            "damping_ratio",
            "float",
            "Viscous damping ratio as a fraction of critical damping; NaN where the source "
            "gave a frequency only (e.g. a frequency-only table of another tool).",
            nullable=True,
            minimum=-1.0,
            maximum=1.0,
            hint="damping ratios are fractions: 1.2 % is 0.012",
        ),
        Column(
            "mac",
            "float",
            "MAC (or MACXP) between the block's mode shape and the tracked reference shape.",
            required=False,
            nullable=True,
            minimum=0.0,
            maximum=1.0,
        ),
        Column(
            "model_order",
            "nullable_int",
            "Model order the pole was selected at.",
            required=False,
            nullable=True,
            minimum=1,
        ),
        *_COMBINED,
        *_HALVES,
        *_ADAPTIVE,
    ),
    patterns=(_SHAPES,),
    unique=("block", "mode"),
    checks=(_end_after_start, _one_start_per_block),
)

POLES = TableContract(
    name="poles",
    description="Stabilisation diagrams: one row per identified pole (one per complex-conjugate "
    "pair, positive imaginary part), per block and model order.",
    columns=(
        _BLOCK,
        Column(
            "model_order",
            "int",
            "Model order (state dimension) of the identified system.",
            minimum=1,
        ),
        _FREQUENCY,
        _DAMPING,
        Column(
            "stable",
            "bool",
            "Pole is stable in frequency, damping and shape against the previous model order.",
        ),
        _MPC,
        _HARMONIC,
    ),
    patterns=(_SHAPES,),
)

SELECTED = TableContract(
    name="selected",
    description="Modes selected automatically from each block's stabilisation diagram (the "
    "input of tracking): one row per block and selected mode, ordered by frequency within "
    "the block. Mode labels are assigned later, by tracking.",
    columns=(
        _BLOCK,
        _BLOCK_START,
        _BLOCK_END,
        _NATURAL_FREQUENCY,
        _DAMPING,
        Column(
            "model_order",
            "int",
            "Model order of the pole that represents the mode (written by identify; "
            "tracking does not need it).",
            required=False,
            minimum=1,
        ),
        _MPC,
        Column(
            "stable",
            "bool",
            "The representing pole is stable against the previous model order.",
            required=False,
        ),
        Column(
            "pole_index",
            "int",
            "Row of the representing pole among the block's poles (all orders).",
            required=False,
            minimum=0,
        ),
        Column(
            "frequency_std_hz",
            "float",
            "Scatter of the frequency over the poles of the mode's cluster.",
            unit="Hz",
            required=False,
            nullable=True,
            minimum=0.0,
        ),
        Column(
            "damping_std",
            "float",
            "Scatter of the damping ratio over the poles of the mode's cluster.",
            required=False,
            nullable=True,
            minimum=0.0,
        ),
        Column(
            "n_poles",
            "int",
            "Poles in the mode's cluster (one per model order at most).",
            required=False,
            minimum=1,
        ),
        _HARMONIC,
        Column(
            "harmonic_frequency_hz",
            "float",
            "Frequency of the marked order at the block's shaft speed (weighted by rpm⁴; "
            "from the speed and the shaft rate per knot found, without a logged shaft "
            "speed); NaN for a mode that is not marked. Tracking checks that a label's "
            "marked rows follow it.",
            unit="Hz",
            required=False,
            nullable=True,
            minimum=0.0,
        ),
        Column(
            "harmonic_checked",
            "bool",
            "Whether the ship log let the block's harmonics be marked (a usable shaft speed, "
            "or the speed); False: an outage, a frozen sensor or a log not covering the "
            "block. Tracking keeps a label with unchecked rows only if it is seen as a mode "
            "in checked blocks.",
            required=False,
        ),
        *_COMBINED,
        *_HALVES,
        *_ADAPTIVE,
    ),
    patterns=(_SHAPES,),
    checks=(_end_after_start, _one_start_per_block),
)

FORECAST = TableContract(
    name="forecast",
    description="Sliding-model forecasts and Kalman-blended estimates, one row per block, "
    "mode and option.",
    columns=(
        _BLOCK,
        _BLOCK_START,
        _MODE,
        Column(
            "phase",
            "str",
            "'train' inside the training window, 'forecast' after it.",
            allowed=("train", "forecast"),
        ),
        Column(
            "ssi_frequency_hz",
            "float",
            "SSI estimate used as measurement (NaN: none).",
            unit="Hz",
            nullable=True,
            minimum=0.0,
        ),
        Column(
            "model_frequency_hz", "float", "Regression-model prediction.", unit="Hz", minimum=0.0
        ),
        Column("model_lower_hz", "float", "Lower 95 % prediction bound.", unit="Hz"),
        Column("model_upper_hz", "float", "Upper 95 % prediction bound.", unit="Hz"),
        Column("kalman_frequency_hz", "float", "Kalman-blended estimate.", unit="Hz", minimum=0.0),
        Column(
            "kalman_std_hz",
            "float",
            "Standard deviation of the Kalman estimate.",
            unit="Hz",
            minimum=0.0,
        ),
        Column(
            "option",
            "str",
            "A: measurement is the tracked pole; B: nearest pole of the stabilisation diagram.",
            allowed=("A", "B"),
        ),
        Column("window_start_block", "int", "First block of the training window used.", minimum=0),
        Column("window_end_block", "int", "Last block of the training window used.", minimum=0),
        Column(
            "model_probability",
            "float",
            "How much the Kalman estimate leaned on the model in this block: the "
            "probability that the model explains the mode, weighed against a filter that "
            "does not use the model by how well each predicted the measurements (the next "
            "block's, and the first block that shares no data with the present; 1: the "
            "blend of model and SSI; 0: the model-free estimate, which follows SSI). NaN "
            "where the row has no estimate or the forecast does not weigh them.",
            required=False,
            nullable=True,
            minimum=0.0,
            maximum=1.0,
        ),
        Column(
            "guard_weight",
            "float",
            "How far the estimate was left where the blend put it: 1 where its distance "
            "from SSI is within SSI's own error (measured on the blocks' halves, "
            "half_difference_hz); below 1, the estimate was drawn toward SSI in that "
            "proportion (SSI + weight x (blend, or its prediction of the block, - SSI)). "
            "NaN where the row has no estimate, the modal table has no half-block errors, "
            "or the blocks overlap (the guard's test needs blocks that share no data).",
            required=False,
            nullable=True,
            minimum=0.0,
            maximum=1.0,
        ),
        Column(
            "log_coverage",
            "float",
            "The predictor table's log_coverage of the row's block: the share of the block "
            "the ship log covers (below 1 the model read means of the logged part, or "
            "filled predictors where too little of it was logged). NaN where the predictor "
            "table gives none.",
            required=False,
            nullable=True,
            minimum=0.0,
            maximum=1.0,
        ),
    ),
    unique=("block", "mode", "option"),
    checks=(_interval_contains_model, _window_order),
)

#: Contracts by the name used on the command line.
from .geometry import SENSOR_GEOMETRY  # noqa: E402  (after the tables it sits beside)

CONTRACTS: dict[str, TableContract] = {
    c.name: c for c in (PREDICTORS, MODAL, POLES, SELECTED, FORECAST, SENSOR_GEOMETRY)
}


# --------------------------------------------------------------------------- mode shapes
def shape_columns(channels: Sequence[str]) -> list[str]:
    """Column names for the mode shapes of *channels*: all real parts, then imaginary parts."""
    return [f"shape_re_{c}" for c in channels] + [f"shape_im_{c}" for c in channels]


def shapes_to_frame(
    channels: Sequence[str], mode_shapes: np.ndarray, index: pd.Index | None = None
) -> pd.DataFrame:
    """Mode shapes (n_rows x n_channels, complex) as ``shape_re_*``/``shape_im_*`` columns."""
    shapes = np.atleast_2d(np.asarray(mode_shapes))
    if shapes.shape[1] != len(channels):
        raise ValueError(
            f"mode_shapes has {shapes.shape[1]} channels but {len(channels)} channel names"
        )
    data = np.concatenate([shapes.real, shapes.imag], axis=1).astype(float)
    return pd.DataFrame(data, columns=shape_columns(channels), index=index)


def shapes_from_frame(frame: pd.DataFrame) -> tuple[list[str], np.ndarray]:
    """Channel names and complex mode shapes (n_rows x n_channels) from shape columns.

    Channels keep the order of their ``shape_re_`` columns; a missing imaginary column is
    read as zero.
    """
    channels = [c[len("shape_re_") :] for c in frame.columns if str(c).startswith("shape_re_")]
    real = frame[[f"shape_re_{c}" for c in channels]].to_numpy(dtype=float)
    imag = np.zeros_like(real)
    for j, c in enumerate(channels):
        if f"shape_im_{c}" in frame.columns:
            imag[:, j] = frame[f"shape_im_{c}"].to_numpy(dtype=float)
    return channels, real + 1j * imag


# --------------------------------------------------------------------------- file I/O
def _format_of(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return "csv"
    if suffix in (".parquet", ".pq"):
        return "parquet"
    raise ContractError(
        [Violation(None, f"unknown table format '{suffix}' (use .csv or .parquet)")],
        source=path,
    )


def read_table(path: str | os.PathLike, contract: TableContract) -> pd.DataFrame:
    """Read a CSV or Parquet table and validate it against *contract*.

    A CSV file is comma-separated with decimal points, as :func:`write_table` writes it,
    or ``;``-separated with decimal commas or points, as a spreadsheet re-saves it in
    such a locale (:func:`~data_contracts.csv_layout.sniff_layout`).

    A parted table (a folder of parts with its index, :mod:`data_contracts.parts`) is
    read as the one table its parts make.

    The block grid recorded with the file (Parquet metadata, or the CSV's
    ``<name>.grid.json`` sidecar; see :mod:`data_contracts.grid`) is attached to the
    returned frame as ``frame.attrs["block_grid"]``.

    Raises
    ------
    ContractError
        When the file is missing, unreadable or violates the contract; every message line
        names the file.
    """
    path = Path(path)
    fmt = _format_of(path)
    if fmt == "parquet" and path.is_dir():
        from .parts import is_parted, read_parts

        if is_parted(path):  # a table written a part at a time (data_contracts.parts)
            return read_parts(path, contract)
    if not path.is_file():
        raise ContractError(
            [Violation(None, "file not found")], source=path, contract=contract.name
        )
    try:
        if fmt == "csv":
            # ',' as written here; ';' with decimal commas as a spreadsheet re-saves it
            lines = decode_text(path.read_bytes(), None).splitlines()
            sep, decimal = sniff_layout(lines)
            cut = ends_mid_row(lines, sep)
            if cut is not None:
                raise ValueError(cut)
            frame = pd.read_csv(
                path, sep=sep, decimal=decimal, low_memory=False, **CSV_READ_OPTIONS
            )
        else:
            frame = pd.read_parquet(path)
    except Exception as error:  # pandas/pyarrow raise many types for unreadable files
        reason = f"cannot read {fmt.upper()} file: {str(error).splitlines()[0] if str(error) else type(error).__name__}"
        raise ContractError(
            [Violation(None, reason)], source=path, contract=contract.name
        ) from None
    frame.attrs.pop(_grid.GRID_ATTR, None)
    table = contract.validate(frame, source=path)
    return _grid.attach_grid(table, _grid.read_grid(path, fmt), path)


def write_table(
    frame: pd.DataFrame, path: str | os.PathLike, contract: TableContract, *, grid=None
) -> Path:
    """Validate *frame* and write it atomically as CSV or Parquet (by suffix).

    Times are written as ISO-8601 UTC; floats with the shortest text that reads back to
    the same double, so a CSV round trip is exact.

    Parameters
    ----------
    grid : mapping or BlockGrid, optional
        The block grid of the table's blocks (default: the one recorded with *frame*, if
        any). Stored in the Parquet metadata, or beside a CSV file as
        ``<name>.grid.json``; see :mod:`data_contracts.grid`.

    Raises
    ------
    ContractError
        When *frame* violates the contract, or its blocks are not on *grid*.
    """
    path = Path(path)
    fmt = _format_of(path)
    record = _grid.grid_record(grid) if grid is not None else _grid.recorded_grid(frame)
    table = contract.validate(frame)
    if record is not None:
        reason = _grid.grid_mismatch(table, record)
        if reason is not None:
            raise ContractError([Violation(None, reason)], source=path, contract=contract.name)
    with atomic_path(path) as tmp:
        if fmt == "csv":
            out = table.copy()
            for column in out.columns:
                values = out[column]
                # ISO-8601 with "T" and "Z"; pandas' own format keeps nanoseconds if any.
                if (
                    isinstance(values.dtype, pd.DatetimeTZDtype)
                    and not (values.dt.nanosecond != 0).any()
                ):
                    out[column] = values.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ").where(
                        values.notna(), ""
                    )
            out.to_csv(tmp, index=False, lineterminator="\n")
        else:
            write_parquet(table, tmp, grid=record)
    if fmt == "csv":
        write_grid_sidecar(path, record)
    return path


def write_parquet(frame: pd.DataFrame, path: str | os.PathLike, *, grid=None) -> Path:
    """Write *frame* (no index) as Parquet, with *grid* in the key-value metadata."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pandas(frame, preserve_index=False)
    if grid is not None:
        table = table.replace_schema_metadata(metadata_with_grid(table.schema.metadata, grid))
    pq.write_table(table, path)
    return Path(path)


def metadata_with_grid(metadata: dict | None, grid) -> dict:
    """Parquet key-value *metadata* plus the block *grid* (``workbench.block_grid``)."""
    return {**(metadata or {}), _grid.GRID_METADATA_KEY: _grid.grid_json(grid).encode()}


def write_grid_sidecar(path: str | os.PathLike, grid) -> Path | None:
    """Write (or, without *grid*, remove) the grid sidecar of the CSV table *path*."""
    sidecar = _grid.grid_sidecar(path)
    if grid is None:
        sidecar.unlink(missing_ok=True)  # a stale grid must not outlive its table
        return None
    with atomic_path(sidecar) as tmp:
        tmp.write_text(_grid.grid_json(grid) + "\n", encoding="utf-8")
    return sidecar


__all__ += ["ContractError"]
