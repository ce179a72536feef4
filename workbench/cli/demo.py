"""``workbench demo``, ``simulate`` and ``run``: the built-in demo voyage, a simulated
voyage, and the chain a ship's configuration describes."""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import defaults as D
from .common import (
    EXIT_OK,
    UsageError,
    _add_parallel,
    _check_hours,
    _check_positive,
    _check_seed,
)


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
    parser.add_argument(
        "--sampling-rate",
        type=float,
        default=D.SIMULATE_SAMPLING_RATE_HZ,
        metavar="HZ",
        help="sampling rate of the acceleration files [Hz], a multiple of 64 Hz (e.g. 2048, "
        "a recorder's rate: same modal physics, broadband content and a 60 Hz hum above the "
        "band)",
    )
    parser.add_argument(
        "--ice-hours",
        type=float,
        default=0.0,
        metavar="H",
        help="end the voyage with H hours of ice breaking (ramming at 3.5 +- 1.5 kn, strong "
        "intermittent excitation, frequencies changing within minutes; 0: none); also writes "
        "truth_files.csv, the true modal parameters of every 5-min file",
    )
    shaft = parser.add_argument_group(
        "shaft harmonics",
        "Orders of the shaft rate (fixed-pitch propeller: the rate follows the speed) and "
        "the blade pass in the accelerations; the ship log carries the shaft speed unless "
        "--no-shaft-rpm. Orders sweep with speed and cross the modes (2.9-8.3 Hz): e.g. "
        "--shaft-orders 1,2 --shaft-hz-per-kn 0.41 sits order 1 on mode 1 at 7 kn and "
        "order 2 on mode 7 at 10 kn.",
    )
    shaft.add_argument(
        "--shaft-orders",
        default=D.SIMULATE_SHAFT_ORDERS,
        metavar="K,K",
        help="shaft orders in the accelerations (default: %(default)s)",
    )
    shaft.add_argument(
        "--blades",
        type=int,
        default=D.SIMULATE_BLADES,
        metavar="N",
        help="propeller blades: the blade-pass order N x the shaft rate (0: none) "
        "(default: %(default)s)",
    )
    shaft.add_argument(
        "--shaft-hz-per-kn",
        type=float,
        default=D.SIMULATE_SHAFT_HZ_PER_KN,
        metavar="HZ",
        help="shaft rate per knot of speed [Hz/kn]; 0.3 turns the shaft at 180 rpm at 10 kn "
        "(default: %(default)s)",
    )
    shaft.add_argument(
        "--no-shaft-rpm",
        action="store_true",
        help="leave the shaft speed out of the ship log (harmonics found from the data alone)",
    )
    parser.set_defaults(run=_run_simulate)


def _shaft_harmonics(args: argparse.Namespace):
    """The :class:`~workbench.simulate.ShaftHarmonics` of the simulate flags."""
    from ..simulate import ShaftHarmonics

    try:
        orders = tuple(int(k) for k in str(args.shaft_orders).split(",") if k.strip())
        return ShaftHarmonics(
            hz_per_kn=args.shaft_hz_per_kn,
            orders=orders,
            blades=args.blades,
            log_rpm=not args.no_shaft_rpm,
        )
    except ValueError as error:
        raise UsageError(f"shaft harmonics: {error}") from None


def _run_simulate(args: argparse.Namespace) -> int:
    from ..simulate import simulate_voyage

    _check_hours(args.hours)
    _check_seed(args.seed)
    from ..demo import describe_voyage

    try:
        voyage = simulate_voyage(
            args.out,
            seed=args.seed,
            hours=args.hours,
            accelerations=not args.no_accelerations,
            sampling_rate_hz=args.sampling_rate,
            shaft=_shaft_harmonics(args),
            ice_hours=args.ice_hours,
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
    parser.add_argument("--out", type=Path, default=D.DEMO_OUT, metavar="DIR", help="output folder")
    parser.add_argument("--seed", type=int, default=D.SEED, help="random seed")
    parser.add_argument(
        "--hours", type=float, default=None, help=f"voyage length [h] (default: {D.HOURS:g})"
    )
    _add_parallel(parser)
    parser.set_defaults(run=_run_demo)


def _run_demo(args: argparse.Namespace) -> int:
    from ..demo import run_demo

    _check_hours(args.hours)
    _check_seed(args.seed)
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


def _add_run(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser(
        "run",
        help="run the chain a ship's TOML configuration describes",
        description="Run identify, track, correlate, fit, forecast and evaluate as far as "
        "the configuration gives their inputs (see workbench.config; `workbench demo` "
        "writes an example, ship.toml), then build the run's report from their results. "
        "A warning that several stages meet (the same ship log read by each) is shown once.",
    )
    parser.add_argument("config_file", type=Path, metavar="SHIP.TOML")
    parser.set_defaults(run=_run_chain)


class _WarningsOnce:
    """A text stream in front of stderr that lets each ``warning: ...`` line through
    once: the stages of a run read the same inputs, and their warnings are the same.

    Only a line that may become a warning is held until its end; everything else (progress
    bars redrawn with carriage returns, errors) passes at once.
    """

    PREFIX = "warning: "

    def __init__(self, stream):
        self._stream = stream
        self._pending = ""
        self.seen: set[str] = set()
        self.repeated = 0

    def write(self, text: str) -> int:
        self._pending += text
        while "\n" in self._pending:
            line, self._pending = self._pending.split("\n", 1)
            self._emit(line + "\n")
        if self._pending and not (
            self._pending.startswith(self.PREFIX) or self.PREFIX.startswith(self._pending)
        ):
            self._stream.write(self._pending)
            self._pending = ""
        return len(text)

    def _emit(self, line: str) -> None:
        if line.startswith(self.PREFIX):
            if line in self.seen:
                self.repeated += 1
                return
            self.seen.add(line)
        self._stream.write(line)

    def flush(self) -> None:
        if self._pending:
            self._emit(self._pending)
            self._pending = ""
        self._stream.flush()

    def __getattr__(self, name: str):  # isatty, fileno, encoding, ... of stderr
        return getattr(self._stream, name)


def _run_chain(args: argparse.Namespace) -> int:
    import sys

    from ..config import ConfigError, chain, load_config
    from . import main

    try:
        steps = chain(load_config(args.config_file))
    except ConfigError as error:
        raise UsageError(str(error)) from None
    stderr = sys.stderr
    once = _WarningsOnce(stderr)
    sys.stderr = once
    try:
        for step in steps:
            print(f"== workbench {' '.join(step)}", flush=True)
            code = main((["--verbose"] if args.verbose else []) + step)
            once.flush()
            if code != EXIT_OK:
                return code
    finally:
        sys.stderr = stderr
    if once.repeated:
        print(
            f"{len(once.seen)} warning(s), each shown once ({once.repeated} repeat(s) by "
            "later stages left out)",
            file=sys.stderr,
        )
    return EXIT_OK
