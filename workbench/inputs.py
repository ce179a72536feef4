"""Command-line options that say how the user's input files are laid out.

Shared by the commands that read ship logs and modal tables; kept apart from
:mod:`workbench.cli` so the commands only call :func:`add_dship_columns` /
:func:`add_modal_layout` and read through :func:`dship_mapping` / :func:`read_modal`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from . import defaults as D
from .errors import UsageError

__all__ = [
    "TIME_FORMAT_HELP",
    "add_dship_columns",
    "add_modal_layout",
    "dship_mapping",
    "dship_utc_offset",
    "read_modal",
    "time_format",
]


#: ``--time-format``: one option for every time column and text start time a command reads.
TIME_FORMAT_HELP = (
    "format of every time column and text start time (modal table, ship log, acceleration "
    "files): strptime (%%d/%%m/%%Y %%H:%%M:%%S) or MATLAB datestr (dd-mmm-yyyy HH:MM:SS); "
    "default: ISO-8601, yyyy/mm/dd, dd.mm.yyyy, dd-mmm-yyyy and slash dates whose days "
    "tell day and month apart"
)


def time_format(args: argparse.Namespace) -> str | None:
    """The ``--time-format`` of a command reading modal tables or ship logs, checked
    (``seconds``/``unix`` are for acceleration files only)."""
    from data_contracts.dship_names import strptime_format

    value = getattr(args, "time_format", None)
    if value is None:
        return None
    if value in ("seconds", "unix"):
        raise _usage(f"--time-format {value} is for acceleration files (identify, validate)")
    try:
        strptime_format(value)
    except ValueError as error:
        raise _usage(f"--time-format: {error}") from None
    return value


def _usage(message: str) -> Exception:
    return UsageError(message)


def add_dship_columns(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--dship-columns",
        action="append",
        metavar="COLUMN=NAME,...",
        help="ship-log columns by name, e.g. speed_kn=SYS.STR.SOG,air_temp_c=TT (also "
        "water_temp_c, wind_speed_ms, wind_dir_rel_deg, wind_dir_true_deg, "
        "wind_speed_true_ms, heading_deg, course_deg, fuel_on_board_t, shaft_rpm, time); "
        "default: the usual DSHIP names",
    )
    parser.add_argument(
        "--dship-utc-offset",
        metavar="+HH:MM",
        help="UTC offset of the ship log's times written without one (local time), e.g. "
        "+02:00 or UTC-05:30; default: such times are UTC. Times that carry an offset keep it",
    )


def dship_utc_offset(args: argparse.Namespace) -> str | None:
    """The ``--dship-utc-offset`` of the command, checked, as ``+HH:MM`` (None when not
    given)."""
    from data_contracts.dship_names import format_utc_offset, parse_utc_offset

    value = getattr(args, "dship_utc_offset", None)
    if value is None:
        return None
    try:
        return format_utc_offset(parse_utc_offset(value))
    except ValueError as error:
        raise _usage(f"--dship-utc-offset: {error}") from None


def dship_mapping(args: argparse.Namespace) -> dict[str, str] | None:
    """The ``--dship-columns`` mapping (None when not given)."""
    from data_contracts.dship_names import AUXILIARY_COLUMNS, SHAFT_COLUMNS, parse_column_mapping
    from data_contracts.tables import CANONICAL_PREDICTORS, OPTIONAL_PREDICTORS

    if not getattr(args, "dship_columns", None):
        return None
    try:
        mapping = parse_column_mapping(args.dship_columns)
        known = (
            {c.name for c in CANONICAL_PREDICTORS}
            | {c.name for c in OPTIONAL_PREDICTORS}
            | set(AUXILIARY_COLUMNS)
            | set(SHAFT_COLUMNS)
            | {"time"}
        )
        unknown = sorted(set(mapping) - known)
        if unknown:
            raise ValueError(
                f"unknown column(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}"
            )
    except ValueError as error:
        raise _usage(f"--dship-columns: {error}") from None
    return mapping


def add_modal_layout(parser: argparse.ArgumentParser, *, time_format: bool = True) -> None:
    """The modal-table layout flags (*time_format*: also ``--time-format``, left out where
    the acceleration layout adds it, which applies to every time column too)."""
    group = parser.add_argument_group(
        "modal tables from other tools",
        "Long (time, mode, frequency, damping), wide (f1, f2, ..., d1, d2, ...) and "
        "block-indexed tables are recognised; these say what their headers do not.",
    )
    group.add_argument(
        "--damping-unit",
        choices=("percent", "fraction"),
        help="unit of damping columns whose header does not state it (Damping [%%] does)",
    )
    group.add_argument(
        "--time-reference",
        choices=("start", "centre", "end"),
        help="what a row's time marks in its analysis window (default: from the column "
        "name, e.g. window_centre, else start with a warning)",
    )
    group.add_argument(
        "--time-zone",
        metavar="ZONE",
        help="zone of times written without one, e.g. UTC or Europe/Berlin (default UTC, "
        "with a warning)",
    )
    if time_format:
        group.add_argument("--time-format", metavar="FMT", help=TIME_FORMAT_HELP)
    group.add_argument(
        "--grid",
        metavar="LENGTH_MIN,STEP_MIN[,T0]",
        help="block grid of the table's windows: block length and step in minutes and the "
        f"start of block 0 (default {D.BLOCK_MINUTES:g},{D.STEP_MINUTES:g} and t0 from the "
        "first window)",
    )


def _layout(args: argparse.Namespace):
    from data_contracts.modal_layout import ModalLayout

    length_min, step_min, t0 = D.BLOCK_MINUTES, D.STEP_MINUTES, None
    if getattr(args, "grid", None):
        parts = [p.strip() for p in args.grid.split(",")]
        try:
            if len(parts) not in (2, 3):
                raise ValueError
            length_min, step_min = float(parts[0]), float(parts[1])
            t0 = parts[2] if len(parts) == 3 else None
            if t0 is not None:
                pd.Timestamp(t0)
        except ValueError:
            raise _usage(
                f"--grid must be LENGTH_MIN,STEP_MIN[,T0], e.g. 20,5,2024-03-01T00:00Z; "
                f"got {args.grid!r}"
            ) from None
    try:
        return ModalLayout(
            damping_unit=getattr(args, "damping_unit", None),
            time_reference=getattr(args, "time_reference", None),
            time_zone=getattr(args, "time_zone", None),
            time_format=time_format(args),
            block_length_s=60.0 * length_min,
            block_step_s=60.0 * step_min,
            grid_t0=t0,
        )
    except ValueError as error:
        raise _usage(f"--grid: {error}") from None


def read_modal(args: argparse.Namespace, path: Path | None) -> pd.DataFrame | None:
    """The modal table at *path* in any recognised layout (None for no path)."""
    from data_contracts.modal_layout import read_modal_table

    if path is None:
        return None
    return read_modal_table(path, _layout(args))


def add_acceleration_layout(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group(
        "acceleration files",
        "Formats by suffix: .npz, .mat (v5, v7.3), .csv/.tsv/.txt, .h5/.hdf5, .uff/.unv "
        "(dataset 58). These say what the files' headers do not.",
    )
    group.add_argument("--time-column", metavar="NAME", help="column with the sample times")
    group.add_argument(
        "--time-format",
        metavar="FMT",
        help=TIME_FORMAT_HELP.replace(
            "(modal", "(acceleration files, their metadata, MATLAB t0; modal"
        ).replace(", acceleration files)", ")")
        + "; or 'seconds' (relative to --start-time) or 'unix'",
    )
    group.add_argument("--separator", metavar="SEP", help="field separator (';', ',', 'tab')")
    group.add_argument("--decimal", choices=(".", ","), help="decimal mark (default: detected)")
    group.add_argument(
        "--start-time",
        metavar="TIME",
        help="UTC time of the first sample (relative times), or 'filename' (the time in "
        "each file's name); with several files: the first file's, the others follow on",
    )
    group.add_argument(
        "--sampling-rate", type=float, metavar="HZ", help="sampling rate (default: from the file)"
    )
    group.add_argument(
        "--units",
        metavar="UNIT|CH=UNIT,...",
        help="unit of all channels (g, mm/s^2, m/s^2, ...) or per channel; converted to m/s^2 "
        "(default: from the headers, e.g. 'acc01 [g]', else m/s^2)",
    )
    group.add_argument("--channels", metavar="CH,CH,...", help="only these columns are channels")
    group.add_argument(
        "--variables",
        metavar="KEY=NAME,...",
        help="MATLAB variables / HDF5 datasets: acceleration, sampling_rate_hz, start_time, "
        "channels, time (default: the usual names, e.g. data, fs, t0, chanNames)",
    )


def acceleration_layout(args: argparse.Namespace) -> dict | None:
    """The acceleration layout given on the command line, checked (None: nothing given)."""
    from data_contracts.dship_names import parse_column_mapping
    from data_contracts.formats import AccelerationLayout

    fields: dict = {}
    if getattr(args, "time_column", None):
        fields["time_column"] = args.time_column
    if getattr(args, "time_format", None):
        fields["time_format"] = args.time_format
    if getattr(args, "separator", None):
        fields["separator"] = "\t" if args.separator.lower() in ("tab", "\\t") else args.separator
    if getattr(args, "decimal", None):
        fields["decimal"] = args.decimal
    if getattr(args, "start_time", None):
        fields["start_time"] = args.start_time
    if getattr(args, "sampling_rate", None) is not None:
        fields["sampling_rate_hz"] = args.sampling_rate
    try:
        if getattr(args, "units", None):
            fields["units"] = (
                parse_column_mapping(args.units) if "=" in args.units else args.units.strip()
            )
        if getattr(args, "channels", None):
            fields["channels"] = [c.strip() for c in args.channels.split(",") if c.strip()]
        if getattr(args, "variables", None):
            fields["variables"] = parse_column_mapping(args.variables)
        if not fields:
            return None
        layout = AccelerationLayout(**fields)
    except (TypeError, ValueError) as error:
        raise _usage(f"acceleration layout: {error}") from None
    return layout.to_dict()
