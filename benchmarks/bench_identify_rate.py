"""Benchmark: identification at a recorder's rate (2048 Hz, 19 channels) against a plain
script (issue 33) and the per-block path (issue 18).

Plain baseline (issue 33; needs koma-python): ``workbench identify --band 2 12`` with the
largest ``--workers`` against the single-process script a user would otherwise run (per
20-min block: read the files, ``scipy.signal.decimate`` 4 x 8 to 64 Hz, koma ``covssi``
i = 20, orders 4..60), interleaved, ``--repeats`` pairs; printed: wall-clock and CPU-second
ratios (the machine may be shared: the CPU ratio is the steadier). Then a profile of the
same command in-process (synchronous scheduler) under cProfile with a CPU clock, one line
per stage (reading, decimation, validation, conditioning, SSI, selection, store writes,
planning and orchestration); library time counts in the stage of the workbench function
that called it. ``--skip-baseline``, ``--skip-profile``, ``--skip-per-block`` leave parts out.

``workbench identify`` runs on a voyage simulated at 2048 Hz (``workbench simulate --rate
2048``; default 1 h, ``--hours 24`` for a day) with the default analysis rate (2048 Hz ->
64 Hz for the 2-12 Hz band), in a fresh store each time, for

* ``--conditioning per-block``: every 20-min block read, checked and decimated from its raw
  files (the path before issue 18: each sample conditioned four times), and
* ``--conditioning per-file``: each file read, checked and decimated once,

with 1 and 2 worker processes. The runs are interleaved (A B, B A, ...) so that both paths
see the same machine load, and the figures are medians over ``--repeats`` runs; the ratio
quoted is the ratio of the medians, and the worst ratio of a back-to-back pair is printed
beside it.

Real-time factor = recording identified per second of wall clock, counted as one block step
(5 min) of new recording per block: a voyage of N five-minute files has N - 3 blocks, so a
short voyage is not credited with the three files that only complete the first block. The
time for a day (288 blocks) is extrapolated from the measured factor (not measured, unless
``--hours 24``). Wall clock includes starting the worker processes.

Peak memory: the largest process of each run (``getrusage`` of the child processes), and
the per-file path in-process (``--scheduler synchronous``) on a voyage of ``--hours`` and
of twice that: memory independent of voyage length means a ratio near 1.

Long stretches (``--long-hours 2 4``, or ``24`` for a whole day where the disk holds its
27 GB): the per-file path with the largest ``--workers`` on voyages of those lengths,
measured end to end (nothing extrapolated): real-time factor, peak memory, and the
incremental real-time factor between consecutive lengths (new recording of the extra
blocks / extra wall clock), which leaves out the fixed costs (start-up, cluster) and is
flat when the cost per block does not grow with the voyage. The machine's load average is
printed with every run (the machine may be shared).

Simulating the voyages is not timed (a 1-h, 2048-Hz voyage writes 1.1 GB; ``--data`` reuses
a folder). Run: ``python benchmarks/bench_identify_rate.py`` (about 25 minutes on a quiet
2-core machine with the defaults).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import itertools
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from child_library import pin_library  # noqa: E402

LIBRARY = pin_library()  # child processes import this library, not the current folder's

RATE_HZ = 2048.0
STEP_S = 300.0
DAY_BLOCKS = 288

#: Runs a command and prints its peak RSS and CPU seconds. The CPU seconds are the larger
#: of two counts: getrusage of the reaped children (every process of the tree that was
#: waited for) and the sum of each process's own CPU time as last seen in /proc (sampled
#: every 50 ms: it also counts processes that exit without being waited for, such as
#: Dask workers terminated at cluster shutdown, which getrusage misses; it misses at most
#: the last 50 ms of each process).
_WRAPPER = (
    "import os, resource, subprocess, sys, threading\n"
    "tick = os.sysconf('SC_CLK_TCK')\n"
    "seen = {}\n"
    "def tree(root):\n"
    "    parents = {}\n"
    "    for name in os.listdir('/proc'):\n"
    "        if name.isdigit():\n"
    "            try:\n"
    "                with open(f'/proc/{name}/stat') as f: fields = f.read().rsplit(')', 1)[1].split()\n"
    "            except OSError: continue\n"
    "            parents[int(name)] = (int(fields[1]), (int(fields[11]) + int(fields[12])) / tick)\n"
    "    inside = {root}\n"
    "    for _ in range(64):\n"
    "        more = {p for p, (pp, _) in parents.items() if pp in inside} - inside\n"
    "        if not more: break\n"
    "        inside |= more\n"
    "    for p in inside:\n"
    "        if p in parents: seen[p] = max(seen.get(p, 0.0), parents[p][1])\n"
    "child = subprocess.Popen(sys.argv[1:], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)\n"
    "done = threading.Event()\n"
    "def poll():\n"
    "    while not done.wait(0.05):\n"
    "        tree(child.pid)\n"
    "threading.Thread(target=poll, daemon=True).start()\n"
    "out, err = child.communicate()\n"
    "done.set()\n"
    "sys.stdout.write(out); sys.stderr.write(err)\n"
    "usage = resource.getrusage(resource.RUSAGE_CHILDREN)\n"
    "cpu = max(usage.ru_utime + usage.ru_stime, sum(seen.values()))\n"
    "print('PEAK_KIB', usage.ru_maxrss, 'CPU_S', cpu)\n"
    "sys.exit(child.returncode)\n"
)


def _voyage(root: Path, hours: float) -> Path:
    folder = root / f"voyage_{RATE_HZ:g}hz_{hours:g}h"
    if not (folder / "voyage.json").is_file():
        from workbench.simulate import simulate_voyage

        print(f"simulating {hours:g} h at {RATE_HZ:g} Hz into {folder} (not timed) ...", flush=True)
        simulate_voyage(folder, seed=0, hours=hours, sampling_rate_hz=RATE_HZ)
    return folder / "accelerations"


def _measured(command: list[str]) -> tuple[float, int, int, float]:
    """*command* in a child process under :data:`_WRAPPER`: (seconds, peak RSS MiB, blocks
    it reports processed, CPU seconds of the process tree)."""
    start = time.perf_counter()
    finished = subprocess.run(
        [sys.executable, "-c", _WRAPPER, *command],
        capture_output=True,
        text=True,
        cwd=tempfile.gettempdir(),
    )
    seconds = time.perf_counter() - start
    if finished.returncode:
        raise SystemExit(finished.stderr)
    usage = finished.stdout.rsplit("PEAK_KIB", 1)[1].split()
    blocks = int(finished.stdout.split(" block(s) processed")[0].split()[-1])
    return seconds, int(usage[0]) // 1024, blocks, float(usage[2])


def _identify(voyage: Path, out: Path, *extra: str) -> tuple[float, int, int, float]:
    """``workbench identify`` in a child process, started as the ``workbench`` command
    starts (``python -m workbench``: the entry point :mod:`workbench.launch`, which hashes
    the inputs while the command line imports; ``-m workbench.cli`` would import the
    command line first): (seconds, peak RSS MiB, blocks done, CPU seconds of the process
    tree)."""
    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, "-m", "workbench", "identify", str(voyage)]
    command += ["--out", str(out), "--quiet", *extra]
    try:
        return _measured(command)
    finally:
        shutil.rmtree(out, ignore_errors=True)


_PLAIN_SCRIPT = """
import sys
from pathlib import Path

