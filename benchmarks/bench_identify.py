"""Benchmark: block-wise identification throughput (1 vs 2 workers) and peak memory vs
voyage length (issue 6).

1. Throughput: ``workbench identify`` on a simulated voyage (default 1 day, 285 blocks of
   20 min, 19 channels at 64 Hz) on a local Dask cluster with 1 and with 2 worker
   processes, each in a fresh store; blocks per second and the speed-up are printed.
2. Memory: the same command in-process (``--scheduler synchronous``) on a 1-day and a 3-day
   voyage; the peak resident set size of each run (``getrusage`` of the child process) is
   printed with their ratio. Bounded memory means a ratio near 1, not 3.

Simulating the voyages is not timed (a 3-day voyage writes about 2.5 GB of acceleration
files; ``--data`` reuses a folder). Run: ``python benchmarks/bench_identify.py``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from child_library import pin_library  # noqa: E402

pin_library()  # child processes import this library, not the current folder's


def _voyage(root: Path, days: float) -> Path:
    folder = root / f"voyage_{days:g}d"
    if not (folder / "voyage.json").is_file():
        from workbench.simulate import simulate_voyage

        print(f"simulating a {days:g}-day voyage into {folder} (not timed) ...", flush=True)
        simulate_voyage(folder, seed=0, hours=24 * days)
    return folder


_WRAPPER = (
    "import resource, subprocess, sys\n"
    "done = subprocess.run(sys.argv[1:], capture_output=True, text=True)\n"
    "sys.stdout.write(done.stdout); sys.stderr.write(done.stderr)\n"
    "print('PEAK_KIB', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
    "sys.exit(done.returncode)\n"
)


def _identify(voyage: Path, out: Path, *extra: str) -> tuple[float, int, str]:
    """Run ``workbench identify`` in a child process: (seconds, peak RSS in MiB, stdout).

    A small wrapper process runs the command so that ``getrusage(RUSAGE_CHILDREN)`` sees
    only this run (the largest process of its tree).
    """
    shutil.rmtree(out, ignore_errors=True)
    command = [
        sys.executable,
        "-m",
        "workbench.cli",
        "identify",
        str(voyage),
        "--out",
        str(out),
        "--quiet",
        *extra,
    ]
    start = time.perf_counter()
    finished = subprocess.run(
        [sys.executable, "-c", _WRAPPER, *command], capture_output=True, text=True
    )
    seconds = time.perf_counter() - start
    if finished.returncode:
        raise SystemExit(finished.stderr)
    peak_kib = int(finished.stdout.rsplit("PEAK_KIB", 1)[1].split()[0])
    return seconds, peak_kib // 1024, finished.stdout


def _blocks(stdout: str) -> int:
    return int(stdout.split(" block(s) processed")[0].split()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, help="folder for (or with) the simulated voyages")
    parser.add_argument("--days", type=float, default=1.0, help="voyage for the throughput")
    parser.add_argument("--skip-memory", action="store_true")
    parser.add_argument("--skip-throughput", action="store_true")
    args = parser.parse_args(argv)
    root = args.data or Path(tempfile.mkdtemp(prefix="bench_identify_"))
    root.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="bench_identify_out_"))
    print(f"machine: {os.cpu_count()} cores")

    rates = {}
    for workers in () if args.skip_throughput else (1, 2):
        voyage = _voyage(root, args.days)
        seconds, _, stdout = _identify(voyage, work / f"w{workers}", "--workers", str(workers))
        n = _blocks(stdout)
        rates[workers] = n / seconds
        print(
            f"{workers} worker(s): {n} blocks in {seconds:.1f} s = {rates[workers]:.2f} "
            "blocks/s (cluster start-up included)"
        )
    if rates:
        print(f"speed-up 2 vs 1 worker: {rates[2] / rates[1]:.2f}x")

    if not args.skip_memory:
        peaks = {}
        for days in (1.0, 3.0):
            folder = _voyage(root, days)
            seconds, peak, stdout = _identify(
                folder, work / f"mem{days:g}", "--scheduler", "synchronous"
            )
            peaks[days] = peak
            print(
                f"{days:g}-day voyage, in-process: {_blocks(stdout)} blocks in "
                f"{seconds:.1f} s, peak RSS {peak} MiB"
            )
        print(f"peak memory 3-day / 1-day: {peaks[3.0] / peaks[1.0]:.2f}")
    shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
