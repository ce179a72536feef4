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


def _serve_demo(args: argparse.Namespace, options) -> int:
    import tempfile

    from ..dashboard import DemoReplay

    with tempfile.TemporaryDirectory(prefix="workbench-dashboard-demo-") as folder:
        replay = DemoReplay(folder).start()
        args.state = Path(folder)
        try:
            return _run_dashboard(argparse.Namespace(**{**vars(args), "demo": False}))
        finally:
            replay.stop()


def _add_monitor(commands: argparse._SubParsersAction) -> None:
    from ..monitor.cli import add_monitor

    add_monitor(commands)
