"""``workbench monitor``: arguments and the run (the CLI's part of :mod:`workbench.monitor`).

Settings come from flags, or from ``--config ship.toml`` (its ``[accelerations] inputs``,
``[dship]``, ``[blocks]``, ``[identify]``, ``[track]`` and ``[forecast]`` sections, read as
the batch commands read them); flags win.
"""

from __future__ import annotations

import argparse
import signal
from pathlib import Path

from .. import defaults as D
from ..forecasting.options import DEFAULT_MODEL

__all__ = ["add_monitor", "prepare_monitor", "run_monitor"]

# dest -> default, applied after the configuration file (flags default to None so that
# the file's values are used when a flag is not given)
_DEFAULTS = {
    "method": "cov",
    "block_rows": 20,
    "min_order": 4,
    "max_order": 60,
    "weighting": "pc",
    "rate": "auto",
    "no_band": False,
    "max_gap": 0.0,
    "selection": "cluster",
    "conditioning": "per-file",
    "harmonic_orders": D.IDENTIFY_HARMONIC_ORDERS,
    "blades": D.IDENTIFY_BLADES,
    "mac_min": 0.9,
    "gate": "mac",
    "frequency_tol": 0.05,
    "option": "A",
    "scheme": 2,
    "train_blocks": 20,
    "model": DEFAULT_MODEL,
    "min_presence": 0.5,
    "reference_hours": 6.0,
    "ewma_lambda": 0.1,
    "false_alarms_per_day": 0.1,
    "health_model": "operational",
    "health_train_hours": 12.0,
    "baseline_hours": 24.0,
    "poll": 1.0,
    "settle": 1.0,
    "late": 900.0,
    "flush_after": 900.0,
    "on_alarm_timeout": 30.0,
}


