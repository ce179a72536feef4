"""Benchmark: pLSCF of one real record against pyOMA2's ``pLSCF`` (speed and accuracy).

Issue 19: the laboratory steel frame of ../shared/realdata/lab_frame (``measurement_1``,
5 good channels, decimated from 256 Hz to 42.7 Hz: 10 240 samples), identified by
:func:`workbench.sid.plscf.lscf` and by pyOMA2's ``pLSCF`` algorithm (pyOMA-2 on PyPI, an
optional benchmark dependency: ``pip install -e ".[bench]"``) with the same model:

- every channel an output and a reference (pyOMA2 uses all channels as references);
- half-spectra from correlations with 1024 lags and an exponential window ending at 0.01
  (pyOMA2 ``method_SD="cor"``, ``nxseg=1024``), the whole band 0 .. Nyquist;
- polynomial orders 1 .. 30 (a companion matrix of 5p states each).

Printed:

1. times (median of ``--repeats`` runs each, ours and pyOMA2 alternately so both see the
   same load), the median of the back-to-back ratios (the target: >= 1, ours at least as
   fast) and the ratio of the fastest runs;
2. accuracy at orders 10, 20, 30: how many of the 11 reference modes (reference_modes.csv,
   the mean over 14 records of the frame) each method finds as a stable pole within 0.5 %,
   the median and largest frequency error of those against the reference, and the largest
   frequency difference between the two methods where both find a mode.

The target is judged with one thread each (``threadpoolctl.threadpool_limits(1)``: BLAS
single-threaded, and ours then runs serially): on the shared 2-core machine pyOMA2 with
numpy's default multi-threaded BLAS was 6-7 times slower still (``--pyoma-default-blas``
times that as well). Ours with its default thread budget (Python threads over model
orders) is printed beside it.

Run: ``python benchmarks/bench_lscf.py [--repeats 5]``.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from workbench.sid.plscf import lscf
from workbench.signals.conditioning import decimate

ROOT = Path(__file__).resolve().parents[1]
LAB_FRAME = ROOT.parent / "shared" / "realdata" / "lab_frame"
RATE_HZ = 256.0 / 6
N_LAGS = 1024
MAX_ORDER = 30
CHECK_ORDERS = (10, 20, 30)
FREQUENCY_TOL = 0.005


def lab_frame_block() -> tuple[np.ndarray, pd.DataFrame]:
    raw = np.load(LAB_FRAME / "measurement_1.npy")[:, :5]  # column 5 is faulty
    data = decimate(raw - raw.mean(axis=0), 256.0, RATE_HZ)
    return np.ascontiguousarray(data), pd.read_csv(LAB_FRAME / "reference_modes.csv")


def run_ours(data: np.ndarray):
    return lscf(data, RATE_HZ, orders=range(1, MAX_ORDER + 1), n_lags=N_LAGS)


def run_pyoma(data: np.ndarray):
    from pyoma2.algorithms import pLSCF
    from pyoma2.setup import SingleSetup

    setup = SingleSetup(data, fs=RATE_HZ)
    algorithm = pLSCF(name="plscf", ordmax=MAX_ORDER, nxseg=N_LAGS, method_SD="cor")
    setup.add_algorithms(algorithm)
    setup.run_by_name("plscf")
    return algorithm.result


def stable_poles_ours(result, order: int) -> tuple[np.ndarray, np.ndarray]:
    poles = result.poles
    rows = (poles["model_order"] == order * 5) & poles["stable"]
    return poles.loc[rows, "frequency_hz"].to_numpy(), poles.loc[rows, "damping_ratio"].to_numpy()


def stable_poles_pyoma(result, order: int) -> tuple[np.ndarray, np.ndarray]:
    column = order - 1  # column k holds the poles of polynomial order k + 1
    frequency = result.Fn_poles[:, column]
    damping = result.Xi_poles[:, column]
    stable = (result.Lab[:, column] == 1) & np.isfinite(frequency)
    return frequency[stable], damping[stable]


def found(frequency: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """For each reference frequency, the nearest pole's relative error (NaN if > 0.5 %)."""
    if frequency.size == 0:
        return np.full(reference.size, np.nan)
    error = frequency[None, :] / reference[:, None] - 1
    nearest = error[np.arange(reference.size), np.argmin(np.abs(error), axis=1)]
    return np.where(np.abs(nearest) < FREQUENCY_TOL, nearest, np.nan)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--pyoma-default-blas", action="store_true")
    args = parser.parse_args(argv)
    if not LAB_FRAME.is_dir():
        print(f"{LAB_FRAME} is absent: nothing to benchmark", file=sys.stderr)
        return 1
    try:
        import pyoma2  # noqa: F401
    except ImportError:
        print('pyOMA2 is not installed: pip install -e ".[bench]"', file=sys.stderr)
        return 1
    logging.disable(logging.INFO)  # pyOMA2 logs every run
    data, reference = lab_frame_block()
    print(
        f"lab frame measurement_1: {data.shape[0]} samples x {data.shape[1]} channels at "
        f"{RATE_HZ:.2f} Hz; {N_LAGS} lags, orders 1..{MAX_ORDER}, all channels references"
    )
    from threadpoolctl import threadpool_limits

    run_ours(data)  # warm-up (imports, FFT plans)

    def timed(function):
        start = time.perf_counter()
        value = function(data)
        return time.perf_counter() - start, value

    ours_times, pyoma_times, threaded = [], [], []
    ours = pyoma = None
    for _ in range(args.repeats):
        with threadpool_limits(1):
            seconds, ours = timed(run_ours)
            ours_times.append(seconds)
            seconds, pyoma = timed(run_pyoma)
            pyoma_times.append(seconds)
        threaded.append(timed(run_ours)[0])
    ratios = [p / o for o, p in zip(ours_times, pyoma_times, strict=True)]
    print("one thread each:")
    print(
        f"  workbench lscf : median {statistics.median(ours_times):.3f} s "
        f"(fastest {min(ours_times):.3f} s)"
    )
    print(
        f"  pyOMA2 pLSCF   : median {statistics.median(pyoma_times):.3f} s "
        f"(fastest {min(pyoma_times):.3f} s)"
    )
    print(
        f"  speed-up (pyOMA2 / ours): median of pairs {statistics.median(ratios):.1f}x, "
        f"worst pair {min(ratios):.1f}x, fastest runs "
        f"{min(pyoma_times) / min(ours_times):.1f}x -> target >= 1x "
        f"{'met' if statistics.median(ratios) >= 1 else 'NOT met'}"
    )
    print(f"workbench lscf, default threads: median {statistics.median(threaded):.3f} s")
    if args.pyoma_default_blas:
        seconds = [timed(run_pyoma)[0] for _ in range(args.repeats)]
        print(f"pyOMA2 pLSCF, default BLAS threads: median {statistics.median(seconds):.3f} s")

    truth = reference["frequency_hz"].to_numpy()
    print(f"\naccuracy against the {truth.size} reference modes (stable poles within 0.5 %):")
    for order in CHECK_ORDERS:
        f_ours, _ = stable_poles_ours(ours, order)
        f_pyoma, _ = stable_poles_pyoma(pyoma, order)
        e_ours, e_pyoma = found(f_ours, truth), found(f_pyoma, truth)
        both = np.isfinite(e_ours) & np.isfinite(e_pyoma)
        between = np.abs((1 + e_ours[both]) / (1 + e_pyoma[both]) - 1)
        for name, error in (("workbench", e_ours), ("pyOMA2   ", e_pyoma)):
            ok = np.abs(error[np.isfinite(error)])
            stats = (
                f"|df|/f median {100 * np.median(ok):.3f} %, max {100 * ok.max():.3f} %"
                if ok.size
                else "-"
            )
            print(f"  order {order:2d} {name}: {ok.size:2d}/{truth.size} modes, {stats}")
        if between.size:
            print(
                f"  order {order:2d} between the two: max |df|/f {100 * between.max():.3f} % "
                f"over {between.size} common modes"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