import numpy as np
from scipy import signal

import koma.oma

files = sorted(Path(sys.argv[1]).glob("*.npz"))
blocks = 0
for first in range(len(files) - 3):  # 20-min blocks of four 5-min files, 5-min step
    data = np.concatenate([np.load(f)["acceleration"] for f in files[first : first + 4]])
    data = data[:, np.isfinite(data).all(axis=0)]  # channels with gaps left out
    data = signal.decimate(signal.decimate(data, 4, axis=0), 8, axis=0)  # 2048 -> 64 Hz
    data -= data.mean(axis=0)
    koma.oma.covssi(data, 64.0, 20, list(range(4, 61, 2)), showinfo=False)
    blocks += 1
print(blocks, "block(s) processed")
"""


def _plain(voyage: Path) -> tuple[float, int, int, float]:
    """The plain single-process script (per 20-min block: read the files, scipy.signal.decimate
    4 x 8 to 64 Hz, koma covssi i = 20, orders 4..60) in a child process: (seconds, peak
    RSS MiB, blocks, CPU seconds)."""
    command = [sys.executable, "-c", _PLAIN_SCRIPT, str(voyage)]
    return _measured(command)


#: Stages of the profile: (name, path fragments of the modules whose time counts there);
#: the first match wins, library time goes to the calling workbench function's stage.
_STAGES = (
    ("reading", ("data_contracts/npz", "signals/file_reads", "data_contracts/formats")),
    ("decimation", ("signals/filter_cascade",)),
    ("validation", ("signals/moments", "signals/step_sums", "data_contracts/accelerations")),
    ("conditioning", ("workbench/signals/",)),
    ("SSI", ("sid/ssi/", "sid/modal", "sid/_lapack", "sid/threads")),
    ("LSCF / cross-check", ("sid/plscf", "sid/crosscheck", "identification/crosscheck")),
    ("selection", ("workbench/sid/",)),
    ("store writes", ("workbench/store", "identification/export")),
    ("planning, orchestration", ("workbench/", "data_contracts/")),
)


def _stage_of(filename: str) -> str | None:
    if "workbench" not in filename and "data_contracts" not in filename:
        return None
    for name, fragments in _STAGES:
        if any(fragment in filename for fragment in fragments):
            return name
    return None


def _profile(voyage: Path, out: Path) -> None:
    """CPU time per stage of ``workbench identify`` run in this process (synchronous
    scheduler) under cProfile with a CPU-time clock; one line per stage."""
    import cProfile
    import pstats

    from workbench.cli import main as workbench_main

    shutil.rmtree(out, ignore_errors=True)
    profiler = cProfile.Profile(time.process_time)
    command = ["identify", str(voyage), "--out", str(out), "--band", "2", "12"]
    command += ["--scheduler", "synchronous", "--quiet"]
    with contextlib.redirect_stdout(io.StringIO()):  # the command's own summary
        profiler.enable()
        workbench_main(command)
        profiler.disable()
    shutil.rmtree(out, ignore_errors=True)
    stats = pstats.Stats(profiler).stats  # {function: (cc, nc, own, cumulative, callers)}
    shares: dict = {}

    def attribute(function, depth: int = 0) -> dict:
        """{stage: share} of *function*'s own time: its module's stage, or its callers'."""
        if function in shares:
            return shares[function]
        stage = _stage_of(function[0])
        if stage is not None:
            shares[function] = {stage: 1.0}
            return shares[function]
        callers = stats[function][4] if function in stats else {}
        total = sum(edge[3] for edge in callers.values())
        if depth > 50 or total <= 0:
            shares[function] = {"other": 1.0}
            return shares[function]
        shares[function] = {"other": 1.0}  # a recursion through this function
        result: dict = {}
        for caller, edge in callers.items():
            for name, share in attribute(caller, depth + 1).items():
                result[name] = result.get(name, 0.0) + share * edge[3] / total
        shares[function] = result
        return result

    seconds: dict = {}
    for function, (_, _, own, _, _) in stats.items():
        for name, share in attribute(function).items():
            seconds[name] = seconds.get(name, 0.0) + own * share
    total = sum(seconds.values())
    print(
        f"\nprofile: workbench identify --band 2 12, in-process, CPU time under cProfile "
        f"({total:.1f} s; the profiler adds to the Python-level stages)"
    )
    for name, value in sorted(seconds.items(), key=lambda item: -item[1]):
        print(f"  profile {name:24s} {value:7.2f} s  {100 * value / total:5.1f} %")


