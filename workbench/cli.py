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
from . import defaults as D
from .arguments import (
    HelpFormatter,
    Namespace,
    add_renamed,
    add_verbosity,
    choice,
    stderr_is_terminal,
)
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
        )
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    print(f"{args.file}: valid {args.kind} file ({checked.summary})")
    return EXIT_OK


def _add_dashboard(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "dashboard",
        help="serve the live bridge dashboard of a monitor's state folder",
        description="Serve a web page that shows what `workbench monitor` publishes into its "
        "state folder: current modes with forecast bounds, the last hours of tracked "
        "frequencies, the health chart with its limit, data health and alarms. It updates "
        "without a reload, needs no internet and never writes into the folder.",
    )
    parser.add_argument("--state", type=Path, metavar="DIR", help="the monitor's state folder")
    parser.add_argument(
        "--demo",
        action="store_true",
        help="replay a simulated voyage into a temporary folder, a block every 2 s",
    )
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to listen on (default: %(default)s, this machine only)",
    )
    parser.add_argument("--port", type=int, default=8050, help="port (0: any free port)")
    parser.add_argument("--hours", type=float, default=6.0, help="tracked-frequency span [h]")
    parser.add_argument("--health-hours", type=float, default=24.0, help="health-chart span [h]")
    parser.add_argument("--poll", type=float, default=1.0, help="page checks for changes every [s]")
    parser.add_argument("--option", choices=("A", "B"), help="forecast option on the mode cards")
    parser.set_defaults(run=_run_dashboard)


def _run_dashboard(args: argparse.Namespace) -> int:
    from .dashboard import DashboardOptions, is_loopback, make_server, serve_until_stopped

    try:
        options = DashboardOptions(
            hours=args.hours,
            health_hours=args.health_hours,
            poll_seconds=args.poll,
            option=args.option,
        )
    except ValueError as error:
        raise UsageError(str(error).replace("poll_seconds", "poll")) from None
    if not 0 <= args.port <= 65535:
        raise UsageError(f"--port={args.port} must be in 0-65535")
    if (args.state is None) == (not args.demo):
        raise UsageError("give --state DIR or --demo (not both)")
    if args.demo:
        return _serve_demo(args, options)
    if args.state.exists() and not args.state.is_dir():
        raise UsageError(f"--state {args.state} is a file, not a folder")
    if not args.state.exists():
        print(f"warning: {args.state} does not exist yet; the page waits for it", file=sys.stderr)
    if not is_loopback(args.host):
        print(
            f"warning: listening on {args.host}: anyone who reaches this machine on port "
            f"{args.port} sees the dashboard (read-only, no login)",
            file=sys.stderr,
        )
    try:
        server = make_server(args.state, host=args.host, port=args.port, options=options)
    except OSError as error:
        reason = error.strerror or str(error)
        raise WorkbenchError(f"cannot listen on {args.host}:{args.port}: {reason}") from None
    print(f"dashboard of {args.state} on {server.url} (Ctrl+C stops it)", flush=True)
    serve_until_stopped(server)
    return EXIT_OK


def _serve_demo(args: argparse.Namespace, options) -> int:
    import tempfile

    from .dashboard import DemoReplay

    with tempfile.TemporaryDirectory(prefix="workbench-dashboard-demo-") as folder:
        replay = DemoReplay(folder).start()
        args.state = Path(folder)
        try:
            return _run_dashboard(argparse.Namespace(**{**vars(args), "demo": False}))
        finally:
            replay.stop()


