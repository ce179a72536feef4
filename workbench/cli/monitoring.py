"""``workbench dashboard`` and ``monitor``: the live bridge page and the folder follower.

The monitor's identification, tracking, forecast and health options are those of
``identify``, ``track``, ``forecast`` and ``health``: :func:`_add_monitor` copies their
declarations (:func:`workbench.arguments.copy_flags`), defaults and help included, and
:func:`_monitor_options` reads them into the options objects with the batch commands'
functions (:func:`identify_options`, :func:`check_forecast_flags`). Settings come from
flags, or from ``--config ship.toml`` (the sections the batch commands read:
:func:`workbench.config.command_defaults`); flags win.
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from .. import defaults as D
from ..arguments import copy_flags
from ..errors import WorkbenchError
from ..inputs import (
    add_acceleration_layout,
    add_dship_columns,
    dship_mapping,
    dship_utc_offset,
)
from .common import EXIT_OK, UsageError
from .forecasting import check_forecast_flags, forecast_options
from .identify import adaptive_options, harmonic_options, identify_options


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
        default=D.DASHBOARD_HOST,
        help="interface to listen on (default: %(default)s, this machine only)",
    )
    parser.add_argument(
        "--port", type=int, default=D.DASHBOARD_PORT, help="port (0: any free port)"
    )
    parser.add_argument(
        "--hours", type=float, default=D.DASHBOARD_HOURS, help="tracked-frequency span [h]"
    )
    parser.add_argument(
        "--health-hours", type=float, default=D.DASHBOARD_HEALTH_HOURS, help="health-chart span [h]"
    )
    parser.add_argument(
        "--poll", type=float, default=D.DASHBOARD_POLL_S, help="page checks for changes every [s]"
    )
    parser.add_argument("--option", choices=("A", "B"), help="forecast option on the mode cards")
    parser.set_defaults(run=_run_dashboard)


def _run_dashboard(args: argparse.Namespace) -> int:
    from ..dashboard import DashboardOptions, is_loopback, make_server, serve_until_stopped

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


class _Stopped(BaseException):
    """SIGTERM or SIGHUP (a service manager's stop, the terminal closed) arrived; a
    BaseException like KeyboardInterrupt, so that no ``except Exception`` swallows it."""


def _serve_demo(args: argparse.Namespace, options) -> int:
    """Serve a simulated voyage replayed into a temporary folder, removed on every way
    out: a normal end, an error, Ctrl-C, SIGTERM or SIGHUP (also while the voyage is
    being simulated, before the server's own SIGTERM handling starts)."""
    import signal
    import tempfile
    import threading

    from ..dashboard import DemoReplay

    def stop(signum, frame) -> None:  # noqa: ARG001 - signal handler signature
        raise _Stopped(signal.Signals(signum).name)

    previous = {}
    if threading.current_thread() is threading.main_thread():
        for name in ("SIGTERM", "SIGHUP"):
            if hasattr(signal, name):
                signum = getattr(signal, name)
                previous[signum] = signal.signal(signum, stop)
    try:
        with tempfile.TemporaryDirectory(prefix="workbench-dashboard-demo-") as folder:
            replay = None
            try:
                replay = DemoReplay(folder).start()
                args.state = Path(folder)
                return _run_dashboard(argparse.Namespace(**{**vars(args), "demo": False}))
            finally:
                if replay is not None:
                    replay.stop()  # no file written while the folder is removed
    except _Stopped:
        return EXIT_OK
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


#: The options ``monitor`` takes over from the batch commands, by destination (each
#: declared once, in the command named; copied in its order, defaults and help included).
MONITOR_IDENTIFY_FLAGS = (
    "method",
    "lscf_max_order",
    "block_rows",
    "max_order",
    "min_order",
    "weighting",
    "reference_channels",
    "rate",
    "band",
    "no_band",
    "block_minutes",
    "cases",
    "step_minutes",
    "selection",
    "no_channel_check",
    "kurtosis_max",
    "kurtosis_z_max",
    "variance_z_max",
    "max_nan_fraction",
    "conditioning",
    "max_gap",
    "harmonic_orders",
    "blades",
)
MONITOR_TRACK_FLAGS = ("mac_min", "gate", "frequency_tol")
MONITOR_FORECAST_FLAGS = (
    "option",
    "scheme",
    "train_blocks",
    "horizon",
    "model",
    "trust",
    "min_presence",
    "reacquire_blocks",
    "all_predictors",
    "extrapolation_sensitivity",
)
MONITOR_HEALTH_FLAGS = ("reference_hours", "ewma_lambda", "false_alarms_per_day")


def _add_monitor(commands: argparse._SubParsersAction) -> None:
    """Add the ``monitor`` subcommand (after ``identify``, ``track``, ``forecast`` and
    ``health``, whose options it copies)."""
    batch = commands.choices
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
    add_dship_columns(parser)
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
        default=D.MONITOR_POLL_S,
        metavar="S",
        help="seconds between polls and between heartbeats (heartbeat.json; a dashboard "
        "says 'not responding' after two missed)",
    )
    parser.add_argument(
        "--settle",
        type=float,
        default=D.MONITOR_SETTLE_S,
        metavar="S",
        help="a file is taken once unmodified for S seconds; hidden temporary files are "
        "never taken",
    )
    parser.add_argument(
        "--late",
        type=float,
        default=D.MONITOR_LATE_S,
        metavar="S",
        help="missing data is waited for until data S seconds newer has landed",
    )
    parser.add_argument(
        "--flush-after",
        type=float,
        default=D.MONITOR_FLUSH_AFTER_S,
        metavar="S",
        help="with no new file for S seconds, decide the blocks still waiting",
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
        default=D.MONITOR_ON_ALARM_TIMEOUT_S,
        metavar="S",
        help="stop an --on-alarm command after S seconds and report it",
    )
    identification = parser.add_argument_group("identification (as workbench identify)")
    copy_flags(
        batch["identify"],
        identification,
        MONITOR_IDENTIFY_FLAGS,
        help={
            "block_minutes": f"block length [min] (default: {D.BLOCK_MINUTES:g}); a length "
            "below the default step needs --step-minutes too. 'auto': each block's length "
            "as identify --block-minutes auto decides it (5-35 min, the longest over which "
            "excitation, speed and state stay steady), decided once the data up to its "
            "longest span's end (17.5 min past its centre with the default step) and the ship log over it have "
            "landed (a log behind is waited for --late seconds of data); at the end of the "
            "input the last blocks take the lengths that fit the data present",
            "cases": "with --block-minutes auto: the voyage's states (CSV with case, start, "
            "end: ice, transit, station, ...), read again when it changes; a block does not "
            "straddle a change of state",
        },
    )
    tracking = parser.add_argument_group("tracking (as workbench track)")
    copy_flags(
        batch["track"],
        tracking,
        MONITOR_TRACK_FLAGS,
        help={
            "mac_min": "lowest MAC (or MACXP with --gate macxp) to join a mode, and of an "
            "option-B pole's shape with its mode's (forecast --mac-min)"
        },
    )
    # the files are read as identify reads them: the same reader registry and layout flags
    add_acceleration_layout(parser)
    forecast = parser.add_argument_group("forecast and health (as workbench forecast / health)")
    copy_flags(batch["forecast"], forecast, MONITOR_FORECAST_FLAGS)
    copy_flags(batch["health"], forecast, MONITOR_HEALTH_FLAGS)
    forecast.add_argument(
        "--health-model",
        choices=("operational", "forecast"),
        default=D.MONITOR_HEALTH_MODEL,
        help="chart the residuals of the operational model fitted on the first "
        "--health-train-hours, or of the forecast",
    )
    forecast.add_argument(
        "--health-train-hours",
        type=float,
        default=D.MONITOR_HEALTH_TRAIN_HOURS,
        metavar="H",
        help="hours the health chart's operational model is fitted on; its reference "
        "period follows",
    )
    forecast.add_argument(
        "--baseline",
        type=Path,
        metavar="FILE",
        help="the ship's health baseline from an earlier voyage (workbench health "
        "--save-model): its modes start the tracker (their labels kept) and its model and "
        "limits chart every block from the first; without it the chart starts after "
        "--health-train-hours + --reference-hours",
    )
    forecast.add_argument(
        "--baseline-hours",
        type=float,
        default=D.MONITOR_BASELINE_HOURS,
        metavar="H",
        help="without fuel_on_board_t in the ship log: time constant of the health chart's "
        "slowly following baseline (0: fixed)",
    )
    parser.set_defaults(run=_run_monitor)


def _monitor_options(args: argparse.Namespace):
    """The :class:`~workbench.monitor.MonitorOptions` of parsed ``monitor`` arguments: the
    identification, tracking and forecast options read as the batch commands read them."""
    from ..monitor import ForecastSettings, MonitorOptions
    from ..monitor.shore import parse_command
    from ..sid.tracking import TrackingOptions

    identify = identify_options(args)  # with auto: blocks of one step, the lengths below
    adaptive = adaptive_options(args)  # --block-minutes auto (and --cases)
    harmonics = harmonic_options(args)  # as identify --dship marks them
    trust = check_forecast_flags(args)  # what `forecast` refuses, the monitor refuses
    try:
        tracking = TrackingOptions(
            mac_min=args.mac_min, gate=args.gate, frequency_tol=args.frequency_tol
        )
        forecast = ForecastSettings(
            forecast=forecast_options(args, trust),
            all_predictors=bool(args.all_predictors),
            dship_mapping=tuple((dship_mapping(args) or {}).items()),
            dship_utc_offset=dship_utc_offset(args),
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
            adaptive=adaptive,
            cases=None if args.cases is None else str(args.cases),
        )
    except (ValueError, argparse.ArgumentTypeError) as error:
        raise UsageError(_as_flag(str(error))) from None


#: The options' names in their messages -> the flags that set them.
_FLAGS = {
    "poll_s": "--poll",
    "settle_s": "--settle",
    "late_s": "--late",
    "flush_after_s": "--flush-after",
    "on_alarm_timeout_s": "--on-alarm-timeout",
    "reference_hours": "--reference-hours",
    "health_train_hours": "--health-train-hours",
    "baseline_hours": "--baseline-hours",
    "ewma_lambda": "--ewma-lambda",
    "false_alarms_per_day": "--false-alarms-per-day",
}


def _as_flag(message: str) -> str:
    """``"poll_s=0.0 must be positive"`` -> ``"--poll 0.0 must be positive"``."""
    name, equals, rest = message.partition("=")
    if equals and name in _FLAGS:
        return f"{_FLAGS[name]} {rest}"
    return message


def prepare_monitor(args: argparse.Namespace):
    """The :class:`~workbench.monitor.Monitor` that parsed ``monitor`` arguments describe
    (parsed by :func:`workbench.cli.parse_arguments`: ``--config`` applied)."""
    from ..monitor import Monitor

    if args.watch is None:
        raise UsageError("monitor needs --watch DIR (or [accelerations] inputs in --config)")
    if args.state is None:
        raise UsageError("monitor needs --state DIR")
    if not args.watch.is_dir():
        raise UsageError(f"--watch {args.watch}: no such folder")
    if args.cases is not None:
        if not args.cases.is_file():
            raise UsageError(f"--cases {args.cases}: no such file")
        from ..identification.adaptive import _read_cases

        _read_cases(args.cases)  # a table it cannot read: one line naming it, exit 1
    if args.start_time not in (None, "filename"):
        raise UsageError(
            f"--start-time {args.start_time}: one start time cannot place the files of a "
            "growing folder; give --start-time filename (the time in each file's name) or "
            "files with times of their own"
        )
    return Monitor(args.watch, args.state, dship=args.dship, options=_monitor_options(args))


#: How many of its notes the monitor prints when it stops (all are in the notes file).
_NOTES_SHOWN = 10


def _run_monitor(args: argparse.Namespace) -> int:
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
        refused = monitor.watcher.refused_reasons
        if refused:  # say why, naming the first file (identify would stop at it too)
            path, reason = next(iter(refused.items()))
            more = f" ({len(refused) - 1} more file(s) refused)" if len(refused) > 1 else ""
            raise WorkbenchError(f"{path}: cannot be monitored: {reason}{more}")
        raise WorkbenchError(f"{args.watch}: no complete acceleration file to monitor")
    if args.once and monitor.store_damaged:  # files left unused: never a silent exit 0
        raise WorkbenchError(monitor.store_damaged)
    if args.once and not monitor.stop_event.is_set():
        nothing = monitor.nothing_identified()
        if nothing:  # never a silent exit 0 with nothing done (identify says it too)
            raise WorkbenchError(nothing)
    through = monitor.tracked_through
    print(
        f"{len(monitor.done)} block(s) decided, tracked up to block "
        f"{through if through >= 0 else '-'}; state in {args.state}"
    )
    shown = monitor.messages[-_NOTES_SHOWN:]
    total = monitor.messages.total
    if total > len(shown):  # the others are in the notes file, never lost
        print(
            f"note: {total} notes in this run, the last {len(shown)} below; every note is in "
            f"{monitor.messages.path}"
        )
    for message in shown:
        print(f"note: {message}")
    given_up = monitor.given_up_note()
    if given_up:
        print(f"note: {given_up}")
    return EXIT_OK