def add_monitor(commands: argparse._SubParsersAction) -> None:
    """Add the ``monitor`` subcommand."""
    from ..arguments import add_renamed
    from ..cli import FORECAST_OPTIONS, FORECAST_SCHEMES
    from ..inputs import add_acceleration_layout

    parser = commands.add_parser(
        "monitor",
        help="follow a folder of acceleration files and the ship log: identify, track, "
        "forecast and chart structural health block by block",
        description="Identify every block as soon as its files are complete, track the "
        "modes, update the forecast and the health chart incrementally, and keep a state "
        "folder (tracked.parquet, forecast.parquet, health.parquet, alarms.parquet, "
        "data_health.parquet, status.json, heartbeat.json) that a dashboard reads, and the "
        "daily key indicators for the shore (shore/key_indicators_DAY.json and .csv). Resumable: stop it "
        "(Ctrl-C, SIGTERM, even kill -9) and start it again, it carries on without losing "
        "or repeating a block. Results equal those of identify + track + forecast over "
        "the same files.",
    )
    parser.add_argument("--watch", type=Path, metavar="DIR", help="folder the files arrive in")
    parser.add_argument("--dship", type=Path, metavar="FILE", help="the ship log (growing)")
    parser.add_argument(
        "--state",
        type=Path,
        metavar="DIR",
        help="state folder (default: OUTPUT/monitor with --config)",
    )
    parser.add_argument(
        "--once",
        action="store_true",
        help="process the files present (as all there will be) and exit",
    )
    parser.add_argument(
        "--poll",
        type=float,
        metavar="S",
        help="seconds between polls and between heartbeats (heartbeat.json; a dashboard "
        "says 'not responding' after two missed) (1)",
    )
    parser.add_argument(
        "--settle",
        type=float,
        metavar="S",
        help="a file is taken once unmodified this long (1 s); hidden temporary files are "
        "never taken",
    )
    parser.add_argument(
        "--late",
        type=float,
        metavar="S",
        help="missing data is waited for until data S seconds newer has landed (900)",
    )
    parser.add_argument(
        "--flush-after",
        type=float,
        metavar="S",
        help="with no new file for S seconds, decide the blocks still waiting (900)",
    )
    parser.add_argument(
        "--foreground",
        action="store_true",
        help="recompute forecast and health in this process (default: a background process)",
    )
    parser.add_argument(
        "--on-alarm",
        metavar="COMMAND",
        help="run COMMAND (split like a shell command line, run without a shell) once per "
        "new alarm episode, the alarm as JSON on its stdin; its failure is reported in the "
        "monitor's messages and the monitor goes on",
    )
    parser.add_argument(
        "--on-alarm-timeout",
        type=float,
        metavar="S",
        help="stop an --on-alarm command after S seconds and report it (30)",
    )
    ident = parser.add_argument_group("identification (as workbench identify)")
    ident.add_argument("--method", choices=("cov", "data", "lscf"))
    ident.add_argument("--block-rows", type=int, metavar="I")
    ident.add_argument("--min-order", type=int, metavar="N")
    ident.add_argument("--max-order", type=int, metavar="N")
    ident.add_argument("--weighting", choices=("pc", "upc", "cva"))
    add_renamed(
        ident,
        "--reference-channels",
        ["--reference"],
        metavar="CH,CH,...",
        help="reference channels",
    )
    ident.add_argument("--rate", metavar="HZ|auto|native", help="analysis rate (auto)")
    ident.add_argument("--band", type=float, nargs=2, metavar=("LOW", "HIGH"))
    ident.add_argument("--no-band", action="store_true", default=None)
    ident.add_argument("--block-minutes", type=float, metavar="MIN")
    ident.add_argument("--step-minutes", type=float, metavar="MIN")
    ident.add_argument("--max-gap", type=float, metavar="S")
    ident.add_argument("--selection", choices=("cluster", "library"))
    ident.add_argument("--no-channel-check", action="store_true", default=None)
    ident.add_argument("--conditioning", choices=("per-file", "per-block"))
    ident.add_argument(
        "--harmonic-orders",
        metavar="K,K",
        help=f"shaft orders kept out of the modes ({D.IDENTIFY_HARMONIC_ORDERS})",
    )
    ident.add_argument(
        "--blades",
        type=int,
        metavar="N",
        help=f"propeller blades: the blade pass N x the shaft rate (and 2N) too; 0: none "
        f"({D.IDENTIFY_BLADES})",
    )
    track = parser.add_argument_group("tracking (as workbench track)")
    add_renamed(
        track,
        "--mac-min",
        ["--threshold", "--shape-mac-min"],
        type=float,
        metavar="MAC",
        help="lowest MAC that joins a mode to a tracked mode, and of an option-B pole with "
        "its mode's shape (0.9)",
    )
    track.add_argument("--gate", choices=("mac", "macxp"))
    add_renamed(track, "--frequency-tol", ["--frequency-tolerance"], type=float)
    # the files are read as identify reads them: the same reader registry and layout flags
    add_acceleration_layout(parser)
    fore = parser.add_argument_group("forecast and health (as workbench forecast / health)")
    fore.add_argument("--option", type=FORECAST_OPTIONS, metavar=FORECAST_OPTIONS.metavar)
    add_renamed(
        fore,
        "--scheme",
        ["--forecast-method"],
        type=FORECAST_SCHEMES,
        metavar=FORECAST_SCHEMES.metavar,
    )
    add_renamed(fore, "--train-blocks", ["--train"], type=int, metavar="N")
    fore.add_argument("--horizon", type=int, metavar="H")
    fore.add_argument("--model", choices=("memory", "window"))
    fore.add_argument("--trust")
    fore.add_argument("--min-presence", type=float, metavar="SHARE")
    fore.add_argument("--reacquire-blocks", type=int, metavar="K")
    fore.add_argument("--all-predictors", action="store_true", default=None)
    fore.add_argument("--reference-hours", type=float, help="health reference period [h] (6)")
    fore.add_argument("--ewma-lambda", type=float)
    fore.add_argument("--false-alarms-per-day", type=float)
    fore.add_argument(
        "--health-model",
        choices=("operational", "forecast"),
        help="chart the residuals of the operational model fitted on the first "
        "--health-train-hours (default) or of the forecast",
    )
    fore.add_argument(
        "--health-train-hours",
        type=float,
        metavar="H",
        help="hours the health chart's operational model is fitted on (12); its reference "
        "period follows",
    )
    fore.add_argument(
        "--baseline",
        type=Path,
        metavar="FILE",
        help="the ship's health baseline from an earlier voyage (workbench health "
        "--save-model): its modes start the tracker (their labels kept) and its model and "
        "limits chart every block from the first; without it the chart starts after "
        "--health-train-hours + --reference-hours (18 h)",
    )
    fore.add_argument(
        "--baseline-hours",
        type=float,
        metavar="H",
        help="without fuel_on_board_t in the ship log: time constant of the health chart's "
        "slowly following baseline (24; 0: fixed)",
    )
    parser.set_defaults(run=run_monitor)