def _add_simulate(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "simulate",
        help="simulate a demo voyage with known modal parameters",
        description="Write a simulated voyage: 5-minute acceleration files, the DSHIP log, "
        "ground-truth and noisy tracked modal tables, and pole tables.",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    parser.add_argument("--seed", type=int, default=D.SEED, help="random seed")
    parser.add_argument(
        "--hours",
        type=float,
        default=None,
        help=f"voyage length [h] (default: the demo length, {D.HOURS:g} h)",
    )
    parser.add_argument(
        "--no-accelerations", action="store_true", help="skip the acceleration files (tables only)"
    )
    add_renamed(
        parser,
        "--sampling-rate",
        ["--rate"],
        type=float,
        default=D.SIMULATE_SAMPLING_RATE_HZ,
        metavar="HZ",
        help="sampling rate of the acceleration files [Hz], a multiple of 64 Hz (e.g. 2048, "
        "a recorder's rate: same modal physics, broadband content and a 60 Hz hum above the "
        "band)",
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
            sampling_rate_hz=args.sampling_rate,
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
    parser.add_argument("--out", type=Path, default=D.DEMO_OUT, metavar="DIR", help="output folder")
    parser.add_argument("--seed", type=int, default=D.SEED, help="random seed")
    parser.add_argument(
        "--hours", type=float, default=None, help=f"voyage length [h] (default: {D.HOURS:g})"
    )
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


def _print_result(result, paths=None) -> None:
    """A stage result's warnings (stderr), lines and the files it wrote."""
    for line in result.warnings:
        print(f"warning: {line}", file=sys.stderr)
    for line in result.lines:
        print(line)
    for name, path in dict(paths or {}).items():
        print(f"{name}: {path}")


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
    from .predictors import canonical_predictors, load_predictors

    table = load_predictors(
        predictors=args.predictors, dship=args.dship, onto=modal, dship_mapping=dship_mapping(args)
    )
    return table if args.all_predictors else canonical_predictors(table)


def _modal_and_predictors(args: argparse.Namespace):
    """``--modal`` and the predictors (``--predictors`` or ``--dship`` averaged onto the
    modal blocks) of correlate, fit and forecast, their block times checked against each
    other."""
    modal = _read_modal(args, args.modal)
    predictors = _predictors_for(args, modal)
    _check_joins(args, modal, predictors)
    return modal, predictors


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
        "--store", type=Path, metavar="DIR", help="per-block store (default: OUT/store)"
    )
    parser.add_argument(
        "--method",
        choices=("cov", "data", "lscf"),
        default=D.IDENTIFY_METHOD,
        help="identification method: covariance-driven (cov) or data-driven (data) SSI, or "
        "poly-reference LSCF (PolyMAX)",
    )
    parser.add_argument(
        "--lscf-max-order",
        type=int,
        default=D.IDENTIFY_LSCF_MAX_ORDER,
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
        "--block-rows",
        type=int,
        default=D.IDENTIFY_BLOCK_ROWS,
        metavar="I",
        help="SSI block rows (time lags of the Hankel matrix)",
    )
    parser.add_argument(
        "--max-order",
        type=int,
        default=D.IDENTIFY_MAX_ORDER,
        metavar="N",
        help="highest model order (lowered to what the block rows and channels allow)",
    )
    parser.add_argument(
        "--min-order",
        type=int,
        default=D.IDENTIFY_MIN_ORDER,
        metavar="N",
        help=f"lowest model order (orders step by {D.IDENTIFY_ORDER_STEP})",
    )
    parser.add_argument(
        "--weighting",
        choices=("pc", "upc", "cva"),
        default=D.IDENTIFY_WEIGHTING,
        help="SSI-data weighting",
    )
    add_renamed(
        parser,
        "--reference-channels",
        ["--reference"],
        metavar="CH,CH,...",
        help="SSI reference channels (default: all)",
    )
    parser.add_argument(
        "--rate",
        default=D.IDENTIFY_RATE,
        metavar="HZ|auto|native",
        help="analysis rate the files are decimated to (Chebyshev I, each file once). "
        "'auto': the files' rate halved while it stays at or above 4 x the "
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
        help=f"block length [min] (default: {D.BLOCK_MINUTES:g}); a length below the default "
        "step needs --step-minutes too",
    )
    parser.add_argument(
        "--step-minutes",
        type=float,
        default=None,
        metavar="MIN",
        help=f"step between blocks [min] (default: {D.STEP_MINUTES:g})",
    )
    parser.add_argument(
        "--short-record",
        choices=("error", "one-block"),
        default=D.IDENTIFY_SHORT_RECORD,
        help="data shorter than one block: an error naming the record, or one block of the "
        "record's length",
    )
    parser.add_argument(
        "--selection",
        choices=("cluster", "library"),
        default=D.IDENTIFY_SELECTION,
        help="automatic pole selection: clustering of the poles of all orders with "
        "thresholds from the data, or the library-and-descent rule",
    )
    check = parser.add_argument_group("channel check (per block; a faulty channel is dropped)")
    check.add_argument(
        "--no-channel-check", action="store_true", help="keep every channel that has data"
    )
    check.add_argument(
        "--kurtosis-max",
        type=float,
        default=D.IDENTIFY_KURTOSIS_MAX,
        metavar="K",
        help="kurtosis above K (Gaussian 3) is a fault when out of line with the other channels",
    )
    check.add_argument(
        "--kurtosis-z-max",
        type=float,
        default=D.IDENTIFY_KURTOSIS_Z_MAX,
        metavar="Z",
        help="robust z-score of a channel's log-kurtosis among the channels above which a "
        "kurtosis above K is a fault (impulsive excitation raises every channel)",
    )
    check.add_argument(
        "--variance-z-max",
        type=float,
        default=D.IDENTIFY_VARIANCE_Z_MAX,
        metavar="Z",
        help="robust z-score of a channel's log-variance among the channels beyond which it "
        "is a fault if it also lost coherence with every other channel",
    )
    check.add_argument(
        "--max-nan-fraction",
        type=float,
        default=D.IDENTIFY_MAX_NAN_FRACTION,
        metavar="SHARE",
        help="largest share of missing samples",
    )
    parser.add_argument(
        "--conditioning",
        choices=("per-file", "per-block"),
        default=D.IDENTIFY_CONDITIONING,
        help="when decimating: condition each file once or every block from its raw files "
        "(reference path, slower)",
    )
    parser.add_argument(
        "--max-gap",
        type=float,
        default=D.IDENTIFY_MAX_GAP_S,
        metavar="S",
        help="NaN-pad gaps between files up to S seconds inside a block",
    )
    add_renamed(
        parser,
        "--stabilisation-figures",
        ["--figures"],
        type=int,
        default=0,
        metavar="K",
        help="stabilisation diagrams of K blocks spread over the voyage",
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
        default=D.IDENTIFY_BATCH_BLOCKS,
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


def identify_options(args: argparse.Namespace):
    """The :class:`~workbench.identify.IdentifyOptions` that parsed identification flags
    describe (``identify`` and ``monitor``); options a command lacks take their defaults.

    Raises
    ------
    UsageError
        For contradicting or impossible flags (exit 2).
    """
    from .blocks import DEFAULT_BLOCK_LENGTH_S, DEFAULT_BLOCK_STEP_S
    from .identify import IdentifyOptions

    def flag(name: str, default):
        value = getattr(args, name, None)
        return default if value is None else value

    lscf_max_order = flag("lscf_max_order", D.IDENTIFY_LSCF_MAX_ORDER)
    if args.min_order < 1 or args.max_order < args.min_order:
        raise UsageError(f"model orders {args.min_order}..{args.max_order} make no sense")
    if lscf_max_order < 1:
        raise UsageError(f"--lscf-max-order must be at least 1, got {lscf_max_order}")
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
    try:
        return IdentifyOptions(
            method=args.method,
            block_rows=args.block_rows,
            orders=tuple(range(args.min_order, args.max_order + 1, D.IDENTIFY_ORDER_STEP)),
            weighting=args.weighting,
            reference_channels=(
                tuple(args.reference_channels.split(",")) if args.reference_channels else None
            ),
            length_s=length_s,
            step_s=step_s,
            target_rate_hz=_analysis_rate(str(args.rate)),
            band_hz=None if args.no_band else (tuple(args.band) if args.band else "auto"),
            max_gap_s=args.max_gap,
            lscf_orders=tuple(range(1, lscf_max_order + 1)),
            cross_check=flag("cross_check", IdentifyOptions().cross_check),
            acceleration_layout=acceleration_layout(args),
            selection=args.selection,
            short_record=flag("short_record", D.IDENTIFY_SHORT_RECORD),
            channel_check=not args.no_channel_check,
            fault_options=(
                ("kurtosis_limits", (1.3, flag("kurtosis_max", D.IDENTIFY_KURTOSIS_MAX))),
                ("max_variance_z", flag("variance_z_max", D.IDENTIFY_VARIANCE_Z_MAX)),
                ("max_kurtosis_z", flag("kurtosis_z_max", D.IDENTIFY_KURTOSIS_Z_MAX)),
                ("max_nan_fraction", flag("max_nan_fraction", D.IDENTIFY_MAX_NAN_FRACTION)),
            ),
            conditioning=args.conditioning,
        )
    except ValueError as error:
        raise UsageError(_option_names(str(error))) from None


def _run_identify(args: argparse.Namespace) -> int:
    from .identify import IdentifyOptionsError
    from .stages import identify

    options = identify_options(args)
    _check_positive(workers=args.workers, batch_blocks=args.batch_blocks)
    if args.stabilisation_figures < 0:
        raise UsageError(
            f"--stabilisation-figures must be 0 or more, got {args.stabilisation_figures}"
        )
    try:
        result = identify(
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
    for line in result.lines:
        print(line)
    if args.stabilisation_figures:
        from .identify import write_block_figures

        for path in write_block_figures(
            args.inputs,
            args.out / "figures",
            options=options,
            n_blocks=args.stabilisation_figures,
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
    "reference_channels": "--reference-channels",
    "batch_blocks": "--batch-blocks",
    "n_workers": "--workers",
    "scheduler": "--scheduler",
    "mac_min": "--mac-min",
    "frequency_tol": "--frequency-tol",
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
    add_renamed(
        parser,
        "--reference-modes",
        ["--reference"],
        type=Path,
        metavar="FILE",
        help="modal table whose modes start the tracker's library (labels kept)",
    )
    add_renamed(
        parser,
        "--mac-min",
        ["--threshold"],
        type=float,
        default=D.TRACK_MAC_MIN,
        metavar="MAC",
        help="lowest MAC (or MACXP with --gate macxp) to join a mode",
    )
    parser.add_argument(
        "--gate",
        choices=("mac", "macxp"),
        default=D.TRACK_GATE,
        help="criterion --mac-min applies to",
    )
    add_renamed(
        parser,
        "--frequency-tol",
        ["--frequency-tolerance"],
        type=float,
        default=D.TRACK_FREQUENCY_TOL,
        metavar="REL",
        help="largest relative frequency difference to join a mode",
    )
    parser.set_defaults(run=_run_track)


def _run_track(args: argparse.Namespace) -> int:
    from .stages import TrackingOptions, track

    try:
        options = TrackingOptions(
            mac_min=args.mac_min, gate=args.gate, frequency_tol=args.frequency_tol
        )
    except ValueError as error:
        raise UsageError(_option_names(str(error))) from None
    _check_table_path(args.out)
    with _data_errors(args.selected):
        result = track(
            args.selected,
            reference_modes=args.reference_modes,
            options=options,
            progress=not args.quiet,
        )
    paths = result.save(args.out)
    _print_result(result, paths)
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
    parser.add_argument("--alpha", type=float, default=D.CORRELATE_ALPHA, help="significance level")
    parser.add_argument(
        "--correction",
        choices=("none", "holm", "fdr_bh"),
        default=D.CORRELATE_CORRECTION,
        help="multiple-testing correction of the p-values",
    )
    parser.add_argument(
        "--min-presence",
        type=float,
        default=D.MIN_PRESENCE,
        metavar="SHARE",
        help="only modes measured in at least this share of the blocks",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    parser.set_defaults(run=_run_correlate)


def _run_correlate(args: argparse.Namespace) -> int:
    from .stages import CorrelateOptions, correlate

    if not 0.0 < args.alpha < 1.0:
        raise UsageError(f"--alpha must be in (0, 1), got {args.alpha}")
    _check_share("min-presence", args.min_presence)
    options = CorrelateOptions(
        alpha=args.alpha,
        correction=None if args.correction == "none" else args.correction,
        min_presence=args.min_presence,
    )
    modal, predictors = _modal_and_predictors(args)
    with _data_errors(args.modal):
        result = correlate(modal, predictors, cases=args.cases, options=options)
        paths = result.save(args.out)
    _print_result(result, paths)
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
    parser.add_argument(
        "--p-enter", type=float, default=D.FIT_P_ENTER, help="F-test p-value to add a term"
    )
    parser.add_argument(
        "--p-remove", type=float, default=D.FIT_P_REMOVE, help="F-test p-value to remove a term"
    )
    parser.add_argument(
        "--upper",
        default=D.FIT_UPPER,
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
        default=D.MIN_PRESENCE,
        metavar="SHARE",
        help="only modes measured in at least this share of the blocks",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    parser.set_defaults(run=_run_fit)


def _run_fit(args: argparse.Namespace) -> int:
    from .stages import FitOptions, fit

    if not 0.0 < args.p_enter < args.p_remove < 1.0:
        raise UsageError(
            f"need 0 < --p-enter < --p-remove < 1, got {args.p_enter} and {args.p_remove}"
        )
    _check_share("min-presence", args.min_presence)
    options = FitOptions(
        p_enter=args.p_enter,
        p_remove=args.p_remove,
        upper=args.upper,
        min_presence=args.min_presence,
    )
    modal, predictors = _modal_and_predictors(args)
    _check_upper(args.upper, predictors)
    with _data_errors(args.modal):
        result = fit(modal, predictors, cases=_cases_argument(args.cases), options=options)
        paths = result.save(args.out)
    _print_result(result, paths)
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


#: ``--option``: what each block measures (the reference work's options A and B).
FORECAST_OPTIONS = choice(
    {"tracked-pole": "A", "pole-cluster": "B", "both": "AB"},
    {"A": "tracked-pole", "B": "pole-cluster", "AB": "both"},
)
#: ``--scheme``: how the forecast slides (the reference work's methods 1 and 2).
FORECAST_SCHEMES = choice(
    {"single-window": 1, "rolling": 2}, {"1": "single-window", "2": "rolling"}
)


def _add_forecast(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "forecast",
        help="sliding regression forecast of each mode, Kalman-blended with SSI",
        description="Train a stepwise model of each mode's frequency on the last N blocks, "
        "predict ahead with 95 % bounds and blend with the SSI estimates by a Kalman filter. "
        "The measurement of a block is its tracked pole (--option tracked-pole, the reference "
        "work's option A) or the pole cluster of its stabilisation diagram inside the "
        "prediction gate (pole-cluster, option B).",
    )
    parser.add_argument(
        "--modal", type=Path, required=True, metavar="FILE", help="tracked modal table"
    )
    _add_predictor_source(parser)
    parser.add_argument(
        "--poles",
        type=Path,
        metavar="FILE",
        help="pole table (stabilisation diagrams), needed for --option pole-cluster",
    )
    parser.add_argument(
        "--option",
        type=FORECAST_OPTIONS,
        metavar=FORECAST_OPTIONS.metavar,
        default=D.FORECAST_OPTION,
        help="measurement: the tracked pole (alias A), the pole cluster of the "
        "stabilisation diagram nearest the prediction (alias B), or both into one table "
        "(alias AB); the table's option column says A or B",
    )
    add_renamed(
        parser,
        "--scheme",
        ["--method"],
        type=FORECAST_SCHEMES,
        metavar=FORECAST_SCHEMES.metavar,
        default=D.FORECAST_SCHEME,
        help="single-window (alias 1): one training window, one long forecast; rolling "
        "(alias 2): predict H blocks, filter them, slide the window, refit",
    )
    add_renamed(
        parser,
        "--train-blocks",
        ["--train"],
        type=int,
        default=D.FORECAST_TRAIN_BLOCKS,
        metavar="N",
        help="training window [blocks]",
    )
    parser.add_argument(
        "--horizon",
        type=int,
        default=None,
        metavar="H",
        help="blocks per forecast [blocks] (default: "
        + ", ".join(f"{h} for {s}" for s, h in D.FORECAST_HORIZON.items())
        + ")",
    )
    parser.add_argument(
        "--model",
        choices=("memory", "window"),
        default=D.FORECAST_MODEL,
        help="window: the reference configuration, a stepwise fit on the last "
        "--train-blocks blocks and --trust; memory: stepwise terms, coefficients over the "
        "whole history with forgetting, noise levels from the data",
    )
    parser.add_argument(
        "--trust",
        default=None,
        help=f"--model window only: steady-state weight on SSI in (0, 1) (default: "
        f"{D.FORECAST_TRUST:g}), or 'data' for a Q from the model's own prediction variance",
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
    add_renamed(
        parser,
        "--workers",
        ["--jobs"],
        type=int,
        default=D.FORECAST_WORKERS,
        metavar="N",
        help="worker processes to spread the modes over (for voyage-length tables)",
    )
    parser.add_argument(
        "--min-presence",
        type=float,
        default=D.MIN_PRESENCE,
        metavar="SHARE",
        help="forecast only modes measured in at least this share of the blocks",
    )
    add_renamed(
        parser,
        "--mac-min",
        ["--shape-mac-min"],
        type=float,
        default=D.FORECAST_MAC_MIN,
        metavar="MAC",
        help="pole-cluster: lowest MAC of a pole's shape with the mode's tracked shape",
    )
    parser.add_argument(
        "--reacquire-blocks",
        type=int,
        default=None,
        metavar="K",
        help="pole-cluster: blocks seen only outside the gate before the track is "
        "re-acquired (default: "
        + ", ".join(f"{k} for --model {m}" for m, k in D.FORECAST_REACQUIRE_BLOCKS.items())
        + ")",
    )
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

    from .stages import ForecastOptions, forecast

    options = ("A", "B") if args.option == "AB" else (args.option,)
    if "B" in options and args.poles is None:
        raise UsageError("--option pole-cluster (B) needs --poles (the stabilisation diagrams)")
    if args.train_blocks < 2:
        raise UsageError(f"--train-blocks must be at least 2, got {args.train_blocks}")
    if args.trust is not None and args.model != "window":
        raise UsageError(
            "--trust applies to --model window; --model memory takes its noise levels from the data"
        )
    _check_positive(
        horizon=args.horizon, workers=args.workers, reacquire_blocks=args.reacquire_blocks
    )
    _check_share("min-presence", args.min_presence)
    _check_share("mac-min", args.mac_min)
    _check_table_path(args.out)
    trust = "auto" if args.trust is None else _parse_trust(args.trust)
    modal, predictors = _modal_and_predictors(args)
    poles = read_table(args.poles, POLES) if args.poles is not None else None
    truth = _read_modal(args, args.truth) if args.truth is not None else None
    _check_joins(args, modal, None, poles)
    stage_options = ForecastOptions(
        options=options,
        scheme=args.scheme,
        train_blocks=args.train_blocks,
        horizon=args.horizon,
        trust=trust,
        model=args.model,
        n_workers=args.workers,
        min_presence=args.min_presence,
        mac_min=args.mac_min,
        reacquire_blocks=args.reacquire_blocks,
    )
    with _data_errors(args.modal):
        result = forecast(
            modal,
            predictors,
            poles=poles,
            cases=_cases_argument(args.cases),
            options=stage_options,
            progress=not args.quiet,
        )
        paths = result.save(args.out, figures=args.figures, truth=truth)
    _print_result(result, paths)
    return EXIT_OK


def _add_evaluate(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "evaluate",
        help="compare SSI, model and Kalman estimates with a true modal table",
        description="Cumulative absolute error per mode of the SSI-only, model-only and "
        "Kalman estimates of a forecast table against the truth (e.g. of the demo voyage), "
        "and the improvement in %.",
    )
    parser.add_argument(
        "--forecast", type=Path, required=True, metavar="FILE", help="forecast table"
    )
    parser.add_argument(
        "--truth", type=Path, required=True, metavar="FILE", help="true modal table"
    )
    parser.add_argument(
        "--phase",
        choices=("forecast", "train", "all"),
        default=D.EVALUATE_PHASE,
        help="rows compared: the forecast blocks, the training blocks or all",
    )
    parser.add_argument(
        "--out", type=Path, metavar="FILE", help="write the table (.csv or .parquet)"
    )
    add_modal_layout(parser)
    parser.set_defaults(run=_run_evaluate)


def _run_evaluate(args: argparse.Namespace) -> int:
    from data_contracts import FORECAST

    from .joins import check_block_times
    from .stages import evaluate
    from .stages.evaluation import SUMMARY_COLUMNS

    if args.out is not None:
        _check_table_path(args.out)
    forecast = _read_modal(args, args.forecast, FORECAST)
    truth = _read_modal(args, args.truth)
    check_block_times(forecast, args.forecast, truth, args.truth)
    result = evaluate(forecast, truth, phase=None if args.phase == "all" else args.phase)
    paths = result.save(args.out) if args.out is not None else {}
    print(result.table[SUMMARY_COLUMNS].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    _print_result(result, paths)
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
    parser = commands.add_parser(
        "health",
        help="structural-health control chart of a forecast's frequency residuals",
        description="Per-mode CUSUM chart (or MEWMA/Hotelling) of the standardised "
        "residuals (SSI minus model) "
        "of a forecast table: learns a reference period, then writes health.csv (statistic, "
        "limit, alarm per block) and alarms.csv (episodes with the modes that moved). Use a "
        "forecast whose model is frozen before the reference period (forecast --scheme "
        "single-window), or give --modal, --predictors and --train-hours to fit the chart's "
        "own operational model (speed, speed², temperatures, speed x water, fuel) on the "
        "first hours.",
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--forecast", type=Path, metavar="FILE", help="forecast table")
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
        "--reference-hours",
        type=float,
        default=D.HEALTH_REFERENCE_HOURS,
        help="reference period length [h]",
    )
    parser.add_argument(
        "--reference-start-block",
        type=int,
        metavar="K",
        help="first block of the reference period (default: the first block of the forecast "
        "phase, or the first after the training hours with --modal)",
    )
    parser.add_argument(
        "--ewma-lambda",
        type=float,
        default=D.HEALTH_EWMA_LAMBDA,
        help="weight of the newest block in the MEWMA statistic",
    )
    parser.add_argument(
        "--false-alarms-per-day",
        type=float,
        default=D.HEALTH_FALSE_ALARMS_PER_DAY,
        help="expected false alarms per day in control (sets the limit)",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")
    parser.set_defaults(run=_run_health)


def _block_step_s(table) -> float:
    """Block step of *table*: its recorded grid, else the median step of its blocks."""
    from data_contracts import recorded_grid

    grid = recorded_grid(table)
    if grid is not None:
        return float(grid["step_s"])
    starts = table["block_start"].drop_duplicates().sort_values()
    return float(starts.diff().median().total_seconds())


def _run_health(args: argparse.Namespace) -> int:
    from data_contracts import FORECAST, MODAL, PREDICTORS, read_table

    from .health import HealthOptions, fit_operational_model
    from .stages import health

    source = args.forecast
    if args.modal is not None:
        if args.predictors is None or args.train_hours is None:
            raise UsageError("--modal needs --predictors and --train-hours")
        source = args.modal
        modal = read_table(args.modal, MODAL)
        predictors = read_table(args.predictors, PREDICTORS)
        step_s = _block_step_s(predictors)
        train = int(round(args.train_hours * 3600 / step_s))
        reference = int(round(args.reference_hours * 3600 / step_s))
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
    blocks = int(round(args.reference_hours * 3600 / _block_step_s(forecast)))
    try:
        options = HealthOptions(
            reference_blocks=blocks,
            reference_start_block=args.reference_start_block,
            ewma_lambda=args.ewma_lambda,
            false_alarms_per_day=args.false_alarms_per_day,
        )
    except ValueError as error:
        raise UsageError(str(error)) from None
    with _data_errors(source):
        result = health(forecast, options=options)
    paths = result.save(args.out)
    print(result.summary())
    for path in paths.values():
        print(f"wrote {path}")
    return EXIT_OK


def _add_monitor(commands: argparse._SubParsersAction) -> None:
    from .monitor.cli import add_monitor

    add_monitor(commands)


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
    _add_dashboard,
    _add_monitor,
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
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    add_verbosity(parser, top_level=True)
    commands = parser.add_subparsers(title="commands", metavar="COMMAND")
    for add in COMMANDS:
        add(commands)
    for name, sub in commands.choices.items():
        sub.formatter_class = HelpFormatter
        add_verbosity(sub)
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
        args = parser.parse_args(argv, namespace=Namespace())
    except SystemExit as exit_:  # argparse exits 2 on usage errors, 0 on --help
        return int(exit_.code or 0)
    if not hasattr(args, "run"):
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    if not stderr_is_terminal():  # no progress bars in logs, pipes and CI
        args.quiet = True
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING,
        format="%(message)s",
        stream=sys.stderr,
    )
    log.setLevel(logging.DEBUG if args.verbose else logging.INFO)
    for noisy in ("distributed", "tornado", "bokeh", "asyncio"):  # cluster chatter
        logging.getLogger(noisy).setLevel(logging.DEBUG if args.verbose else logging.ERROR)
    import matplotlib

    matplotlib.use("Agg")  # commands write figures to files and never open a window
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
