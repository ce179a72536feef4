"""Measurement: processes left behind by ``kill -9`` of ``workbench monitor``.

The monitor follows a folder holding a simulated voyage (the monitor tests' 1-h voyage
reduced to 6 channels) and recomputes forecast and health in its background worker. A
second after that worker has started, the monitor is killed with SIGKILL; 10 s later the
processes it had started (the worker and multiprocessing's resource tracker) are counted,
with their memory, and then ended. Repeated ``--kills`` times.

Run from outside the source tree (``python -m`` puts the working folder first on the
path): ``cd /tmp && PYTHONPATH=REPO python REPO/benchmarks/bench_processes.py --kills 4``
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil  # a dependency of dask.distributed

sys.path.insert(0, str(Path(__file__).resolve().parent))
from child_library import pin_library  # noqa: E402

pin_library()  # child processes import this library, not the current folder's


def _monitor(voyage: Path, state: Path) -> subprocess.Popen:
    argv = ["monitor", "--watch", voyage / "accelerations", "--state", state]
    argv += ["--dship", voyage / "dship.tsv", "--block-rows", "8", "--max-order", "20"]
    argv += ["--band", "2", "12", "--train-blocks", "6", "--poll", "0.05", "--settle", "0.2"]
    return subprocess.Popen(
        [sys.executable, "-m", "workbench.cli", *map(str, argv)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kills", type=int, default=4)
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from tests.monitor.conftest import write_voyage  # the monitor tests' reduced voyage

    with tempfile.TemporaryDirectory() as folder:
        voyage = write_voyage(Path(folder), hours=1.0)
        total = 0
        for k in range(args.kills):
            process = _monitor(voyage, Path(folder) / f"state{k}")
            parent = psutil.Process(process.pid)
            while not any(
                "--multiprocessing-fork" in " ".join(c.cmdline())
                for c in parent.children(recursive=True)
            ):
                time.sleep(0.1)
            time.sleep(1.0)
            started = parent.children(recursive=True)
            process.kill()
            process.wait()
            time.sleep(10.0)
            alive = [c for c in started if c.is_running() and c.status() != psutil.STATUS_ZOMBIE]
            memory = [round(c.memory_info().rss / 1e6) for c in alive]
            print(
                f"kill {k + 1}: {len(started)} started, {len(alive)} alive 10 s later {memory} MB"
            )
            total += len(alive)
            for child in alive:
                os.kill(child.pid, 9)
        print(f"after {args.kills} kills: {total} processes left")


if __name__ == "__main__":
    main()
