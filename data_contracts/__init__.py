"""Data contracts: the table and file schemas every stage of workbench reads and writes.

Schemas are code. Each contract validates lazily and raises one :class:`ContractError`
listing every violation (column, rows, reason). Units are part of column names. See
``data_contracts/README.md`` for every column.
"""

from ._core import Column, ColumnPattern, ContractError, TableContract, Violation, atomic_path
from .accelerations import (
    AccelerationRecord,
    channel_names,
    read_accelerations,
    validate_accelerations,
    write_accelerations,
)
from .dship import DEFAULT_DSHIP_MAPPING, DSHIP_LOG, ColumnMappingError, read_dship
from .geometry import SENSOR_GEOMETRY, geometry_directions
from .grid import grid_record, recorded_grid, set_grid
from .health import ALARMS, HEALTH
from .tables import (
    CANONICAL_PREDICTORS,
    COLUMN_LOG_COVERAGE,
    CONTRACTS,
    DIRECTION_PREDICTORS,
    FORECAST,
    LOG_COVERAGE,
    MODAL,
    OPTIONAL_PREDICTORS,
    POLES,
    PREDICTOR_KEYS,
    PREDICTORS,
    SELECTED,
    column_log_coverage_name,
    read_table,
    shape_columns,
    shapes_from_frame,
    shapes_to_frame,
    write_table,
)
from .validation import FILE_KINDS, ValidatedFile, validate_file

__all__ = [
    "ALARMS",
    "HEALTH",
    "CANONICAL_PREDICTORS",
    "DIRECTION_PREDICTORS",
    "CONTRACTS",
    "DEFAULT_DSHIP_MAPPING",
    "DSHIP_LOG",
    "FILE_KINDS",
    "FORECAST",
    "COLUMN_LOG_COVERAGE",
    "LOG_COVERAGE",
    "MODAL",
    "OPTIONAL_PREDICTORS",
    "POLES",
    "PREDICTOR_KEYS",
    "PREDICTORS",
    "SELECTED",
    "SENSOR_GEOMETRY",
    "AccelerationRecord",
    "Column",
    "ColumnPattern",
    "ColumnMappingError",
    "ContractError",
    "TableContract",
    "ValidatedFile",
    "Violation",
    "atomic_path",
    "channel_names",
    "column_log_coverage_name",
    "geometry_directions",
    "grid_record",
    "read_accelerations",
    "read_dship",
    "read_table",
    "recorded_grid",
    "set_grid",
    "shape_columns",
    "shapes_from_frame",
    "shapes_to_frame",
    "validate_accelerations",
    "validate_file",
    "write_accelerations",
    "write_table",
]