def _baseline(args, voyage: Path, work: Path) -> None:
    """Plain single-process script against ``workbench identify --band 2 12`` with the
    largest --workers, interleaved."""
    try:
        import koma.oma  # noqa: F401
    except ImportError:
        print("koma-python is not installed (pip install koma-python): no plain baseline")
        return
    workers = max(args.workers)
    plain, ours, plain_cpu, ours_cpu, pairs = [], [], [], [], []
    blocks = 0
    for repeat in range(args.repeats):
        order = ("plain", "ours") if repeat % 2 == 0 else ("ours", "plain")
        pair = {}
        for name in order:
            if name == "plain":
                took, peak, blocks, cpu = _plain(voyage)
                plain.append(took)
                plain_cpu.append(cpu)
            else:
                took, peak, blocks, cpu = _identify(
                    voyage, work / "out", "--band", "2", "12", "--workers", str(workers)
                )
                ours.append(took)
                ours_cpu.append(cpu)
            pair[name] = took
            print(
                f"  run {repeat + 1}, {name:5s}: {took:7.1f} s wall, CPU {cpu:.1f} s, peak "
                f"{peak} MiB, load average {_load()}",
                flush=True,
            )
        pairs.append(pair["plain"] / pair["ours"])
    wall_ratio = statistics.median(plain) / statistics.median(ours)
    cpu_ratio = statistics.median(plain_cpu) / statistics.median(ours_cpu)
    factor = blocks * STEP_S / statistics.median(ours)
    print(
        f"plain script / workbench identify ({workers} workers): {wall_ratio:.2f}x wall "
        f"(ratio of medians; pairs median {statistics.median(pairs):.2f}x), {cpu_ratio:.2f}x "
        f"CPU seconds; real-time factor {factor:.1f} (a day in "
        f"{DAY_BLOCKS * STEP_S / factor / 60:.1f} min)"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, help="folder for (or with) the simulated voyages")
    parser.add_argument("--hours", type=float, default=1.0, help="voyage length (24: a day)")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each configuration")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--skip-memory", action="store_true")
    parser.add_argument(
        "--long-hours",
        type=float,
        nargs="*",
        default=[],
        help="also identify voyages of these lengths (per-file, largest --workers)",
    )
    parser.add_argument("--skip-ratio", action="store_true", help="only the long stretches")
    parser.add_argument(
        "--skip-per-block", action="store_true", help="no per-block / per-file comparison"
    )
    parser.add_argument(
        "--skip-baseline", action="store_true", help="no plain-script (scipy + koma) baseline"
    )
    parser.add_argument("--skip-profile", action="store_true", help="no profile per stage")
    args = parser.parse_args(argv)
    root = args.data or Path(tempfile.mkdtemp(prefix="bench_identify_rate_"))
    root.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="bench_identify_rate_out_"))
    voyage = _voyage(root, args.hours)
    print(
        f"machine: {os.cpu_count()} cores, load average {_load()}; voyage {args.hours:g} h "
        f"at {RATE_HZ:g} Hz, 19 channels; workbench from {LIBRARY}"
    )
    if not args.skip_baseline:
        _baseline(args, voyage, work)
    if not args.skip_profile:
        _profile(voyage, work / "profile")
    if not args.skip_ratio and not args.skip_per_block:
        _ratios(args, root, voyage, work)
    if args.long_hours:
        _long_stretches(args, root, work, max(args.workers))
    print(f"load average at the end: {_load()}")
    shutil.rmtree(work, ignore_errors=True)
    return 0


