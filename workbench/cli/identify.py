"""``workbench identify`` and the identification options it shares with ``monitor``
(:func:`identify_options`)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from .. import defaults as D
from ..errors import printable
from ..inputs import (
    acceleration_layout,
    add_acceleration_layout,
    add_dship_columns,
    dship_mapping,
    dship_utc_offset,
)
from .common import EXIT_OK, UsageError, _add_parallel, _check_positive, _option_names


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
        "the modes of both per block (crosscheck.csv, agreement in the summary); the "
        "selected modes then carry the combined estimate and its uncertainty "
        "(combined_* columns, the forecast's per-block measurement noise)",
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
    parser.add_argument(
        "--reference-channels",
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
        default=None,
        metavar="MIN|auto",
        help=f"block length [min] (default: {D.BLOCK_MINUTES:g}); a length below the default "
        "step needs --step-minutes too. 'auto': each block's length from the conditions, "
        "5-35 min (odd multiples of the step, centred in the middle of a step), the longest "
        "over which the excitation (within 3 dB), the ship's speed (within 1 kn, with "
        "--dship) and the state (--cases) stay steady; tables carry block_length_s and "
        "excitation_range_db",
    )
    parser.add_argument(
        "--cases",
        type=Path,
        default=None,
        metavar="FILE",
        help="with --block-minutes auto: the voyage's states (CSV with case, start, end: "
        "ice, transit, station, ...); a block does not straddle a change of state",
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
    parser.add_argument(
        "--stabilisation-figures",
        type=int,
        default=D.IDENTIFY_STABILISATION_FIGURES,
        metavar="K",
        help="stabilisation diagrams of K blocks spread over the voyage",
    )
    add_acceleration_layout(parser)
    harmonic = parser.add_argument_group(
        "shaft harmonics",
        "With the voyage's ship log, the shaft orders and the blade pass are marked among "
        "the selected modes and poles (column 'harmonic') and kept out of tracking: from the "
        "logged shaft speed, or, without it, from modes whose frequency follows the speed "
        "with a fixed shape.",
    )
    harmonic.add_argument(
        "--dship", type=Path, metavar="FILE", help="the voyage's ship log (DSHIP export)"
    )
    add_dship_columns(harmonic)
    harmonic.add_argument(
        "--harmonic-orders",
        default=D.IDENTIFY_HARMONIC_ORDERS,
        metavar="K,K",
        help="shaft orders checked (default: %(default)s)",
    )
    harmonic.add_argument(
        "--blades",
        type=int,
        default=D.IDENTIFY_BLADES,
        metavar="N",
        help="propeller blades: the blade pass N x the shaft rate (and 2N) is checked too; "
        "0: none (default: %(default)s)",
    )
    parser.add_argument(
        "--tpe-figures",
        type=int,
        default=D.IDENTIFY_TPE_FIGURES,
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
    parser.add_argument(
        "--keep-removed-inputs",
        action="store_true",
        help="an input file the store's results came from is no longer given: keep the "
        "blocks computed from it (default: drop them, so the rerun equals a fresh run over "
        "the files given); either way each such file is named",
    )
    _add_parallel(parser)
    parser.set_defaults(run=_run_identify)


def _block_minutes(value):
    """``--block-minutes``: None, a positive number of minutes or ``"auto"``.

    Raises
    ------
    UsageError
        For anything else (exit 2, one line).
    """
    if value is None or isinstance(value, int | float):
        return value
    text = str(value)
    if text.strip().lower() == "auto":
        return "auto"
    try:
        minutes = float(text)
    except ValueError:
        raise UsageError(f"--block-minutes {text!r} is not a number of minutes or 'auto'") from None
    if not (math.isfinite(minutes) and minutes > 0):
        raise UsageError(f"--block-minutes {text} must be a positive number of minutes or 'auto'")
    return minutes


def adaptive_options(args: argparse.Namespace):
    """The :class:`~workbench.identification.AdaptiveBlockOptions` of ``--block-minutes
    auto`` (with ``--step-minutes``), or None for a fixed length.

    Raises
    ------
    UsageError
        For limits that do not fit the step (exit 2).
    """
    from ..errors import OptionError
    from ..identification import AdaptiveBlockOptions

    if _block_minutes(getattr(args, "block_minutes", None)) != "auto":
        if getattr(args, "cases", None) is not None:
            raise UsageError("--cases is used with --block-minutes auto only")
        return None
    defaults = AdaptiveBlockOptions()
    step_s = defaults.step_s if args.step_minutes is None else 60.0 * args.step_minutes
    try:
        return AdaptiveBlockOptions(min_length_s=max(defaults.min_length_s, step_s), step_s=step_s)
    except OptionError as error:
        raise UsageError(f"--block-minutes auto with --step-minutes: {error}") from None


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
    """The :class:`~workbench.identification.IdentifyOptions` that parsed identification flags
    describe (``identify`` and ``monitor``); options a command lacks take their defaults.

    Raises
    ------
    UsageError
        For contradicting or impossible flags (exit 2).
    """
    from data_contracts.limits import MAX_LSCF_ORDER, MAX_MODEL_ORDER

    from ..blocks import DEFAULT_BLOCK_LENGTH_S, DEFAULT_BLOCK_STEP_S, MAX_BLOCKS_PER_SAMPLE
    from ..identification import IdentifyOptions

    def flag(name: str, default):
        value = getattr(args, name, None)
        return default if value is None else value

    lscf_max_order = flag("lscf_max_order", D.IDENTIFY_LSCF_MAX_ORDER)
    if args.min_order < 1 or args.max_order < args.min_order:
        raise UsageError(f"model orders {args.min_order}..{args.max_order} make no sense")
    if lscf_max_order < 1:
        raise UsageError(f"--lscf-max-order must be at least 1, got {lscf_max_order}")
    # ranges are checked before the order tuples are built from them
    if args.max_order > MAX_MODEL_ORDER:
        raise UsageError(
            f"--max-order {args.max_order} is above the highest order {MAX_MODEL_ORDER}"
        )
    if lscf_max_order > MAX_LSCF_ORDER:
        raise UsageError(
            f"--lscf-max-order {lscf_max_order} is above the highest order {MAX_LSCF_ORDER}"
        )
    if args.no_band and args.band is not None:
        raise UsageError("--band and --no-band contradict each other")
    minutes = _block_minutes(args.block_minutes)
    step_s = DEFAULT_BLOCK_STEP_S if args.step_minutes is None else 60.0 * args.step_minutes
    if minutes == "auto":  # the lengths are the adaptive options' (adaptive_options)
        length_s = step_s
    else:
        length_s = DEFAULT_BLOCK_LENGTH_S if minutes is None else 60.0 * minutes
    if not (length_s > 0 and step_s > 0):
        raise UsageError("--block-minutes and --step-minutes must be positive")
    if step_s > length_s:
        given = "--block-minutes" if args.step_minutes is None else "--step-minutes"
        raise UsageError(
            f"{given}: step {step_s / 60:g} min is longer than the block "
            f"{length_s / 60:g} min; give --step-minutes at most --block-minutes"
        )
    if length_s > MAX_BLOCKS_PER_SAMPLE * step_s:  # before any block is listed
        raise UsageError(
            f"--step-minutes {step_s / 60:g} puts every sample in {length_s / step_s:.3g} "
            f"blocks of {length_s / 60:g} min; at most {MAX_BLOCKS_PER_SAMPLE}: give "
            f"--step-minutes of at least {length_s / 60 / MAX_BLOCKS_PER_SAMPLE:g} "
            f"(--block-minutes / {MAX_BLOCKS_PER_SAMPLE})"
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
                (
                    "kurtosis_limits",
                    (D.IDENTIFY_KURTOSIS_MIN, flag("kurtosis_max", D.IDENTIFY_KURTOSIS_MAX)),
                ),
                ("max_variance_z", flag("variance_z_max", D.IDENTIFY_VARIANCE_Z_MAX)),
                ("max_kurtosis_z", flag("kurtosis_z_max", D.IDENTIFY_KURTOSIS_Z_MAX)),
                ("max_nan_fraction", flag("max_nan_fraction", D.IDENTIFY_MAX_NAN_FRACTION)),
            ),
            conditioning=args.conditioning,
        )
    except ValueError as error:
        raise UsageError(_option_names(str(error))) from None


def harmonic_options(args: argparse.Namespace):
    """The :class:`~workbench.sid.harmonics.HarmonicOptions` of ``--harmonic-orders`` and
    ``--blades``."""
    from ..sid.harmonics import HarmonicOptions

    try:
        orders = tuple(float(k) for k in str(args.harmonic_orders).split(",") if k.strip())
        return HarmonicOptions(orders=orders, blades=args.blades)
    except ValueError as error:
        raise UsageError(f"--harmonic-orders/--blades: {error}") from None


def _run_identify(args: argparse.Namespace) -> int:
    from ..identification import IdentifyOptionsError
    from ..stages import identify

    options = identify_options(args)
    adaptive = adaptive_options(args)
    _check_positive(workers=args.workers, batch_blocks=args.batch_blocks)
    if args.stabilisation_figures < 0:
        raise UsageError(
            f"--stabilisation-figures must be 0 or more, got {args.stabilisation_figures}"
        )
    harmonics = harmonic_options(args)
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
            keep_removed_inputs=args.keep_removed_inputs,
            dship=args.dship,
            dship_mapping=dship_mapping(args),
            dship_utc_offset=dship_utc_offset(args),
            harmonics=harmonics,
            adaptive=adaptive,
            cases=args.cases,
        )
    except IdentifyOptionsError as error:
        raise UsageError(str(error)) from None
    for notice in result.warnings:  # what the store found changed, and what was done
        print(f"warning: {printable(notice)}", file=sys.stderr)
    for line in result.lines:
        print(printable(line))
    if args.stabilisation_figures:
        from ..identification import write_block_figures

        for path in write_block_figures(
            args.inputs,
            args.out / "figures",
            options=options,
            n_blocks=args.stabilisation_figures,
        ):
            print(f"figure: {path}")
    if args.tpe_figures > 0:
        from ..identification import write_tpe_figures

        for path in write_tpe_figures(
            args.inputs, args.out / "figures", options=options, n_blocks=args.tpe_figures
        ):
            print(f"figure: {path}")
    return EXIT_OK
