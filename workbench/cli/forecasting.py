"""``workbench forecast``, ``evaluate`` and ``health``: the sliding forecast blended with
SSI, its errors against a truth, and the structural-health chart of its residuals."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from .. import defaults as D
from ..arguments import choice
from ..errors import WorkbenchError
from ..inputs import add_modal_layout
from .common import (
    EXIT_OK,
    UsageError,
    _add_min_presence,
    _add_modal_and_predictors,
    _add_out_dir,
    _cases_argument,
    _check_hours_flags,
    _check_joins,
    _check_positive,
    _check_share,
    _check_table_path,
    _data_errors,
    _modal_and_predictors,
    _predictor_source,
    _print_result,
    _read_modal,
)

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
    _add_modal_and_predictors(parser)
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
    parser.add_argument(
        "--scheme",
        type=FORECAST_SCHEMES,
        metavar=FORECAST_SCHEMES.metavar,
        default=D.FORECAST_SCHEME,
        help="single-window (alias 1): one training window, one long forecast; rolling "
        "(alias 2): predict H blocks, filter them, slide the window, refit",
    )
    parser.add_argument(
        "--train-blocks",
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
    parser.add_argument(
        "--workers",
        type=int,
        default=D.FORECAST_WORKERS,
        metavar="N",
        help="worker processes to spread the modes over (for voyage-length tables)",
    )
    _add_min_presence(parser, "forecast only modes measured in at least this share of the blocks")
    parser.add_argument(
        "--mac-min",
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
        "re-acquired (--model window) or the column there is measured, Huber-weighted "
        "(--model memory) (default: "
        + ", ".join(f"{k} for --model {m}" for m, k in D.FORECAST_REACQUIRE_BLOCKS.items())
        + ")",
    )
    parser.add_argument(
        "--extrapolation-sensitivity",
        default=None,
        metavar="COLUMN=RHO,...",
        help="--model memory: prior relative frequency change of a mode per unit of a "
        "predictor beyond the range the model was fitted on; widens the band where a mode "
        "is not measured (a hole in the record), the estimate unchanged (default: "
        + ",".join(f"{k}={v:g}" for k, v in D.FORECAST_EXTRAPOLATION_SENSITIVITY.items())
        + "; 'none': no prior)",
    )
    parser.set_defaults(run=_run_forecast)


def _parse_sensitivity(text: str | None) -> dict[str, float] | None:
    """``--extrapolation-sensitivity``: None (the default), {} for 'none', else the pairs."""
    if text is None:
        return None
    if text.strip().lower() == "none":
        return {}
    pairs = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        try:
            rho = float(value)
        except ValueError:
            rho = math.nan
        if not sep or not name.strip() or not (math.isfinite(rho) and rho >= 0.0):
            raise UsageError(
                f"--extrapolation-sensitivity takes COLUMN=RHO pairs, RHO >= 0 (or 'none'), "
                f"got {item!r}"
            )
        pairs[name.strip()] = rho
    return pairs


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


def check_forecast_flags(args: argparse.Namespace) -> float | None | str:
    """Check the forecast flags ``forecast`` and ``monitor`` share (one rule for both);
    return ``--trust`` parsed (``"auto"`` when not given).

    Raises
    ------
    UsageError
        Naming the flag (exit 2).
    """
    from ..forecasting.options import MIN_TRAIN_BLOCKS

    if args.train_blocks < MIN_TRAIN_BLOCKS:
        raise UsageError(
            f"--train-blocks must be at least {MIN_TRAIN_BLOCKS} (the fewest blocks a model is "
            f"fitted on), got {args.train_blocks}"
        )
    if args.trust is not None and args.model != "window":
        raise UsageError(
            f"--trust {args.trust} applies to --model window; --model {args.model} takes its "
            "noise levels from the data"
        )
    _check_positive(horizon=args.horizon, reacquire_blocks=args.reacquire_blocks)
    _check_share("min-presence", args.min_presence)
    _check_share("mac-min", args.mac_min)
    _parse_sensitivity(getattr(args, "extrapolation_sensitivity", None))
    return "auto" if args.trust is None else _parse_trust(str(args.trust))


def forecast_options(args: argparse.Namespace, trust, **more):
    """The one :class:`~workbench.forecasting.options.ForecastOptions` of parsed forecast
    flags, for ``workbench forecast`` and ``workbench monitor`` alike (*trust* as
    :func:`check_forecast_flags` returns it; a configuration file gives names or letters)."""
    from ..forecasting.options import ForecastOptions

    option = FORECAST_OPTIONS(str(args.option))
    return ForecastOptions(
        options=("A", "B") if option == "AB" else (option,),
        scheme=FORECAST_SCHEMES(str(args.scheme)),
        train_blocks=args.train_blocks,
        horizon=args.horizon,
        trust=trust,
        model=args.model,
        min_presence=args.min_presence,
        mac_min=args.mac_min,
        **({} if args.reacquire_blocks is None else {"reacquire_blocks": args.reacquire_blocks}),
        extrapolation_sensitivity=_parse_sensitivity(
            getattr(args, "extrapolation_sensitivity", None)
        ),
        **more,
    )


def _run_forecast(args: argparse.Namespace) -> int:
    from data_contracts import POLES, read_table

    from ..stages import forecast

    options = ("A", "B") if args.option == "AB" else (args.option,)
    if "B" in options and args.poles is None:
        raise UsageError("--option pole-cluster (B) needs --poles (the stabilisation diagrams)")
    trust = check_forecast_flags(args)
    _check_positive(workers=args.workers)
    _check_table_path(args.out)
    modal, predictors = _modal_and_predictors(args)
    poles = read_table(args.poles, POLES) if args.poles is not None else None
    truth = _read_modal(args, args.truth) if args.truth is not None else None
    _check_joins(args, modal, None, poles)
    stage_options = forecast_options(args, trust, n_workers=args.workers)
    train = {"train_blocks": f"--train-blocks {args.train_blocks}"}
    with _data_errors(args.modal, predictors=_predictor_source(args), flags=train):
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

    from ..forecasting.evaluate import SUMMARY_COLUMNS
    from ..joins import check_block_times
    from ..stages import evaluate

    if args.out is not None:
        _check_table_path(args.out)
    forecast = _read_modal(args, args.forecast, FORECAST)
    truth = _read_modal(args, args.truth)
    check_block_times(forecast, args.forecast, truth, args.truth)
    with _data_errors(args.forecast):
        result = evaluate(forecast, truth, phase=None if args.phase == "all" else args.phase)
    paths = result.save(args.out) if args.out is not None else {}
    print(result.table[SUMMARY_COLUMNS].to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    _print_result(result, paths)
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
        "--statistic",
        choices=("cusum", "mewma"),
        default=D.HEALTH_STATISTIC,
        help="per-mode one-sided CUSUM (for a drop of one mode) or MEWMA Hotelling T²",
    )
    parser.add_argument(
        "--ewma-lambda",
        type=float,
        default=D.HEALTH_EWMA_LAMBDA,
        help="weight of the newest block in the MEWMA statistic",
    )
    parser.add_argument(
        "--baseline-hours",
        type=float,
        metavar="H",
        help="let each mode's in-control level follow the residuals with this time "
        "constant, for a drift no logged predictor explains (fuel burn without tank "
        "soundings); default: the reference's level, fixed",
    )
    parser.add_argument(
        "--false-alarms-per-day",
        type=float,
        default=D.HEALTH_FALSE_ALARMS_PER_DAY,
        help="expected false alarms per day in control (sets the limit)",
    )
    parser.add_argument(
        "--save-model",
        type=Path,
        metavar="FILE",
        help="with --modal --predictors --train-hours: write the operational model, the "
        "chart's reference and limits and the tracked modes to FILE (JSON), the baseline a "
        "later voyage of the ship is charted with from its first block (--baseline)",
    )
    parser.add_argument(
        "--baseline",
        type=Path,
        metavar="FILE",
        help="with --modal --predictors: chart every block, from the first, with the model "
        "and limits of an earlier voyage (written by --save-model; its chart options are "
        "used, not --statistic, --ewma-lambda, --false-alarms-per-day, --reference-hours); "
        "the modal table should be tracked from its modes (track --reference-modes FILE)",
    )
    _add_out_dir(parser)
    parser.set_defaults(run=_run_health)


def _block_step_s(table, path) -> float:
    """Block step of *table* (read from *path*): its recorded grid, else the median step of
    its blocks; a table of one block without a recorded grid has none (exit 1)."""
    from data_contracts import recorded_grid

    grid = recorded_grid(table)
    if grid is not None:
        return float(grid["step_s"])
    starts = table["block_start"].drop_duplicates().sort_values()
    if len(starts) < 2:
        raise WorkbenchError(
            f"{path}: the table holds one block only and records no block grid: no block "
            "step to turn hours into blocks"
        )
    return float(starts.diff().median().total_seconds())


def _run_health(args: argparse.Namespace) -> int:
    from data_contracts import FORECAST, PREDICTORS

    from ..shm import BaselineError, HealthBaseline, HealthOptions, fit_operational_model
    from ..shm.model import MIN_TRAIN_BLOCKS
    from ..stages import health

    if args.baseline is not None:
        return _run_health_baseline(args)
    _check_hours_flags(train_hours=args.train_hours, reference_hours=args.reference_hours)
    source = args.forecast
    model = modal = predictors = None
    if args.save_model is not None and (args.modal is None or args.train_hours is None):
        raise UsageError("--save-model needs --modal, --predictors and --train-hours")
    if args.modal is not None:
        if args.predictors is None or args.train_hours is None:
            raise UsageError("--modal needs --predictors and --train-hours")
        source = args.modal
        # as forecast reads it: rows without a frequency (an SSI outage) dropped, warned
        modal = _read_modal(args, args.modal)
        predictors = _read_modal(args, args.predictors, PREDICTORS)
        _check_joins(args, modal, predictors)  # the same blocks, as forecast checks
        step_s = _block_step_s(predictors, args.predictors)
        train = int(round(args.train_hours * 3600 / step_s))
        if train < MIN_TRAIN_BLOCKS:
            raise UsageError(
                f"--train-hours {args.train_hours:g} gives {train} block(s) of "
                f"{step_s / 60:g} min; the operational model needs at least "
                f"{MIN_TRAIN_BLOCKS} ({MIN_TRAIN_BLOCKS * step_s / 3600:g} h)"
            )
        reference = int(round(args.reference_hours * 3600 / step_s))
        first = int(predictors["block"].min())
        if args.reference_start_block is None:
            args.reference_start_block = first + train
        flags = {
            "train_blocks": f"--train-hours {args.train_hours:g}: {train} blocks",
            "reference_start_block": f"--reference-start-block {args.reference_start_block}",
        }
        with _data_errors(args.modal, predictors=args.predictors, flags=flags):
            model = fit_operational_model(
                modal, predictors, train_start_block=first, train_blocks=train
            )
            forecast = model.forecast(
                modal,
                predictors,
                reference_start_block=args.reference_start_block,
                reference_blocks=reference,
            )
    else:
        forecast = _read_modal(args, args.forecast, FORECAST)
    blocks = int(round(args.reference_hours * 3600 / _block_step_s(forecast, source)))
    try:
        options = HealthOptions(
            reference_blocks=blocks,
            reference_start_block=args.reference_start_block,
            ewma_lambda=args.ewma_lambda,
            false_alarms_per_day=args.false_alarms_per_day,
            statistic=args.statistic,
            baseline_hours=args.baseline_hours,
        )
    except ValueError as error:
        # "ewma_lambda=2.0 must be ..." names the flag: "--ewma-lambda 2.0 must be ..."
        name, equals, rest = str(error).partition("=")
        message = f"--{name.replace('_', '-')} {rest}" if equals and name.isidentifier() else ""
        raise UsageError(message or str(error)) from None
    with _data_errors(source):
        result = health(forecast, options=options)
    paths = result.save(args.out)
    if args.save_model is not None:
        from data_contracts import recorded_grid

        grid = recorded_grid(modal) or recorded_grid(predictors) or {}
        try:
            baseline = HealthBaseline.from_chart(
                modal,
                predictors,
                model,
                result,
                step_s=_block_step_s(predictors, args.predictors),
                length_s=grid.get("length_s"),
                source={"modal": str(args.modal), "predictors": str(args.predictors)},
            )
            paths["baseline"] = baseline.save(args.save_model)
        except (BaselineError, ValueError) as error:
            raise WorkbenchError(f"{args.save_model}: {error}") from None
    print(result.summary())
    for path in paths.values():
        print(f"wrote {path}")
    return EXIT_OK


def _run_health_baseline(args: argparse.Namespace) -> int:
    """``health --baseline FILE --modal --predictors``: the chart with an earlier voyage's
    model and limits, from the first block."""
    from data_contracts import MODAL, PREDICTORS

    from ..shm import BaselineError, HealthBaseline
    from ..stages import health

    if args.modal is None or args.predictors is None:
        raise UsageError("--baseline needs --modal and --predictors (not --forecast)")
    for flag, value in (
        ("--train-hours", args.train_hours),
        ("--reference-start-block", args.reference_start_block),
        ("--save-model", args.save_model),
        ("--baseline-hours", args.baseline_hours),
    ):
        if value is not None:
            raise UsageError(f"{flag} cannot be used with --baseline (the baseline fixes it)")
    try:
        baseline = HealthBaseline.load(args.baseline)
    except BaselineError as error:
        raise WorkbenchError(str(error)) from None
    modal = _read_modal(args, args.modal, MODAL)
    predictors = _read_modal(args, args.predictors, PREDICTORS)
    try:
        channels = [c[len("shape_re_") :] for c in modal.columns if c.startswith("shape_re_")]
        baseline.check_channels(channels, str(args.modal))
        baseline.check_predictors(predictors, str(args.predictors))
        baseline.check_modes(modal, str(args.modal))
    except BaselineError as error:
        raise WorkbenchError(str(error)) from None
    with _data_errors(args.modal, predictors=args.predictors):
        forecast = baseline.forecast(modal, predictors)
        result = health(forecast, baseline=baseline)
    paths = result.save(args.out)
    print(
        f"baseline {args.baseline}: model of blocks {baseline.model.train_start_block}-"
        f"{baseline.model.train_end_block} of {baseline.source.get('modal', 'an earlier voyage')}"
        f"; charting from block {int(result.table['block'].min())}"
    )
    print(result.summary())
    for path in paths.values():
        print(f"wrote {path}")
    return EXIT_OK