#: The acceleration layout flags (workbench.inputs.add_acceleration_layout): read from the
#: configuration's [times] and [accelerations] sections as identify reads them.
_LAYOUT_DESTS = (
    "time_column",
    "time_format",
    "separator",
    "decimal",
    "start_time",
    "sampling_rate",
    "units",
    "channels",
    "variables",
)


def _from_config(args: argparse.Namespace) -> None:
    """Fill the flags not given from ``--config`` (the batch commands' sections)."""
    from ..config import command_defaults, load_config

    config = load_config(args.config)
    identify = command_defaults("identify", config)
    for dest in (
        "method",
        "block_rows",
        "min_order",
        "max_order",
        "weighting",
        "rate",
        "no_band",
        "band",
        "reference_channels",
        "block_minutes",
        "step_minutes",
        "max_gap",
        *_LAYOUT_DESTS,
        "harmonic_orders",
        "blades",
    ):
        if getattr(args, dest, None) is None and dest in identify:
            setattr(args, dest, identify[dest])
    if args.watch is None and identify.get("inputs"):
        args.watch = Path(identify["inputs"][0])
    track = command_defaults("track", config)
    for dest in ("mac_min", "gate", "frequency_tol"):
        if getattr(args, dest) is None and dest in track:
            setattr(args, dest, track[dest])
    forecast = command_defaults("forecast", config)
    pairs = {
        "option": "option",
        "scheme": "scheme",
        "train_blocks": "train_blocks",
        "horizon": "horizon",
        "min_presence": "min_presence",
        "reacquire_blocks": "reacquire_blocks",
        "trust": "trust",
        "model": "model",
        "dship": "dship",
        "all_predictors": "all_predictors",
    }
    for dest, key in pairs.items():
        if getattr(args, dest) is None and key in forecast:
            setattr(args, dest, forecast[key])
    if config.has("dship", "columns"):
        args.dship_columns = dict(config.get("dship", "columns"))
    if args.state is None:
        args.state = config.out_dir / "monitor"


