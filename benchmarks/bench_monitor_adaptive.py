"""The monitor's adaptive blocks against the batch run on the ice voyages.

For each voyage of ``bench_adaptive_blocks.py`` (station, transit, 0-10 kn alternation,
then ice breaking), in this session, one after the other and each in a fresh process:

* **batch**: ``workbench identify ACC --out DIR --block-minutes auto --dship LOG
  --scheduler synchronous`` then ``workbench track DIR/selected.parquet``;
* **monitor**: ``workbench monitor --watch ACC --state DIR --dship LOG --block-minutes auto
  --once`` (in-process forecast and health at the end, one worker like the batch run).

Printed per voyage: blocks and their lengths, whether the monitor's tables equal the
batch's (block lengths and stationarity measures per block, the selected modes'
frequencies per block, the tracked table), the largest frequency difference, and the
wall time of each run per block with the ratio monitor / batch. The monitor's time is
given whole and up to its last block's state (``identified_at`` of the last block in
``data_health.parquet``: identification and tracking, without the final forecast, which
the batch pair does not run).

With ``--live SEED`` the monitor is also fed live: the voyage's files are replayed into a
watched folder at ``--speed`` (60: a 5-min file every 5 s; each lands under a hidden name,
then renamed, when its last sample is due) with the ship log growing alongside, and
``workbench monitor --block-minutes auto`` follows them in its own process (forecast and
health in its background process, ``--flush-after 10``). Printed: the tables against the
batch run's, the monitor's CPU seconds per block (its process tree), and per block the
wall time from the landing of the file that completes the block's decision span (its
longest candidate, 17.5 min past its centre) to the block's state (``identified_at``);
the last blocks, decided at the end of the input (after ``--flush-after``), apart.

Run: ``python benchmarks/bench_monitor_adaptive.py [--seeds 0,1,2,3,4] [--work
/tmp/bench_adaptive] [--also-fixed 20] [--live 0 --speed 60]`` (voyages simulated where
missing; the runs are made again each time, in ``WORK/<voyage>/monitor_bench_*``).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_adaptive_blocks import add_voyage_arguments, voyages  # noqa: E402
from child_library import pin_library  # noqa: E402

pin_library()  # child processes import this library, not the current folder's

_CODE = "import sys; from workbench.cli import main; sys.exit(main(sys.argv[1:]))"


def _run(*argv) -> float:
    """Run ``workbench ARGV`` in a fresh process; its wall time. [s]"""
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", _CODE, *map(str, argv)], capture_output=True, text=True
    )
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"workbench {' '.join(map(str, argv))}: exit {done.returncode}\n"
                         f"{done.stderr[-2000:]}")  # fmt: skip
    return seconds


def _store_table(store: Path, kind: str) -> pd.DataFrame:
    files = sorted((store / kind).glob("day=*/*.parquet"))
    frame = pd.concat([pd.read_parquet(p) for p in files], ignore_index=True)
    return frame.drop(columns=["day"], errors="ignore")


def compare(folder: Path, minutes: str = "auto") -> dict:
    """Run the pair on the voyage in *folder* with ``--block-minutes MINUTES``; what they
    gave and took."""
    work = folder / f"monitor_bench_{minutes}"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    accelerations, log = folder / "accelerations", folder / "dship.tsv"
    started = pd.Timestamp.now(tz="UTC")
    batch_s = _run(
        "identify", accelerations, "--out", work / "batch", "--block-minutes", minutes,
        "--dship", log, "--scheduler", "synchronous", "--quiet",
    )  # fmt: skip
    batch_s += _run(
        "track", work / "batch" / "selected.parquet", "--out", work / "batch_tracked.parquet"
    )
    state = work / "state"
    monitor_started = pd.Timestamp.now(tz="UTC")
    monitor_s = _run(
        "monitor", "--watch", accelerations, "--state", state, "--dship", log,
        "--block-minutes", minutes, "--once", "--quiet",
    )  # fmt: skip
    health = pd.read_parquet(state / "data_health.parquet")
    to_last_block_s = (health["identified_at"].max() - monitor_started).total_seconds()
    blocks = pd.read_csv(work / "batch" / "blocks.csv")
    if minutes == "auto":
        lengths = _store_table(state / "store", "lengths").sort_values("block")
        measures = ["block_length_s", "excitation_range_db", "speed_range_kn"]
        same_lengths = blocks["block"].tolist() == lengths["block"].tolist() and all(
            np.allclose(blocks[c], lengths[c], rtol=1e-12, atol=0, equal_nan=True) for c in measures
        )
    else:  # one length: the blocks' spans
        blocks["block_length_s"] = 60.0 * float(minutes)
        stored = _store_table(state / "store", "blocks").sort_values("block")
        same_lengths = blocks["block"].tolist() == stored["block"].tolist()
    keys = ["block", "model_order", "frequency_hz"]
    batch_selected = pd.read_parquet(work / "batch" / "selected.parquet")
    batch_selected = batch_selected.sort_values(keys).reset_index(drop=True)
    selected = _store_table(state / "store", "selected").sort_values(keys).reset_index(drop=True)
    same_selected = len(selected) == len(batch_selected) and np.array_equal(
        selected["block"], batch_selected["block"]
    )
    df_selected = (
        float(np.max(np.abs(selected["frequency_hz"] - batch_selected["frequency_hz"])))
        if same_selected
        else float("nan")
    )
    tracked = pd.read_parquet(state / "tracked.parquet")
    batch_tracked = pd.read_parquet(work / "batch_tracked.parquet")
    try:
        pd.testing.assert_frame_equal(tracked, batch_tracked)
        same_tracked = True
    except AssertionError:
        same_tracked = False
    df_tracked = (
        float(np.max(np.abs(tracked["frequency_hz"] - batch_tracked["frequency_hz"])))
        if len(tracked) == len(batch_tracked)
        else float("nan")
    )
    counts = blocks["block_length_s"].value_counts().sort_index()
    return {
        "voyage": folder.name,
        "blocks min": minutes,
        "started": started.strftime("%H:%M:%SZ"),
        "blocks": len(blocks),
        "lengths": ", ".join(f"{n}x{length / 60:g}" for length, n in counts.items()),
        "lengths equal": same_lengths,
        "selected rows": f"{len(selected)}/{len(batch_selected)}",
        "max |df| selected [Hz]": df_selected,
        "tracked equal": same_tracked,
        "max |df| tracked [Hz]": df_tracked,
        "batch s/block": batch_s / len(blocks),
        "monitor s/block": monitor_s / len(blocks),
        "monitor to last block s/block": to_last_block_s / len(blocks),
        "ratio": monitor_s / batch_s,
        "ratio to last block": to_last_block_s / batch_s,
    }


def live(folder: Path, speed: float) -> dict:
    """Feed the voyage in *folder* to a live monitor (after :func:`compare`'s auto pair,
    whose batch tables it is compared with); what it gave and took."""
    import json
    import os
    import resource
    import signal

    from bench_monitor import _ShipLog

    from workbench.identification.adaptive import AdaptiveBlockOptions, decision_span
    from workbench.signals.block_plan import read_file_info

    work = folder / "monitor_bench_live"
    shutil.rmtree(work, ignore_errors=True)
    watch, state = work / "watch", work / "state"
    watch.mkdir(parents=True)
    log = _ShipLog(folder / "dship.tsv", work / "dship.tsv")
    files = sorted((folder / "accelerations").glob("*.npz"))
    infos = [read_file_info(p) for p in files]
    batch = folder / "monitor_bench_auto"
    expected = len(pd.read_csv(batch / "batch" / "blocks.csv"))
    command = [
        sys.executable, "-c", _CODE, "monitor", "--watch", watch, "--state", state,
        "--dship", log.target, "--block-minutes", "auto", "--poll", "0.25", "--settle", "0.5",
        "--flush-after", "10", "--quiet",
    ]  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(work / "monitor.log", "w", encoding="utf-8") as stderr:
        process = subprocess.Popen(
            list(map(str, command)), stderr=stderr, stdout=subprocess.DEVNULL
        )
        time.sleep(3.0)  # start-up (imports) is not part of a block's time
        origin = time.time()
        t0 = infos[0].start_time
        landed = []  # (data end, wall time it landed)
        for path, info in zip(files, infos, strict=True):
            due = origin + (info.end_time - t0).total_seconds() / speed
            time.sleep(max(0.0, due - time.time()))
            tmp = watch / f".{path.name}.part"
            shutil.copyfile(path, tmp)
            os.replace(tmp, watch / path.name)
            log.until(info.end_time)
            landed.append((info.end_time, pd.Timestamp(time.time(), unit="s", tz="UTC")))
        log.until(None)
        deadline = time.time() + 900
        while time.time() < deadline:
            try:
                status = json.loads((state / "status.json").read_text())
            except (OSError, ValueError):
                status = {}
            if status.get("blocks_done") == expected:
                break
            time.sleep(0.2)
        time.sleep(2.0)
        process.send_signal(signal.SIGTERM)
        code = process.wait(timeout=600)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    tracked = pd.read_parquet(state / "tracked.parquet")
    try:
        pd.testing.assert_frame_equal(tracked, pd.read_parquet(batch / "batch_tracked.parquet"))
        same = True
    except AssertionError:
        same = False
    lengths = _store_table(state / "store", "lengths").sort_values("block")
    blocks = pd.read_csv(batch / "batch" / "blocks.csv")
    same_lengths = np.array_equal(lengths["block_length_s"], blocks["block_length_s"])
    health = pd.read_parquet(state / "data_health.parquet").set_index("block")
    options = AdaptiveBlockOptions()
    half = pd.Timedelta(seconds=options.step_s / 2)
    waits, flushed = [], []
    data_end = landed[-1][0]
    for block in health.index:
        span_end = t0 + half * decision_span(block, options)[1]
        if span_end > data_end:  # decided at the end of the input
            flushed.append(block)
            continue
        completing = next(when for end, when in landed if end >= span_end)
        waits.append((health.loc[block, "identified_at"] - completing).total_seconds())
    waits = np.array(waits)
    return {
        "voyage": folder.name,
        "exit": code,
        "blocks": len(health),
        "lengths equal": same_lengths,
        "tracked equal": same,
        "CPU s/block": cpu / len(health),
        "span landed -> state, median s": float(np.median(waits)),
        "90 %": float(np.percentile(waits, 90)),
        "worst": float(waits.max()),
        "decided at the end": f"{len(flushed)} (blocks {flushed[0]}-{flushed[-1]})",
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_voyage_arguments(parser, "0,1,2,3,4")
    parser.add_argument(
        "--also-fixed",
        metavar="MIN",
        help="run the pair with fixed blocks of MIN minutes too (the monitor's ratio before "
        "auto was monitored), each voyage's fixed pair right after its auto pair",
    )
    parser.add_argument("--live", type=int, metavar="SEED", help="feed this voyage live too")
    parser.add_argument("--speed", type=float, default=60.0, help="replay speed of --live")
    args = parser.parse_args(argv)
    found = voyages(args)
    if found is None:
        return 2
    runs = ["auto"] + ([args.also_fixed] if args.also_fixed else [])
    rows = [compare(folder, minutes) for _, folder in found for minutes in runs]
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 250, "display.max_columns", 30):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    for minutes, part in table.groupby("blocks min", sort=False):
        print(
            f"\n--block-minutes {minutes}: all equal: blocks {part['lengths equal'].all()}, "
            f"tracked {part['tracked equal'].all()}; ratio monitor / batch: median "
            f"{part['ratio'].median():.3f} (to the last block "
            f"{part['ratio to last block'].median():.3f})"
        )
    if args.live is not None:
        folder = dict(found).get(args.live)
        if folder is None:
            print(f"--live {args.live}: not among --seeds", file=sys.stderr)
            return 2
        row = live(folder, args.speed)
        print(f"\nlive at {args.speed:g}x ({folder.name}):")
        for key, value in row.items():
            print(f"  {key}: {value:.3g}" if isinstance(value, float) else f"  {key}: {value}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
