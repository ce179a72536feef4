"""Command-line interface: ``workbench COMMAND ...``.

The CLI parses arguments, calls the library and prints; nothing else. Exit status: 0 on
success, 1 on bad data (one line per problem on stderr, naming file, column and rows),
2 on usage errors. Tracebacks only with ``--verbose``.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import re
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

from data_contracts import ContractError

from . import __version__
from .errors import OptionError, WorkbenchError
from .inputs import (
    acceleration_layout,
    add_acceleration_layout,
    add_dship_columns,
    add_modal_layout,
    dship_mapping,
    read_modal,
)

EXIT_OK, EXIT_DATA, EXIT_USAGE = 0, 1, 2

log = logging.getLogger("workbench")


class UsageError(Exception):
    """Arguments that parse but make no sense together (exit status 2)."""


def _add_validate(commands: argparse._SubParsersAction) -> None:
    from data_contracts import CONTRACTS

    kinds = ["accelerations", "dship", *CONTRACTS]
    parser = commands.add_parser(
        "validate",
        help="check a file against a data contract",
        description="Check FILE against the contract KIND and report every problem.",
    )
    parser.add_argument("kind", choices=kinds, metavar="KIND", help=f"one of: {', '.join(kinds)}")
    parser.add_argument("file", type=Path, metavar="FILE")
    add_dship_columns(parser)
    add_acceleration_layout(parser)
    parser.set_defaults(run=_run_validate)


def _run_validate(args: argparse.Namespace) -> int:
    from data_contracts import CONTRACTS, read_accelerations, read_dship, read_table

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if args.kind == "accelerations":
            record = read_accelerations(args.file, layout=acceleration_layout(args))
            summary = (
                f"{record.n_samples} samples x {len(record.channels)} channels at "
                f"{record.sampling_rate_hz:g} Hz from {record.start_time.isoformat()}"
            )
        elif args.kind == "dship":
            table = read_dship(args.file, mapping=dship_mapping(args))
            summary = f"{len(table)} records, columns {', '.join(table.columns[1:])}"
        else:
            table = read_table(args.file, CONTRACTS[args.kind])
            summary = f"{len(table)} rows"
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    print(f"{args.file}: valid {args.kind} file ({summary})")
    return EXIT_OK


def _add_simulate(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "simulate",
        help="simulate a demo voyage with known modal parameters",
        description="Write a simulated voyage: 5-minute acceleration files, the DSHIP log, "
        "ground-truth and noisy tracked modal tables, and pole tables.",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--hours",
        type=float,
        default=None,
        help="voyage length [h] (default: the demo length, 12 h)",
    )
    parser.add_argument(
        "--no-accelerations", action="store_true", help="skip the acceleration files (tables only)"
    )
    parser.add_argument(
        "--rate",
        type=float,
        default=64.0,
        metavar="HZ",
        help="sampling rate of the acceleration files, a multiple of 64 Hz (e.g. 2048, a "
        "recorder's rate: same modal physics, broadband content and a 60 Hz hum above the "
        "band) [default: 64]",
    )
    parser.set_defaults(run=_run_simulate)


def _run_simulate(args: argparse.Namespace) -> int:
    from .simulate import simulate_voyage

    _check_hours(args.hours)
    from .demo import describe_voyage

    try:
        voyage = simulate_voyage(
            args.out,
            seed=args.seed,
            hours=args.hours,
            accelerations=not args.no_accelerations,
            sampling_rate_hz=args.rate,
        )
    except ValueError as error:  # e.g. a voyage shorter than one block
        raise UsageError(str(error)) from None
    print(f"simulated voyage written to {args.out}: {describe_voyage(voyage)}")
    return EXIT_OK


#: Longest simulated voyage: a year (longer ones would write ~10^5 files per month). [h]
MAX_SIMULATED_HOURS = 24.0 * 366


def _check_hours(hours) -> None:
    import math

    if hours is not None and not (math.isfinite(hours) and 0 < hours <= MAX_SIMULATED_HOURS):
        raise UsageError(
            f"--hours must be a positive number of hours up to {MAX_SIMULATED_HOURS:g}, "
            f"got {hours:g}"
        )


def _check_positive(**values) -> None:
    """Usage error unless every given integer option is at least 1 (None passes)."""
    for name, value in values.items():
        if value is not None and value < 1:
            raise UsageError(f"--{name.replace('_', '-')} must be at least 1, got {value}")


def _check_share(name: str, value: float, *, low_open: bool = False) -> None:
    """Usage error unless *value* lies in [0, 1] ((0, 1] with *low_open*)."""
    import math

    ok = math.isfinite(value) and (0.0 < value if low_open else 0.0 <= value) and value <= 1.0
    if not ok:
        interval = "(0, 1]" if low_open else "[0, 1]"
        raise UsageError(f"--{name} must be in {interval}, got {value:g}")


def _add_demo(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "demo",
        help="run the whole chain on the built-in demo voyage",
        description="Simulate the demo voyage into reports/demo/ and run every stage on it.",
    )
    parser.add_argument("--out", type=Path, default=Path("reports") / "demo", metavar="DIR")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--hours", type=float, default=None, help="voyage length [h] (default 12)")
    _add_parallel(parser)
    parser.set_defaults(run=_run_demo)


def _run_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    _check_hours(args.hours)
    _check_positive(workers=args.workers)
    summary = run_demo(
        args.out,
        seed=args.seed,
        hours=args.hours,
        scheduler=args.scheduler,
        n_workers=args.workers,
        progress=not args.quiet,
    )
    print(summary)
    return EXIT_OK


@contextlib.contextmanager
def _data_errors(source):
    """A ValueError of the library about the data becomes a one-line error naming *source*
    (contract errors pass unchanged: they name file, column and rows themselves)."""
    try:
        yield
    except (ContractError, OptionError):
        raise
    except ValueError as error:
        raise WorkbenchError(f"{source}: {error}") from None


def _print_result(result) -> None:
    for line in result.warnings:
        print(f"warning: {line}", file=sys.stderr)
    for line in result.lines:
        print(line)


def _add_predictor_source(parser: argparse.ArgumentParser) -> None:
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument(
        "--predictors", type=Path, metavar="FILE", help="block predictor table (CSV/Parquet)"
    )
    source.add_argument(
        "--dship",
        type=Path,
        metavar="FILE",
        help="raw DSHIP log, averaged onto the modal table's blocks",
    )
    add_dship_columns(parser)
    add_modal_layout(parser)
    parser.add_argument(
        "--all-predictors",
        action="store_true",
        help="use every numeric column of the predictors, not only speed, water/air "
        "temperature, wind speed and relative wind direction",
    )


def _predictors_for(args: argparse.Namespace, modal):
    from .pipeline import canonical_predictors, load_predictors

    table = load_predictors(
        predictors=args.predictors, dship=args.dship, like=modal, dship_mapping=dship_mapping(args)
    )
    return table if args.all_predictors else canonical_predictors(table)


def _add_parallel(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("parallel execution")
    group.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="address of a running dask.distributed scheduler "
        "(tcp://host:8786), or 'synchronous' to run in this process; "
        "default: a local cluster on all cores",
    )
    group.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="worker processes of the local cluster (default: all cores)",
    )
    group.add_argument("--quiet", action="store_true", help="no progress bar")


def _add_identify(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "identify",
        help="SSI of every block of acceleration files -> pole tables, selected modes",
        description="Cut acceleration files into blocks (default 20 min, 75 % overlap), "
        "condition them, run stochastic subspace identification over all model orders, "
        "mark stable poles and select modes automatically, block by block in parallel. "
        "Results go to a resumable per-block store: run the same command again after an "
        "interruption and it carries on.",
    )
    parser.add_argument(
        "inputs",
        nargs="+",
        type=Path,
        metavar="DIR_OR_FILE",
        help="acceleration files or folders holding them",
    )
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="DIR",
        help="folder for poles.parquet, selected.parquet, faults.csv, ...",
    )
    parser.add_argument(
        "--store", type=Path, metavar="DIR", help="per-block store (default OUT/store)"
    )
    parser.add_argument(
        "--method",
        choices=("cov", "data", "lscf"),
        default="cov",
        help="covariance-driven or data-driven SSI, or poly-reference LSCF (PolyMAX)",
    )
    parser.add_argument(
        "--lscf-max-order",
        type=int,
        default=15,
        metavar="P",
        help="LSCF polynomial orders 1..P (P x references poles)",
    )
    parser.add_argument(
        "--cross-check",
        action="store_true",
        help="also identify with the other method (LSCF for SSI, SSI-cov for LSCF) and pair "
        "the modes of both per block (crosscheck.csv, agreement in the summary)",
    )
    parser.add_argument(
        "--block-rows", type=int, default=20, metavar="I", help="SSI block rows (default 20)"
    )
    parser.add_argument(
        "--max-order",
        type=int,
        default=60,
        metavar="N",
        help="highest model order (default 60; lowered to what the block rows and channels "
        "left give)",
    )
    parser.add_argument(
        "--min-order", type=int, default=4, metavar="N", help="lowest model order (default 4)"
    )
    parser.add_argument(
        "--weighting", choices=("pc", "upc", "cva"), default="pc", help="SSI-data weighting"
    )
    parser.add_argument(
        "--reference", metavar="CH,CH,...", help="reference channels (default: all)"
    )
    parser.add_argument(
        "--rate",
        default="auto",
        metavar="HZ|auto|native",
        help="analysis rate the files are decimated to (Chebyshev I, each file once). "
        "'auto' (default): the files' rate halved while it stays at or above 4 x the "
        "band's upper edge, 4 x 25 Hz without --band (2048 Hz files: 64 Hz with --band 2 12, "
        "128 Hz without; 64 Hz files stay); "
        "'native': keep the files' rate",
    )
    parser.add_argument(
        "--band",
        type=float,
        nargs=2,
        default=None,
        metavar=("LOW", "HIGH"),
        help="band-pass and selection band [Hz] (LOW 0: no high-pass); default: 0 to the "
        "anti-aliasing filter's edge 0.8 r/2 of the analysis rate r (--rate, or the files' "
        "rate); HIGH may not exceed that edge when decimating",
    )
    parser.add_argument("--no-band", action="store_true", help="no band-pass filter")
    parser.add_argument(
        "--block-minutes",
        type=float,
        default=None,
        metavar="MIN",
        help="block length [min] (default 20); a length below the default step needs "
        "--step-minutes too",
    )
    parser.add_argument(
        "--step-minutes",
        type=float,
        default=None,
        metavar="MIN",
        help="step between blocks [min] (default 5)",
    )
    parser.add_argument(
        "--short-record",
        choices=("error", "one-block"),
        default="error",
        help="data shorter than one block: an error naming the record (default), or one "
        "block of the record's length",
    )
    parser.add_argument(
        "--selection",
        choices=("cluster", "library"),
        default="cluster",
        help="automatic pole selection: clustering of the poles of all orders with "
        "thresholds from the data (default), or the library-and-descent rule",
    )
    check = parser.add_argument_group("channel check (per block; a faulty channel is dropped)")
    check.add_argument(
        "--no-channel-check", action="store_true", help="keep every channel that has data"
    )
    check.add_argument(
        "--kurtosis-max",
        type=float,
        default=10.0,
        metavar="K",
        help="kurtosis above K (Gaussian 3) is a fault when out of line with the other "
        "channels (default 10)",
    )
    check.add_argument(
        "--kurtosis-z-max",
        type=float,
        default=3.0,
        metavar="Z",
        help="robust z-score of a channel's log-kurtosis among the channels above which a "
        "kurtosis above K is a fault (default 3; impulsive excitation raises every channel)",
    )
    check.add_argument(
        "--variance-z-max",
        type=float,
        default=6.0,
        metavar="Z",
        help="robust z-score of a channel's log-variance among the channels beyond which it "
        "is a fault if it also lost coherence with every other channel (default 6)",
    )
    check.add_argument(
        "--max-nan-fraction",
        type=float,
        default=0.05,
        metavar="SHARE",
        help="largest share of missing samples (default 0.05)",
    )
    parser.add_argument(
        "--conditioning",
        choices=("per-file", "per-block"),
        default="per-file",
        help="when decimating: condition each file once (default) or every block from its "
        "raw files (reference path, slower)",
    )
    parser.add_argument(
        "--max-gap",
        type=float,
        default=0.0,
        metavar="S",
        help="NaN-pad gaps between files up to S seconds inside a block",
    )
    parser.add_argument(
        "--figures",
        type=int,
        default=0,
        metavar="K",
        help="stabilisation figures of K blocks spread over the voyage",
    )
    add_acceleration_layout(parser)
    parser.add_argument(
        "--tpe-figures",
        type=int,
        default=0,
        metavar="K",
        help="SSI-data stabilisation diagrams with the total prediction error per model "
        "order beside them, for K blocks",
    )
    parser.add_argument(
        "--batch-blocks",
        type=int,
        default=16,
        metavar="N",
        help="blocks stored together (an interruption loses at most these)",
    )
    _add_parallel(parser)
    parser.set_defaults(run=_run_identify)


def _analysis_rate(text: str):
    """``--rate``: a rate in Hz, ``auto`` or ``native`` (None: the files' rate)."""
    if text.lower() in ("auto", "native"):
        return None if text.lower() == "native" else "auto"
    try:
        rate = float(text)
    except ValueError:
        raise UsageError(f"--rate {text!r} is not a rate in Hz, 'auto' or 'native'") from None
    if not (math.isfinite(rate) and rate > 0):
        raise UsageError(f"--rate {text} Hz must be a positive rate")
    return rate


def _run_identify(args: argparse.Namespace) -> int:
    from .blocks import DEFAULT_BLOCK_LENGTH_S, DEFAULT_BLOCK_STEP_S
    from .identify import IdentifyOptions, IdentifyOptionsError, identify_voyage

    if args.min_order < 1 or args.max_order < args.min_order:
        raise UsageError(f"model orders {args.min_order}..{args.max_order} make no sense")
    if args.lscf_max_order < 1:
        raise UsageError(f"--lscf-max-order must be at least 1, got {args.lscf_max_order}")
    if args.no_band and args.band is not None:
        raise UsageError("--band and --no-band contradict each other")
    length_s = DEFAULT_BLOCK_LENGTH_S if args.block_minutes is None else 60.0 * args.block_minutes
    step_s = DEFAULT_BLOCK_STEP_S if args.step_minutes is None else 60.0 * args.step_minutes
    if not (length_s > 0 and step_s > 0):
        raise UsageError("--block-minutes and --step-minutes must be positive")
    if step_s > length_s:
        given = "--block-minutes" if args.step_minutes is None else "--step-minutes"
        raise UsageError(
            f"{given}: step {step_s / 60:g} min is longer than the block "
            f"{length_s / 60:g} min; give --step-minutes at most --block-minutes"
        )
    _check_positive(workers=args.workers, batch_blocks=args.batch_blocks)
    if args.figures < 0:
        raise UsageError(f"--figures must be 0 or more, got {args.figures}")
    try:
        options = IdentifyOptions(
            method=args.method,
            block_rows=args.block_rows,
            orders=tuple(range(args.min_order, args.max_order + 1, 2)),
            weighting=args.weighting,
            reference_channels=tuple(args.reference.split(",")) if args.reference else None,
            length_s=length_s,
            step_s=step_s,
            target_rate_hz=_analysis_rate(args.rate),
            band_hz=None if args.no_band else (tuple(args.band) if args.band else "auto"),
            max_gap_s=args.max_gap,
            lscf_orders=tuple(range(1, args.lscf_max_order + 1)),
            cross_check=args.cross_check,
            acceleration_layout=acceleration_layout(args),
            selection=args.selection,
            short_record=args.short_record,
            channel_check=not args.no_channel_check,
            fault_options=(
                ("kurtosis_limits", (1.3, args.kurtosis_max)),
                ("max_variance_z", args.variance_z_max),
                ("max_kurtosis_z", args.kurtosis_z_max),
                ("max_nan_fraction", args.max_nan_fraction),
            ),
            conditioning=args.conditioning,
        )
    except ValueError as error:
        raise UsageError(_option_names(str(error))) from None
    try:
        result = identify_voyage(
            args.inputs,
            args.out,
            options=options,
            store_dir=args.store,
            scheduler=args.scheduler,
            n_workers=args.workers,
            progress=not args.quiet,
            batch_blocks=args.batch_blocks,
        )
    except IdentifyOptionsError as error:
        raise UsageError(str(error)) from None
    for line in result.lines():
        print(line)
    if args.figures:
        from .identify import write_block_figures

        for path in write_block_figures(
            args.inputs, args.out / "figures", options=options, n_blocks=args.figures
        ):
            print(f"figure: {path}")
    if args.tpe_figures > 0:
        from .identify import write_tpe_figures

        for path in write_tpe_figures(
            args.inputs, args.out / "figures", options=options, n_blocks=args.tpe_figures
        ):
            print(f"figure: {path}")
    return EXIT_OK


#: Library parameter names and the CLI options that set them (for usage messages).
_OPTION_NAMES = {
    "length_s": "--block-minutes (in s)",
    "step_s": "--step-minutes (in s)",
    "max_gap_s": "--max-gap",
    "target_rate_hz": "--rate",
    "band_hz": "--band",
    "block_rows": "--block-rows",
    "orders": "--min-order/--max-order",
    "reference_channels": "--reference",
    "batch_blocks": "--batch-blocks",
    "n_workers": "--workers",
    "scheduler": "--scheduler",
    "threshold": "--threshold",
    "frequency_tolerance": "--frequency-tolerance",
}


def _option_names(message: str) -> str:
    """*message* with a library parameter name at its start shown as the CLI option."""
    for name, option in _OPTION_NAMES.items():
        if message.startswith(name):
            return option + message[len(name) :]
    return message


def _check_joins(args, modal, predictors=None, poles=None) -> None:
    """Block numbers must mean the same times in every input (one-line error, exit 1)."""
    from .joins import check_block_times, check_poles_match, check_predictors_overlap

    if predictors is not None:
        source = args.predictors if args.predictors is not None else args.dship
        check_block_times(modal, args.modal, predictors, source)
        check_predictors_overlap(modal, predictors, source)
    if poles is not None:
        check_poles_match(modal, args.modal, poles, args.poles)


def _read_modal(args: argparse.Namespace, path: Path, contract=None):
    """A modal table in any recognised layout (or a table of *contract*) with rows, its
    block numbers on one time grid."""
    from data_contracts import read_table

    from .joins import check_block_grid

    table = read_modal(args, path) if contract is None else read_table(path, contract)
    if table.empty:
        raise WorkbenchError(f"{path}: the table has a header but no rows")
    check_block_grid(table, path)
    return table


def _persistent(modal, min_presence: float):
    from .pipeline import persistent_modes

    if not 0.0 <= min_presence <= 1.0:
        raise UsageError(f"--min-presence must be in [0, 1], got {min_presence}")
    kept, lines = persistent_modes(modal, min_presence)
    for line in lines:
        print(line)
    return kept


def _add_track(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "track",
        help="track identified modes across blocks -> tracked modal table",
        description="Give the modes selected block by block (the `selected` table written "
        "by `workbench identify`) labels that follow each mode through the voyage: "
        "one-to-one Hungarian assignment to a library of reference modes by MACXP.",
    )
    parser.add_argument(
        "selected", type=Path, metavar="SELECTED", help="selected modes per block (CSV/Parquet)"
    )
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="FILE",
        help="tracked modal table to write (.csv or .parquet)",
    )
    parser.add_argument(
        "--reference",
        type=Path,
        metavar="FILE",
        help="modal table whose modes start the library (labels kept)",
    )
    parser.add_argument(
        "--threshold",
        type=float,
        default=0.9,
        help="lowest MAC (or MACXP with --gate macxp) to join a mode",
    )
    parser.add_argument("--gate", choices=("mac", "macxp"), default="mac")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument(
        "--frequency-tolerance",
        type=float,
        default=0.05,
        help="largest relative frequency difference to join a mode",
    )
    parser.set_defaults(run=_run_track)


