"""The speed-following harmonic test (a ship log with the speed but no shaft speed) on long
voyages: memory and time against the number of selected modes.

``identify --dship`` with a speed-only log tests the whole voyage's selected modes at once
(:func:`workbench.sid.harmonics.mark_speed_following`); a week at 5-min blocks holds about
2000 blocks x 10 modes. The voyages here are one identified voyage (the ``ramps`` scenario
of ``bench_harmonics.py``: orders 1 and 2 at 0.3 Hz/kn, 5 blades, ``--hours`` long)
repeated end to end up to each size, each repeated block's speed jittered by a factor
1 + N(0, ``--jitter``) (the modes, frequencies and shapes kept): every harmonic line and
every mode then holds as many modes as on a voyage that long.

Printed per size: the marks (count, and whether they equal the dense test's, the test
before this benchmark: a MAC matrix of every pair of usable modes, kept here as the
baseline ``_dense_marks``, run up to ``--dense-max`` modes), the peak of the memory the
test allocates (tracemalloc) and its time, each as a ratio against the smallest size, and
the monitor's cost per block: adding the newest block's modes to the test holding the
rest (:class:`~workbench.sid.harmonics.SpeedFollowing`), as a share of the whole test's
time at that size.

Run: ``python benchmarks/bench_harmonics_speed_scale.py [--sizes 2000 5000 10000 20000]
[--dense-max 10000] [--work DIR]``; the output is kept in
``benchmarks/results/harmonics_speed_scale_51.txt``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from data_contracts import read_dship  # noqa: E402
from workbench.demo import DEMO_IDENTIFY_OPTIONS  # noqa: E402
from workbench.identification import identify_voyage  # noqa: E402
from workbench.sid import harmonics  # noqa: E402
from workbench.sid.harmonics import (  # noqa: E402
    HarmonicOptions,
    SpeedFollowing,
    _mac_matrix,
    _shapes,
    block_shaft_table,
    mark_speed_following,
    order_list,
)
from workbench.simulate import ShaftHarmonics, simulate_voyage  # noqa: E402

SHAFT = ShaftHarmonics(hz_per_kn=0.3, orders=(1, 2), blades=5)
OPTIONS = HarmonicOptions(blades=SHAFT.blades)


class ShapeComparisons:
    """Counts the MACs the speed-following test computes (a cost that does not depend on
    the machine's load), while in a ``with`` block."""

    def __init__(self):
        self.count = 0

    def __enter__(self):
        def counted(a, b):
            self.count += len(a) * len(b)
            return _mac_matrix(a, b)

        self.count = 0
        harmonics._mac_matrix = counted
        return self

    def __exit__(self, *exc):
        harmonics._mac_matrix = _mac_matrix
        return False


def _dense_marks(selected, shaft, options: HarmonicOptions) -> pd.Series:
    """The speed-following test as it was (commit 9d5aee9): the MAC of every pair of
    usable modes, and per mode the shape components of its ratio window."""
    out = pd.Series(np.nan, index=selected.index, name="harmonic")
    speed = selected["block"].map(shaft.set_index("block")["speed_energy_kn"]).to_numpy(float)
    usable = np.isfinite(speed) & (speed > options.min_speed_kn)
    if usable.sum() < options.min_rows:
        return out
    rows = np.flatnonzero(usable)
    part = selected.iloc[rows]
    frequency = part["frequency_hz"].to_numpy(float)
    log_ratio = np.log(frequency / speed[rows])
    shapes = _shapes(part)
    same_shape = _mac_matrix(shapes, shapes) >= options.mac_min
    same_ratio = np.abs(log_ratio[:, None] - log_ratio[None, :]) <= options.ratio_tol
    marked = np.zeros(len(rows), dtype=bool)
    for i in range(len(rows)):
        window = np.flatnonzero(same_ratio[i])
        if len(window) < options.min_rows:
            continue
        _, component = connected_components(
            csr_matrix(same_shape[np.ix_(window, window)]), directed=False
        )
        members = window[component == component[np.searchsorted(window, i)]]
        spread = frequency[members].max() / frequency[members].min() - 1.0
        if len(members) >= options.min_rows and spread > options.min_sweep:
            marked[i] = True
    if marked.any():
        base = float(np.exp(np.min(log_ratio[marked])))
        lowest = min(options.orders)
        for order in order_list(options):
            marked |= np.abs(log_ratio - np.log(base * order / lowest)) <= options.ratio_tol
        out.attrs["shaft_hz_per_kn"] = base / lowest
    out.iloc[rows[marked]] = 0.0
    return out


def identified(work: Path, hours: float, seed: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The ramps voyage's selected modes and its speed-only block table."""
    voyage = simulate_voyage(work / "voyage", seed=seed, hours=hours, shaft=SHAFT)
    result = identify_voyage(
        [work / "voyage" / "accelerations"], work / "identify", options=DEMO_IDENTIFY_OPTIONS
    )
    columns = ["harmonic", "harmonic_frequency_hz", "harmonic_checked"]
    selected = pd.read_parquet(result.files["selected"]).drop(columns=columns, errors="ignore")
    log = read_dship(voyage.dship_log).drop(columns="shaft_rpm")
    return selected, block_shaft_table(log, selected)


def repeated(selected, shaft, size: int, jitter: float, seed: int):
    """The voyage repeated end to end until it holds *size* selected modes, each repeated
    block's speed times 1 + N(0, jitter)."""
    rng = np.random.default_rng(seed)
    n_blocks = int(shaft["block"].max()) + 1
    copies = -(-size // len(selected))
    parts, shafts = [], []
    for copy in range(copies):
        parts.append(selected.assign(block=selected["block"] + copy * n_blocks))
        factor = 1.0 if copy == 0 else 1.0 + jitter * rng.standard_normal(len(shaft))
        shafts.append(
            shaft.assign(
                block=shaft["block"] + copy * n_blocks,
                speed_energy_kn=shaft["speed_energy_kn"] * factor,
            )
        )
    big = pd.concat(parts, ignore_index=True).iloc[:size]
    return big, pd.concat(shafts, ignore_index=True)


def measured(function, *args):
    """(result, seconds, peak bytes allocated): timed once untraced, traced once."""
    started = time.perf_counter()
    result = function(*args)
    seconds = time.perf_counter() - started
    tracemalloc.start()
    tracemalloc.reset_peak()
    function(*args)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return result, seconds, peak


def per_block(selected, shaft, blocks: int = 30) -> tuple[float, float]:
    """Mean time [s] and MACs of adding one block's modes to the test holding the modes
    before it (the monitor's cost of a block), over the newest *blocks* blocks."""
    speed = selected["block"].map(shaft.set_index("block")["speed_energy_kn"]).to_numpy(float)
    usable = np.isfinite(speed) & (speed > OPTIONS.min_speed_kn)
    frequency = selected["frequency_hz"].to_numpy(float)
    shapes = _shapes(selected)
    block = selected["block"].to_numpy()
    newest = np.unique(block[usable])[-blocks:]
    test = SpeedFollowing(OPTIONS)
    first = usable & (block < newest[0])
    test.add(frequency[first], speed[first], shapes[first])
    started = time.perf_counter()
    with ShapeComparisons() as comparisons:
        for b in newest:
            rows = usable & (block == b)
            test.add(frequency[rows], speed[rows], shapes[rows])
            test.marked()
    return (time.perf_counter() - started) / len(newest), comparisons.count / len(newest)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[2000, 5000, 10000, 20000])
    parser.add_argument("--dense-max", type=int, default=10000)
    parser.add_argument("--hours", type=float, default=12.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jitter", type=float, default=0.005)
    parser.add_argument("--work", type=Path, help="folder for the voyage (default: temporary)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        selected, shaft = identified(args.work or Path(tmp), args.hours, args.seed)
    print(
        f"voyage: ramps, seed {args.seed}, {args.hours:g} h: {len(selected)} selected modes in "
        f"{selected['block'].nunique()} blocks"
    )
    print(
        "modes  marked  same as dense  dense: peak MB  s      new: peak MB  s     "
        "new peak / modes [kB]  MACs / modes²  per block: s, MACs / modes"
    )
    for size in args.sizes:
        big, big_shaft = repeated(selected, shaft, size, args.jitter, args.seed)
        marks, seconds, peak = measured(mark_speed_following, big, big_shaft, OPTIONS)
        with ShapeComparisons() as comparisons:
            mark_speed_following(big, big_shaft, OPTIONS)
        dense = "-"
        dense_cells = "      -        -"
        if size <= args.dense_max:
            reference, dense_seconds, dense_peak = measured(_dense_marks, big, big_shaft, OPTIONS)
            same = reference.equals(marks) and reference.attrs == marks.attrs
            dense = "yes" if same else "NO"
            dense_cells = f"{dense_peak / 1e6:9.0f} {dense_seconds:8.1f}"
        block_s, block_macs = per_block(big, big_shaft)
        print(
            f"{size:6d} {int(marks.notna().sum()):6d}  {dense:>13s}  {dense_cells}  "
            f"{peak / 1e6:9.1f} {seconds:6.2f}  {peak / size / 1e3:10.1f}  "
            f"{comparisons.count / size**2:12.4f}   {block_s:.3f}, {block_macs / size:.2f}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