def _load() -> str:
    return " ".join(f"{x:.1f}" for x in os.getloadavg())


def _long_stretches(args, root: Path, work: Path, workers: int) -> None:
    """Per-file identification of voyages of ``args.long_hours``, measured end to end."""
    print(f"\nlong stretches: per-file, {workers} worker(s), each measured once")
    print("hours  blocks  wall s  real-time factor  peak MiB  load average")
    done = []
    for hours in sorted(args.long_hours):
        folder = _voyage(root, hours)
        took, peak, blocks, cpu = _identify(
            folder, work / "long", "--workers", str(workers), "--conditioning", "per-file"
        )
        factor = blocks * STEP_S / took
        done.append((hours, blocks, took))
        print(
            f"{hours:5g}  {blocks:6d}  {took:6.1f}  {factor:16.1f}  {peak:8d}  {_load()}"
            f"  (CPU {cpu:.1f} s: {blocks * STEP_S / cpu:.1f} s of recording per CPU second)",
            flush=True,
        )
    for (h0, b0, t0), (h1, b1, t1) in itertools.pairwise(done):
        if t1 > t0:
            print(
                f"incremental {h0:g} h -> {h1:g} h: {(b1 - b0) * STEP_S / (t1 - t0):.1f} "
                f"(extra {b1 - b0} blocks in {t1 - t0:.1f} s)"
            )
    if done and done[-1][1] >= DAY_BLOCKS:
        print(f"a day measured: {done[-1][2] / 60:.1f} min for {done[-1][1]} blocks")