def _run_track(args: argparse.Namespace) -> int:
    from .pipeline import run_track
    from .sid.tracking import TrackingOptions

    try:
        TrackingOptions(
            threshold=args.threshold, gate=args.gate, frequency_tolerance=args.frequency_tolerance
        )
    except ValueError as error:
        raise UsageError(_option_names(str(error))) from None
    _check_table_path(args.out)
    with _data_errors(args.selected):
        result = run_track(
            args.selected,
            args.out,
            reference=args.reference,
            threshold=args.threshold,
            gate=args.gate,
            frequency_tolerance=args.frequency_tolerance,
            progress=not args.quiet,
        )
    _print_result(result)
    return EXIT_OK


def _add_correlate(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "correlate",
        help="correlation and significance of modes vs predictors -> CSV, figures, HTML",
        description="Pearson r, two-sided p-value and n for every mode frequency/damping "
        "and predictor pair (and among predictors), per operating case and stitched; "
        "flags significant (p < alpha) and useful (|r| >= 0.5 and significant).",
    )
    parser.add_argument(
        "--modal", type=Path, required=True, metavar="FILE", help="tracked modal table"
    )
    _add_predictor_source(parser)
    parser.add_argument(
        "--cases", type=Path, metavar="FILE", help="operating cases: CSV with case,start,end (UTC)"
    )
    parser.add_argument("--alpha", type=float, default=0.05)
    parser.add_argument(
        "--correction",
        choices=("none", "holm", "fdr_bh"),
        default="none",
        help="multiple-testing correction of the p-values",
    )
    parser.add_argument(
        "--min-presence",
        type=float,
        default=0.5,
        metavar="SHARE",
        help="only modes measured in at least this share of the blocks",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR")
    parser.set_defaults(run=_run_correlate)


def _run_correlate(args: argparse.Namespace) -> int:

    from .reporting.correlation import write_correlation_report

    if not 0.0 < args.alpha < 1.0:
        raise UsageError(f"--alpha must be in (0, 1), got {args.alpha}")
    _check_share("min-presence", args.min_presence)
    cases = None
    if args.cases is not None:
        from .stats.correlation import read_cases

        try:
            cases = read_cases(args.cases)
        except ValueError as error:
            raise WorkbenchError(str(error).splitlines()[0]) from None
        if (cases["case"].str.lower() == "all").any():
            raise WorkbenchError(
                f"{args.cases}: the case name 'all' is reserved for the stitched cases; "
                "rename that case"
            )
    modal = _read_modal(args, args.modal)
    predictors = _predictors_for(args, modal)
    _check_joins(args, modal, predictors)
    modal = _persistent(modal, args.min_presence)
    with _data_errors(args.modal):
        paths = write_correlation_report(
            modal,
            predictors,
            args.out,
            cases=cases,
            alpha=args.alpha,
            correction=None if args.correction == "none" else args.correction,
            # a frequency-only table (another tool's) has no damping to correlate
            quantities=("frequency_hz", "damping_ratio")
            if modal["damping_ratio"].notna().any()
            else ("frequency_hz",),
        )
    for name, path in dict(paths).items():
        print(f"{name}: {path}")
    return EXIT_OK


def _add_fit(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "fit",
        help="stepwise regression with interactions per mode -> summary, coefficients, diagnostics",
        description="Fit one stepwise linear model (MATLAB stepwiselm semantics: F-test "
        "entry p < 0.05, removal p > 0.10, two-way interactions, hierarchy) of each mode's "
        "frequency on the block predictors; write a summary, JSON, a coefficient table and "
        "residual diagnostics.",
    )
    parser.add_argument(
        "--modal", type=Path, required=True, metavar="FILE", help="tracked modal table"
    )
    _add_predictor_source(parser)
    parser.add_argument("--p-enter", type=float, default=0.05)
    parser.add_argument("--p-remove", type=float, default=0.10)
    parser.add_argument(
        "--upper",
        default="interactions",
        help="largest model: constant, linear, interactions, or a formula "
        "such as 'y ~ speed_kn + water_temp_c + speed_kn:water_temp_c'",
    )
    parser.add_argument(
        "--cases",
        metavar="FILE|derive",
        help="also fit per operating case beside the stitched model: a CSV with "
        "case,start,end (UTC), or 'derive' (stationary below 1 kn, ice at water <= -1.5 C, "
        "else open water)",
    )
    parser.add_argument(
        "--min-presence",
        type=float,
        default=0.5,
        metavar="SHARE",
        help="only modes measured in at least this share of the blocks",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR")
    parser.set_defaults(run=_run_fit)


def _run_fit(args: argparse.Namespace) -> int:

    from .reporting.diagnostics_plot import write_fit_report

    if not 0.0 < args.p_enter < args.p_remove < 1.0:
        raise UsageError(
            f"need 0 < --p-enter < --p-remove < 1, got {args.p_enter} and {args.p_remove}"
        )
    _check_share("min-presence", args.min_presence)
    modal = _read_modal(args, args.modal)
    predictors = _predictors_for(args, modal)
    _check_joins(args, modal, predictors)
    _check_upper(args.upper, predictors)
    modal = _persistent(modal, args.min_presence)
    with _data_errors(args.modal):
        paths = write_fit_report(
            modal,
            predictors,
            args.out,
            p_enter=args.p_enter,
            p_remove=args.p_remove,
            upper=args.upper,
            cases=_cases_argument(args.cases),
        )
    for name, path in dict(paths).items():
        print(f"{name}: {path}")
    return EXIT_OK


def _cases_argument(value: str | None):
    """--cases: None, "derive" or the path of a case,start,end CSV."""
    if value is None or value == "derive":
        return value
    return Path(value)


def _check_upper(upper: str, predictors) -> None:
    """A usage error for an --upper model that names no predictor or is not a model."""
    from .stats.terms import parse_terms

    names = [c for c in predictors.columns if c not in ("block", "block_start", "block_end")]
    try:
        parse_terms(upper, names, parameter="--upper")
    except (ValueError, TypeError) as error:
        raise UsageError(str(error).splitlines()[0]) from None


def _check_table_path(path: Path) -> None:
    """A usage error unless *path* names a .csv or .parquet file (not a folder)."""
    if path.suffix.lower() not in (".csv", ".parquet", ".pq"):
        raise UsageError(f"{path}: the table must end in .csv or .parquet")
    if path.is_dir():
        raise UsageError(f"{path}: is a folder; give a file name ending in .csv or .parquet")


def _add_forecast(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "forecast",
        help="sliding regression forecast of each mode, Kalman-blended with SSI",
        description="Train a stepwise model of each mode's frequency on the last N blocks, "
        "predict ahead with 95 % bounds and blend with the SSI estimates by a Kalman filter "
        "(option A: tracked pole; option B: nearest pole of the stabilisation diagram).",
    )
    parser.add_argument(
        "--modal", type=Path, required=True, metavar="FILE", help="tracked modal table"
    )
    _add_predictor_source(parser)
    parser.add_argument(
        "--poles",
        type=Path,
        metavar="FILE",
        help="pole table (stabilisation diagrams), needed for option B",
    )
    parser.add_argument(
        "--option",
        choices=("A", "B", "AB"),
        default="A",
        help="measurement option; AB runs both into one table",
    )
    parser.add_argument(
        "--method",
        type=int,
        choices=(1, 2),
        default=2,
        help="1: one long forecast; 2: predict H blocks, filter, slide, refit",
    )
    parser.add_argument(
        "--train", type=int, default=20, metavar="N", help="training window [blocks]"
    )
    parser.add_argument(
        "--horizon",
        type=int,
        default=None,
        metavar="H",
        help="blocks per forecast (default 34 for method 1, 4 for method 2)",
    )
    parser.add_argument(
        "--model",
        choices=("memory", "window"),
        default="window",
        help="window: the reference configuration, a stepwise fit on the last --train blocks "
        "and --trust (default); memory: stepwise terms, coefficients over the whole history "
        "with forgetting, noise levels from the data",
    )
    parser.add_argument(
        "--trust",
        default=None,
        help="--model window only: steady-state weight on SSI in (0, 1) (default 0.65), "
        "or 'data' for a Q from the model's own prediction variance",
    )
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="FILE",
        help="forecast table to write (.csv or .parquet)",
    )
    parser.add_argument(
        "--cases",
        metavar="FILE|derive",
        help="forecast each window with the model of the current operating case: a CSV "
        "with case,start,end (UTC), or 'derive' (stationary / open water / ice by rule)",
    )
    parser.add_argument(
        "--figures", type=Path, metavar="DIR", help="write one figure per mode into DIR"
    )
    parser.add_argument(
        "--truth",
        type=Path,
        metavar="FILE",
        help="true modal table to draw in the figures (simulations)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help="processes to spread the modes over (for voyage-length tables)",
    )
    parser.add_argument(
        "--min-presence",
        type=float,
        default=0.5,
        metavar="SHARE",
        help="forecast only modes measured in at least this share of the blocks",
    )
    parser.add_argument(
        "--shape-mac-min",
        type=float,
        default=0.9,
        metavar="MAC",
        help="option B: lowest MAC of a pole's shape with the mode's tracked shape",
    )
    parser.add_argument(
        "--reacquire-blocks",
        type=int,
        default=None,
        metavar="K",
        help="option B: blocks seen only outside the gate before the track is re-acquired "
        "(default 2 for --model memory, 1 for --model window)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(run=_run_forecast)


def _parse_trust(text: str) -> float | None:
    if text.strip().lower() in ("data", "none"):
        return None
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"--trust must be a number in (0, 1) or 'data', got {text!r}") from None
    if not 0.0 < value < 1.0:
        raise UsageError(f"--trust must be in (0, 1), got {value}")
    return value


def _run_forecast(args: argparse.Namespace) -> int:
    from data_contracts import POLES, read_table

    from .pipeline import run_forecast

    options = ("A", "B") if args.option == "AB" else (args.option,)
    if "B" in options and args.poles is None:
        raise UsageError("option B needs --poles (the stabilisation diagrams)")
    if args.train < 2:
        raise UsageError(f"--train must be at least 2 blocks, got {args.train}")
    if args.trust is not None and args.model != "window":
        raise UsageError(
            "--trust applies to --model window; --model memory takes its noise levels from the data"
        )
    _check_positive(horizon=args.horizon, jobs=args.jobs, reacquire_blocks=args.reacquire_blocks)
    _check_share("min-presence", args.min_presence)
    _check_share("shape-mac-min", args.shape_mac_min)
    _check_table_path(args.out)
    trust = "auto" if args.trust is None else _parse_trust(args.trust)
    modal = _read_modal(args, args.modal)
    predictors = _predictors_for(args, modal)
    poles = read_table(args.poles, POLES) if args.poles is not None else None
    truth = _read_modal(args, args.truth) if args.truth is not None else None
    _check_joins(args, modal, predictors, poles)
    with _data_errors(args.modal):
        result = run_forecast(
            modal,
            predictors,
            args.out,
            poles=poles,
            options=options,
            method=args.method,
            train_blocks=args.train,
            horizon=args.horizon,
            trust=trust,
            model=args.model,
            figures=args.figures,
            truth=truth,
            n_jobs=args.jobs,
            progress=not args.quiet,
            min_presence=args.min_presence,
            option_b={
                "shape_mac_min": args.shape_mac_min,
                "reacquire_blocks": args.reacquire_blocks,
            },
            cases=_cases_argument(args.cases),
        )
    _print_result(result)
    return EXIT_OK


def _add_evaluate(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "evaluate",
        help="compare SSI, model and Kalman estimates with a true modal table",
        description="Cumulative absolute error per mode of the SSI-only, model-only and "
        "Kalman estimates of a forecast table against the truth (e.g. of the demo voyage), "
        "and the improvement in %.",
    )
    parser.add_argument("--forecast", type=Path, required=True, metavar="FILE")
    parser.add_argument(
        "--truth", type=Path, required=True, metavar="FILE", help="true modal table"
    )
    parser.add_argument("--phase", choices=("forecast", "train", "all"), default="forecast")
    parser.add_argument(
        "--out", type=Path, metavar="FILE", help="write the table (.csv or .parquet)"
    )
    add_modal_layout(parser)
    parser.set_defaults(run=_run_evaluate)


def _run_evaluate(args: argparse.Namespace) -> int:
    from data_contracts import FORECAST

    from .joins import check_block_times
    from .pipeline import evaluate_forecast

    if args.out is not None:
        _check_table_path(args.out)
    forecast = _read_modal(args, args.forecast, FORECAST)
    truth = _read_modal(args, args.truth)
    check_block_times(forecast, args.forecast, truth, args.truth)
    result = evaluate_forecast(
        forecast, truth, out=args.out, phase=None if args.phase == "all" else args.phase
    )
    table = result.tables["evaluation"]
    columns = [
        "option",
        "mode",
        "n_ssi",
        "ssi_cumulative_error_hz",
        "model_cumulative_error_hz",
        "kalman_cumulative_error_hz",
        "improvement_vs_ssi_pct",
    ]
    print(table[columns].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    _print_result(result)
    return EXIT_OK


def _add_run(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "run",
        help="run the chain a ship's TOML configuration describes",
        description="Run identify, track, correlate, fit, forecast and evaluate as far as "
        "the configuration gives their inputs (see workbench.config; `workbench demo` "
        "writes an example, ship.toml).",
    )
    parser.add_argument("config_file", type=Path, metavar="SHIP.TOML")
    parser.set_defaults(run=_run_chain)


def _run_chain(args: argparse.Namespace) -> int:
    from .config import ConfigError, chain, load_config

    try:
        steps = chain(load_config(args.config_file))
    except ConfigError as error:
        raise UsageError(str(error)) from None
    for step in steps:
        print(f"== workbench {' '.join(step)}", flush=True)
        code = main((["--verbose"] if args.verbose else []) + step)
        if code != EXIT_OK:
            return code
    return EXIT_OK


def _add_report(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "report",
        help="one HTML report of a run from its tables",
        description="Build one HTML page of the run in DIR (the folder the stages wrote "
        "into): an overview (what ran, on which data, modes found, warnings, skipped blocks, "
        "dropped channels), then spectra, stabilisation diagrams, tracked modes, mode shapes, "
        "correlation, regression and forecasts, as far as the run has them.",
    )
    parser.add_argument("dir", type=Path, metavar="DIR", help="the run's folder")
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
    parser.set_defaults(run=_run_report)


def _run_report(args: argparse.Namespace) -> int:
    from .reporting.report import build_report, find_run

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
    with _data_errors(args.dir):
        path = build_report(
            args.dir, out=args.out, run=run, title=args.title, stabilisation_blocks=blocks
        )
    print(f"report: {path}")
    return EXIT_OK


def _add_health(commands: argparse._SubParsersAction) -> None:
    from .health import HealthOptions

    defaults = HealthOptions()
    parser = commands.add_parser(
        "health",
        help="structural-health control chart of a forecast's frequency residuals",
        description="MEWMA/Hotelling chart of the standardised residuals (SSI minus model) "
        "of a forecast table: learns a reference period, then writes health.csv (statistic, "
        "limit, alarm per block) and alarms.csv (episodes with the modes that moved). Use a "
        "forecast whose model is frozen before the reference period (forecast --method 1), "
        "or give --modal, --predictors and --train-hours to fit the chart's own operational "
        "model (speed, speed², temperatures, speed x water, fuel) on the first hours.",
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--forecast", type=Path, metavar="FILE")
    source.add_argument("--modal", type=Path, metavar="FILE", help="tracked modal table")
    parser.add_argument(
        "--predictors", type=Path, metavar="FILE", help="block predictors (with --modal)"
    )
    parser.add_argument(
        "--train-hours",
        type=float,
        metavar="H",
        help="with --modal: hours the operational model is fitted on; the reference "
        "period follows them",
    )
    parser.add_argument(
        "--reference-hours", type=float, default=6.0, help="reference period length [h]"
    )
    parser.add_argument("--reference-start-block", type=int, metavar="K")
    parser.add_argument("--ewma-lambda", type=float, default=defaults.ewma_lambda)
    parser.add_argument("--false-alarms-per-day", type=float, default=defaults.false_alarms_per_day)
    parser.add_argument("--out", type=Path, required=True, metavar="DIR")
    parser.set_defaults(run=_run_health)


def _run_health(args: argparse.Namespace) -> int:
    from data_contracts import FORECAST, MODAL, PREDICTORS, read_table

    from .health import HealthOptions, fit_operational_model, health_chart

    source = args.forecast
    if args.modal is not None:
        if args.predictors is None or args.train_hours is None:
            raise UsageError("--modal needs --predictors and --train-hours")
        source = args.modal
        modal = read_table(args.modal, MODAL)
        predictors = read_table(args.predictors, PREDICTORS)
        step = predictors["block_start"].drop_duplicates().sort_values().diff().median()
        train = int(round(args.train_hours * 3600 / step.total_seconds()))
        reference = int(round(args.reference_hours * 3600 / step.total_seconds()))
        first = int(predictors["block"].min())
        if args.reference_start_block is None:
            args.reference_start_block = first + train
        try:
            model = fit_operational_model(
                modal, predictors, train_start_block=first, train_blocks=train
            )
            forecast = model.forecast(
                modal,
                predictors,
                reference_start_block=args.reference_start_block,
                reference_blocks=reference,
            )
        except ValueError as error:
            raise WorkbenchError(f"{args.modal}: {error}") from None
    else:
        forecast = read_table(args.forecast, FORECAST)
    step_h = forecast["block_start"].drop_duplicates().sort_values().diff().median()
    blocks = int(round(args.reference_hours * 3600 / step_h.total_seconds()))
    try:
        options = HealthOptions(
            reference_blocks=blocks,
            reference_start_block=args.reference_start_block,
            ewma_lambda=args.ewma_lambda,
            false_alarms_per_day=args.false_alarms_per_day,
        )
    except ValueError as error:
        raise UsageError(str(error)) from None
    try:
        result = health_chart(forecast, options)
    except ContractError:
        raise
    except ValueError as error:
        raise WorkbenchError(f"{source}: {error}") from None
    paths = result.save(args.out)
    print(result.summary())
    for path in paths.values():
        print(f"wrote {path}")
    return EXIT_OK


#: Subcommands in the order ``--help`` lists them.
COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_demo,
    _add_run,
    _add_simulate,
    _add_identify,
    _add_track,
    _add_correlate,
    _add_fit,
    _add_forecast,
    _add_evaluate,
    _add_report,
    _add_health,
    _add_validate,
)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line, ``warning: ...``, without source location (unless --verbose)."""
    print(f"warning: {_plain(message)}", file=sys.stderr if file is None else file)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="workbench",
        description="Hull vibration monitoring: identify, track, model and forecast a ship's "
        "structural modes from accelerations and the ship's log.",
    )
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show tracebacks and debug logging"
    )
    commands = parser.add_subparsers(title="commands", metavar="COMMAND")
    for add in COMMANDS:
        add(commands)
    for name, sub in commands.choices.items():
        if name in ("demo", "simulate", "run"):
            continue
        sub.add_argument(
            "--config",
            type=Path,
            metavar="SHIP.TOML",
            help="take this command's settings from a ship's configuration (flags win)",
        )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with *argv* (default ``sys.argv[1:]``) and return the exit status."""
    parser = build_parser()
    try:
        _apply_config(parser, argv)
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # argparse exits 2 on usage errors, 0 on --help
        return int(exit_.code or 0)
    if not hasattr(args, "run"):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING,
        format="%(message)s",
        stream=sys.stderr,
    )
    log.setLevel(logging.DEBUG if args.verbose else logging.INFO)
    for noisy in ("distributed", "tornado", "bokeh", "asyncio"):  # cluster chatter
        logging.getLogger(noisy).setLevel(logging.DEBUG if args.verbose else logging.ERROR)
    shown = warnings.showwarning
    if not args.verbose:
        warnings.showwarning = _show_warning
    try:
        return _run(args)
    finally:
        warnings.showwarning = shown


def _apply_config(parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> None:
    """Defaults from ``--config FILE`` (bad files: message and exit 2)."""
    from .config import ConfigError, apply_config, load_config

    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--config", type=Path)
    known, _ = pre.parse_known_args(argv)
    if known.config is not None:
        try:
            apply_config(parser, load_config(known.config))
        except ConfigError as error:
            print(f"workbench: error: {error}", file=sys.stderr)
            raise SystemExit(EXIT_USAGE) from None


#: NumPy >= 2 scalar reprs (``np.float64(0.5)``) inside messages built with ``!r``.
_NUMPY_REPR = re.compile(r"\bnp\.(?:float|int|uint|complex|bool|str)\w*\(([^()]*)\)")


def _plain(message) -> str:
    """*message* with NumPy scalar reprs shown as plain values (``0.5``, not
    ``np.float64(0.5)``); one rule for every message the CLI prints."""
    return _NUMPY_REPR.sub(r"\1", str(message))


def _os_error_line(error: OSError) -> str:
    """``path: reason`` of a file-system error (read-only folder, disk full, ...)."""
    reason = error.strerror or str(error).splitlines()[0] or type(error).__name__
    names = [n for n in (error.filename, error.filename2) if n is not None]
    return f"{' -> '.join(map(str, names))}: {reason}" if names else reason


def _run(args: argparse.Namespace) -> int:
    """Run the chosen command; user errors become messages and exit statuses."""
    try:
        return int(args.run(args) or EXIT_OK)
    except ContractError as error:
        if args.verbose:
            raise
        for line in error.lines():
            print(_plain(line), file=sys.stderr)
        return EXIT_DATA
    except WorkbenchError as error:
        if args.verbose:
            raise
        print(f"error: {_plain(error)}", file=sys.stderr)
        return EXIT_DATA
    except (UsageError, OptionError) as error:
        print(f"workbench: error: {_plain(_option_names(str(error)))}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as error:  # file-system errors on output: one line, exit 1
        if args.verbose:
            raise
        print(f"error: {_os_error_line(error)}", file=sys.stderr)
        return EXIT_DATA
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