def _options(args: argparse.Namespace):
    from ..cli import (
        FORECAST_OPTIONS,
        FORECAST_SCHEMES,
        UsageError,
        identify_options,
    )
    from ..cli.forecasting import check_forecast_flags
    from ..cli.identify import _harmonic_options
    from ..sid.tracking import TrackingOptions
    from .core import MonitorOptions
    from .outlook import ForecastSettings
    from .shore import parse_command

    identify = identify_options(args)
    harmonics = _harmonic_options(args)  # as identify --dship marks them
    trust = check_forecast_flags(args)  # what `forecast` refuses, the monitor refuses
    try:
        tracking = TrackingOptions(
            mac_min=args.mac_min, gate=args.gate, frequency_tol=args.frequency_tol
        )
        option = FORECAST_OPTIONS(str(args.option))  # the file may hold names or letters
        options = ("A", "B") if option == "AB" else (option,)
        forecast = ForecastSettings(
            options=options,
            scheme=FORECAST_SCHEMES(str(args.scheme)),
            train_blocks=args.train_blocks,
            horizon=args.horizon,
            trust=trust,
            model=args.model,
            min_presence=args.min_presence,
            mac_min=args.mac_min,
            reacquire_blocks=args.reacquire_blocks,
            all_predictors=bool(args.all_predictors),
            dship_mapping=tuple(dict(getattr(args, "dship_columns", None) or {}).items()),
            reference_hours=args.reference_hours,
            ewma_lambda=args.ewma_lambda,
            false_alarms_per_day=args.false_alarms_per_day,
            health_model=args.health_model,
            health_train_hours=args.health_train_hours,
            baseline_hours=args.baseline_hours or None,
            health_baseline=None if args.baseline is None else str(args.baseline),
        )
        return MonitorOptions(
            identify=identify,
            tracking=tracking,
            harmonics=harmonics,
            forecast=forecast,
            poll_s=args.poll,
            settle_s=args.settle,
            late_s=args.late,
            flush_after_s=args.flush_after,
            background=not (args.foreground or args.once),
            on_alarm=parse_command(args.on_alarm) if args.on_alarm is not None else (),
            on_alarm_timeout_s=args.on_alarm_timeout,
        )
    except (ValueError, argparse.ArgumentTypeError) as error:
        raise UsageError(str(error)) from None


def prepare_monitor(args: argparse.Namespace):
    """The :class:`~workbench.monitor.Monitor` that parsed ``monitor`` arguments describe
    (configuration file and defaults applied)."""
    from ..cli import UsageError
    from .core import Monitor

    if getattr(args, "config", None) is not None:
        _from_config(args)
    for dest, value in _DEFAULTS.items():
        if getattr(args, dest, None) is None:
            setattr(args, dest, value)
    if args.watch is None:
        raise UsageError("monitor needs --watch DIR (or [accelerations] inputs in --config)")
    if args.state is None:
        raise UsageError("monitor needs --state DIR")
    if not args.watch.is_dir():
        raise UsageError(f"--watch {args.watch}: no such folder")
    if args.start_time not in (None, "filename"):
        raise UsageError(
            f"--start-time {args.start_time}: one start time cannot place the files of a "
            "growing folder; give --start-time filename (the time in each file's name) or "
            "files with times of their own"
        )
    return Monitor(args.watch, args.state, dship=args.dship, options=_options(args))


def run_monitor(args: argparse.Namespace) -> int:
    """Run ``workbench monitor``; returns the exit status."""
    monitor = prepare_monitor(args)
    previous = {}

    def stop(signum, frame) -> None:  # noqa: ARG001 - signal handler signature
        monitor.stop_event.set()

    for signum in (signal.SIGINT, signal.SIGTERM):
        previous[signum] = signal.signal(signum, stop)
    try:
        monitor.run(once=args.once)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        monitor.close()
    if args.once and monitor.voyage is None:
        from ..errors import WorkbenchError

        refused = monitor.watcher.refused_reasons
        if refused:  # say why, naming the first file (identify would stop at it too)
            path, reason = next(iter(refused.items()))
            more = f" ({len(refused) - 1} more file(s) refused)" if len(refused) > 1 else ""
            raise WorkbenchError(f"{path}: cannot be monitored: {reason}{more}")
        raise WorkbenchError(f"{args.watch}: no complete acceleration file to monitor")
    through = monitor.tracked_through
    print(
        f"{len(monitor.done)} block(s) decided, tracked up to block "
        f"{through if through >= 0 else '-'}; state in {args.state}"
    )
    for message in monitor.messages[-10:]:
        print(f"note: {message}")
    given_up = monitor.given_up_note()
    if given_up:
        print(f"note: {given_up}")
    return 0
