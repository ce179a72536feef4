"""Command-line interface: ``workbench COMMAND ...``.

The CLI parses arguments, calls the library and prints; nothing else. Exit status: 0 on
success, 1 on bad data (one line per problem on stderr, naming file, column and rows),
2 on usage errors. Tracebacks only with ``--verbose``.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

from data_contracts import ContractError

from . import __version__
from .errors import WorkbenchError

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
    parser.set_defaults(run=_run_validate)


def _run_validate(args: argparse.Namespace) -> int:
    from data_contracts import CONTRACTS, read_accelerations, read_dship, read_table

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if args.kind == "accelerations":
            record = read_accelerations(args.file)
            summary = (
                f"{record.n_samples} samples x {len(record.channels)} channels at "
                f"{record.sampling_rate_hz:g} Hz from {record.start_time.isoformat()}"
            )
        elif args.kind == "dship":
            table = read_dship(args.file)
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

    if args.hours is not None and args.hours <= 0:
        raise UsageError(f"--hours must be positive, got {args.hours}")
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
    except ContractError:
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
    parser.add_argument(
        "--all-predictors",
        action="store_true",
        help="use every numeric column of the predictors, not only speed, water/air "
        "temperature, wind speed and relative wind direction",
    )


def _predictors_for(args: argparse.Namespace, modal):
    from .pipeline import canonical_predictors, load_predictors

    table = load_predictors(predictors=args.predictors, dship=args.dship, like=modal)
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
        description="Cut acceleration files into blocks (default 20 min, 75 %% overlap), "
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
        choices=("cov", "data"),
        default="cov",
        help="covariance-driven or data-driven SSI",
    )
    parser.add_argument("--block-rows", type=int, default=20, metavar="I")
    parser.add_argument("--max-order", type=int, default=60, metavar="N")
    parser.add_argument("--min-order", type=int, default=4, metavar="N")
    parser.add_argument(
        "--weighting", choices=("pc", "upc", "cva"), default="pc", help="SSI-data weighting"
    )
    parser.add_argument(
        "--reference", metavar="CH,CH,...", help="reference channels (default: all)"
    )
    parser.add_argument(
        "--rate",
        type=_analysis_rate,
        default="auto",
        metavar="HZ|auto|native",
        help="analysis rate the files are decimated to (Chebyshev I, each file once). "
        "'auto' (default): the files' rate halved while it stays at or above 4 x the "
        "band's upper edge (2048 Hz files and the 2-12 Hz band -> 64 Hz; 64 Hz files stay); "
        "'native': keep the files' rate",
    )
    parser.add_argument(
        "--band",
        type=float,
        nargs=2,
        default=(2.0, 12.0),
        metavar=("LOW", "HIGH"),
        help="band-pass and selection band [Hz]",
    )
    parser.add_argument("--no-band", action="store_true", help="no band-pass filter")
    parser.add_argument(
        "--conditioning",
        choices=("per-file", "per-block"),
        default="per-file",
        help="when decimating: condition each file once (default) or every block from its "
        "raw files (reference path, slower)",
    )
    parser.add_argument("--block-minutes", type=float, default=20.0)
    parser.add_argument("--step-minutes", type=float, default=5.0)
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
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a rate in Hz, 'auto' or 'native'"
        ) from None
    if not rate > 0:
        raise argparse.ArgumentTypeError(f"rate {text} Hz must be positive")
    return rate


def _run_identify(args: argparse.Namespace) -> int:
    from .identify import IdentifyOptions, identify_voyage

    if args.min_order < 1 or args.max_order < args.min_order:
        raise UsageError(f"model orders {args.min_order}..{args.max_order} make no sense")
    try:
        options = IdentifyOptions(
            method=args.method,
            block_rows=args.block_rows,
            orders=tuple(range(args.min_order, args.max_order + 1, 2)),
            weighting=args.weighting,
            reference_channels=tuple(args.reference.split(",")) if args.reference else None,
            length_s=60.0 * args.block_minutes,
            step_s=60.0 * args.step_minutes,
            target_rate_hz=args.rate,
            band_hz=None if args.no_band else tuple(args.band),
            max_gap_s=args.max_gap,
            conditioning=args.conditioning,
        )
    except ValueError as error:
        raise UsageError(str(error)) from None
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
    for line in result.lines():
        print(line)
    if args.figures:
        from .identify import write_block_figures

        for path in write_block_figures(
            args.inputs, args.out / "figures", options=options, n_blocks=args.figures
        ):
            print(f"figure: {path}")
    return EXIT_OK


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
    from data_contracts import MODAL, read_table

    from .reporting.correlation import write_correlation_report

    if not 0.0 < args.alpha < 1.0:
        raise UsageError(f"--alpha must be in (0, 1), got {args.alpha}")
    modal = read_table(args.modal, MODAL)
    predictors = _predictors_for(args, modal)
    modal = _persistent(modal, args.min_presence)
    with _data_errors(args.modal):
        paths = write_correlation_report(
            modal,
            predictors,
            args.out,
            cases=args.cases,
            alpha=args.alpha,
            correction=None if args.correction == "none" else args.correction,
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
        "--min-presence",
        type=float,
        default=0.5,
        metavar="SHARE",
        help="only modes measured in at least this share of the blocks",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="DIR")
    parser.set_defaults(run=_run_fit)


def _run_fit(args: argparse.Namespace) -> int:
    from data_contracts import MODAL, read_table

    from .reporting.diagnostics_plot import write_fit_report

    if not 0.0 < args.p_enter < args.p_remove < 1.0:
        raise UsageError(
            f"need 0 < --p-enter < --p-remove < 1, got {args.p_enter} and {args.p_remove}"
        )
    modal = read_table(args.modal, MODAL)
    predictors = _predictors_for(args, modal)
    modal = _persistent(modal, args.min_presence)
    with _data_errors(args.modal):
        paths = write_fit_report(
            modal,
            predictors,
            args.out,
            p_enter=args.p_enter,
            p_remove=args.p_remove,
            upper=args.upper,
        )
    for name, path in dict(paths).items():
        print(f"{name}: {path}")
    return EXIT_OK


def _add_forecast(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "forecast",
        help="sliding regression forecast of each mode, Kalman-blended with SSI",
        description="Train a stepwise model of each mode's frequency on the last N blocks, "
        "predict ahead with 95 %% bounds and blend with the SSI estimates by a Kalman filter "
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
        "--trust",
        default="0.65",
        help="steady-state weight on SSI in (0, 1), or 'data' for a Q from "
        "the model's own prediction variance",
    )
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="FILE",
        help="forecast table to write (.csv or .parquet)",
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
        default=1,
        metavar="K",
        help="option B: blocks seen only outside the gate before the track is re-acquired",
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
    from data_contracts import MODAL, POLES, read_table

    from .pipeline import run_forecast

    options = ("A", "B") if args.option == "AB" else (args.option,)
    if "B" in options and args.poles is None:
        raise UsageError("option B needs --poles (the stabilisation diagrams)")
    if args.train < 2:
        raise UsageError(f"--train must be at least 2 blocks, got {args.train}")
    trust = _parse_trust(args.trust)
    modal = read_table(args.modal, MODAL)
    predictors = _predictors_for(args, modal)
    poles = read_table(args.poles, POLES) if args.poles is not None else None
    truth = read_table(args.truth, MODAL) if args.truth is not None else None
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
            figures=args.figures,
            truth=truth,
            n_jobs=args.jobs,
            progress=not args.quiet,
            min_presence=args.min_presence,
            option_b={
                "shape_mac_min": args.shape_mac_min,
                "reacquire_blocks": args.reacquire_blocks,
            },
        )
    _print_result(result)
    return EXIT_OK


def _add_evaluate(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "evaluate",
        help="compare SSI, model and Kalman estimates with a true modal table",
        description="Cumulative absolute error per mode of the SSI-only, model-only and "
        "Kalman estimates of a forecast table against the truth (e.g. of the demo voyage), "
        "and the improvement in %%.",
    )
    parser.add_argument("--forecast", type=Path, required=True, metavar="FILE")
    parser.add_argument(
        "--truth", type=Path, required=True, metavar="FILE", help="true modal table"
    )
    parser.add_argument("--phase", choices=("forecast", "train", "all"), default="forecast")
    parser.add_argument("--out", type=Path, metavar="FILE", help="write the table as CSV")
    parser.set_defaults(run=_run_evaluate)


def _run_evaluate(args: argparse.Namespace) -> int:
    from data_contracts import FORECAST, MODAL, read_table

    from .pipeline import evaluate_forecast

    forecast = read_table(args.forecast, FORECAST)
    truth = read_table(args.truth, MODAL)
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


#: Subcommands in the order ``--help`` lists them.
COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_demo,
    _add_simulate,
    _add_identify,
    _add_track,
    _add_correlate,
    _add_fit,
    _add_forecast,
    _add_evaluate,
    _add_validate,
)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line, ``warning: ...``, without source location (unless --verbose)."""
    print(f"warning: {message}", file=sys.stderr if file is None else file)


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
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI with *argv* (default ``sys.argv[1:]``) and return the exit status."""
    parser = build_parser()
    try:
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


def _run(args: argparse.Namespace) -> int:
    """Run the chosen command; user errors become messages and exit statuses."""
    try:
        return int(args.run(args) or EXIT_OK)
    except ContractError as error:
        if args.verbose:
            raise
        for line in error.lines():
            print(line, file=sys.stderr)
        return EXIT_DATA
    except WorkbenchError as error:
        if args.verbose:
            raise
        print(f"error: {error}", file=sys.stderr)
        return EXIT_DATA
    except UsageError as error:
        print(f"workbench: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
