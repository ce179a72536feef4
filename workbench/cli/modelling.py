"""``workbench track``, ``correlate`` and ``fit``: modes followed through the voyage,
their correlation with the predictors and a stepwise model per mode."""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import defaults as D
from .common import (
    EXIT_OK,
    UsageError,
    _add_min_presence,
    _add_modal_and_predictors,
    _add_out_dir,
    _cases_argument,
    _check_share,
    _check_table_path,
    _data_errors,
    _modal_and_predictors,
    _option_names,
    _predictor_source,
    _print_result,
)


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
        "--reference-modes",
        type=Path,
        metavar="FILE",
        help="modal table whose modes start the tracker's library (labels kept), or a "
        "health baseline (.json, health --save-model): its modes",
    )
    parser.add_argument(
        "--mac-min",
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
    parser.add_argument(
        "--frequency-tol",
        type=float,
        default=D.TRACK_FREQUENCY_TOL,
        metavar="REL",
        help="largest relative frequency difference to join a mode",
    )
    parser.set_defaults(run=_run_track)


def _run_track(args: argparse.Namespace) -> int:
    from ..stages import TrackingOptions, track

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
    _add_modal_and_predictors(parser)
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
    _add_min_presence(parser)
    _add_out_dir(parser)
    parser.set_defaults(run=_run_correlate)


def _run_correlate(args: argparse.Namespace) -> int:
    from ..stages import CorrelateOptions, correlate

    if not 0.0 < args.alpha < 1.0:
        raise UsageError(f"--alpha must be in (0, 1), got {args.alpha}")
    _check_share("min-presence", args.min_presence)
    options = CorrelateOptions(
        alpha=args.alpha,
        correction=None if args.correction == "none" else args.correction,
        min_presence=args.min_presence,
    )
    modal, predictors = _modal_and_predictors(args)
    with _data_errors(args.modal, predictors=_predictor_source(args)):
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
    _add_modal_and_predictors(parser)
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
    _add_min_presence(parser)
    _add_out_dir(parser)
    parser.set_defaults(run=_run_fit)


def _run_fit(args: argparse.Namespace) -> int:
    from ..stages import FitOptions, fit

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
    with _data_errors(args.modal, predictors=_predictor_source(args)):
        result = fit(modal, predictors, cases=_cases_argument(args.cases), options=options)
        paths = result.save(args.out)
    _print_result(result, paths)
    return EXIT_OK


def _check_upper(upper: str, predictors) -> None:
    """A usage error for an --upper model that names no predictor or is not a model."""
    from data_contracts import PREDICTOR_KEYS

    from ..predictors.directions import model_columns
    from ..stats.terms import parse_terms

    # a direction enters the models as its cosine (wind_dir_rel_cos)
    names = model_columns([c for c in predictors.columns if c not in PREDICTOR_KEYS])
    try:
        parse_terms(upper, names, parameter="--upper")
    except (ValueError, TypeError) as error:
        raise UsageError(str(error).splitlines()[0]) from None
