"""``workbench validate`` and ``report``: a file checked against its contract, one HTML
page of a run."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from ..errors import printable
from ..inputs import (
    acceleration_layout,
    add_acceleration_layout,
    add_dship_columns,
    add_modal_layout,
    dship_mapping,
    dship_utc_offset,
    time_format,
)
from .common import EXIT_OK, UsageError, _data_errors


def _add_validate(commands: argparse._SubParsersAction) -> None:
    from data_contracts import FILE_KINDS

    parser = commands.add_parser(
        "validate",
        help="check a file against a data contract",
        description="Check FILE against the contract KIND and report every problem.",
    )
    parser.add_argument(
        "kind", choices=FILE_KINDS, metavar="KIND", help=f"one of: {', '.join(FILE_KINDS)}"
    )
    parser.add_argument("file", type=Path, metavar="FILE")
    add_dship_columns(parser)
    add_acceleration_layout(parser)
    parser.set_defaults(run=_run_validate)


def _run_validate(args: argparse.Namespace) -> int:
    from data_contracts import validate_file

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        checked = validate_file(
            args.kind,
            args.file,
            layout=acceleration_layout(args) if args.kind == "accelerations" else None,
            dship_mapping=dship_mapping(args) if args.kind == "dship" else None,
            time_format=time_format(args) if args.kind == "dship" else None,
            dship_utc_offset=dship_utc_offset(args) if args.kind == "dship" else None,
        )
    for warning in caught:
        print(f"warning: {printable(warning.message)}", file=sys.stderr)
    print(printable(f"{args.file}: valid {args.kind} file ({checked.summary})"))
    return EXIT_OK


def _add_report(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "report",
        help="one HTML report of a run from its tables",
        description="Build one HTML page of the run in DIR (the folder the stages wrote "
        "into): an overview (what ran, on which data, modes found, warnings, skipped blocks, "
        "dropped channels), then spectra, stabilisation diagrams, tracked modes, mode shapes, "
        "correlation, regression and forecasts, as far as the run has them. The run's "
        "own results are shown as its stages left them (the correlate stage's pairs and "
        "predictors, the fit's models); acceleration files are read as identification "
        "read them (its recorded layout), unless the flags below or --config say otherwise.",
    )
    parser.add_argument(
        "dir", type=Path, metavar="DIR", help="the run's folder (with --config: its output dir)"
    )
    parser.add_argument(
        "--out", type=Path, metavar="FILE", help="report to write (default DIR/report.html)"
    )
    parser.add_argument(
        "--accelerations",
        type=Path,
        nargs="+",
        metavar="DIR_OR_FILE",
        help="acceleration files (default: an 'accelerations' folder below DIR) for spectra, "
        "spectrograms and channel moments",
    )
    parser.add_argument("--dship", type=Path, metavar="FILE", help="DSHIP log for predictors")
    parser.add_argument("--cases", type=Path, metavar="FILE", help="operating cases CSV")
    parser.add_argument(
        "--geometry", type=Path, metavar="FILE", help="sensor geometry CSV (mode shapes)"
    )
    parser.add_argument(
        "--blocks", metavar="N,N,...", help="blocks whose stabilisation diagrams are drawn"
    )
    parser.add_argument("--title", help="page title")
    parser.add_argument(
        "--modal",
        type=Path,
        metavar="FILE",
        help="the run's modal table when it is not DIR's tracked_modal.* (e.g. another "
        "tool's, in any layout correlate reads)",
    )
    add_dship_columns(parser)
    add_modal_layout(parser, time_format=False)
    # how to read the acceleration files: default the layout identification recorded
    add_acceleration_layout(parser)
    parser.set_defaults(run=_run_report)


def _run_report(args: argparse.Namespace) -> int:
    from ..reporting.report import build_report, find_run

    if not args.dir.is_dir():
        raise UsageError(f"{args.dir}: no such folder")
    try:
        blocks = [int(b) for b in args.blocks.split(",")] if args.blocks else None
    except ValueError:
        raise UsageError(
            f"--blocks must be block numbers like 0,40,80, got {args.blocks!r}"
        ) from None
    run = find_run(
        args.dir,
        accelerations=args.accelerations or (),
        dship=args.dship,
        cases=args.cases,
        geometry=args.geometry,
    )
    layout = acceleration_layout(args)
    mapping = dship_mapping(args)
    modal = None
    if args.modal is not None:
        from .common import _read_modal

        with _data_errors(args.modal):
            modal = _read_modal(args, args.modal)
    with _data_errors(args.dir):
        path = build_report(
            args.dir,
            out=args.out,
            run=run,
            title=args.title,
            stabilisation_blocks=blocks,
            modal=modal,
            acceleration_layout=layout,
            dship_mapping=mapping,
            dship_utc_offset=dship_utc_offset(args),
            time_format=time_format(args) if args.time_format not in ("seconds", "unix") else None,
        )
    print(f"report: {path}")
    return EXIT_OK