def _ratios(args, root: Path, voyage: Path, work: Path) -> None:
    """Per-block against per-file, interleaved, for each worker count."""

    paths = ("per-block", "per-file")
    seconds: dict = {(p, w): [] for p in paths for w in args.workers}
    peaks: dict = {(p, w): [] for p in paths for w in args.workers}
    pairs: dict = {w: [] for w in args.workers}
    cpus: dict = {(p, w): [] for p in paths for w in args.workers}
    n_blocks = 0
    for repeat in range(args.repeats):
        for workers in args.workers:
            order = paths if repeat % 2 == 0 else paths[::-1]
            pair = {}
            for path in order:
                took, peak, n_blocks, cpu = _identify(
                    voyage, work / "out", "--workers", str(workers), "--conditioning", path
                )
                cpus[path, workers].append(cpu)
                seconds[path, workers].append(took)
                peaks[path, workers].append(peak)
                pair[path] = took
                print(
                    f"  run {repeat + 1}, {workers} worker(s), {path:9s}: {took:7.1f} s, "
                    f"peak {peak} MiB, CPU {cpu:.1f} s, load average {_load()}",
                    flush=True,
                )
            pairs[workers].append(pair["per-block"] / pair["per-file"])

    print(f"\n{n_blocks} blocks = {n_blocks * STEP_S / 3600:g} h of new recording per run")
    print("workers  path       median s  real-time factor  day (288 blocks)  peak MiB")
    factors = {}
    for workers in args.workers:
        for path in paths:
            median = statistics.median(seconds[path, workers])
            factor = n_blocks * STEP_S / median
            factors[path, workers] = factor
            day_min = DAY_BLOCKS * STEP_S / factor / 60
            print(
                f"{workers:7d}  {path:9s}  {median:8.1f}  {factor:16.1f}  {day_min:11.1f} min"
                f"  {max(peaks[path, workers]):8d}"
            )
    for workers in args.workers:
        ratio = factors["per-file", workers] / factors["per-block", workers]
        print(
            f"{workers} worker(s): per-file / per-block throughput = {ratio:.2f}x (ratio of "
            f"medians); back-to-back pairs: median {statistics.median(pairs[workers]):.2f}x, "
            f"worst {min(pairs[workers]):.2f}x"
        )
        cpu_ratio = statistics.median(cpus["per-block", workers]) / statistics.median(
            cpus["per-file", workers]
        )
        print(f"  CPU seconds per run, per-block / per-file (medians): {cpu_ratio:.2f}x")
    print("(day times extrapolated from the measured real-time factor unless --hours 24)")

    if not args.skip_memory:
        peak_of = {}
        for hours in (args.hours, 2 * args.hours):
            folder = _voyage(root, hours)
            took, peak, blocks, _ = _identify(
                folder, work / "mem", "--scheduler", "synchronous", "--conditioning", "per-file"
            )
            peak_of[hours] = peak
            print(
                f"per-file, in-process, {hours:g} h: {blocks} blocks in {took:.1f} s, peak {peak} MiB"
            )
        ratio = peak_of[2 * args.hours] / peak_of[args.hours]
        print(f"peak memory {2 * args.hours:g} h / {args.hours:g} h: {ratio:.2f}")


if __name__ == "__main__":
    sys.exit(main())
