"""``workbench dashboard`` and ``monitor``: the live bridge page and the folder follower
(its options live in :mod:`workbench.monitor.cli`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import WorkbenchError
from .common import EXIT_OK, UsageError


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


def _add_monitor(commands: argparse._SubParsersAction) -> None:
    from ..monitor.cli import add_monitor

    add_monitor(commands)
