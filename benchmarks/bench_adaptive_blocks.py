"""Adaptive against fixed block lengths on a voyage with an ice stretch and speed changes.

Each seed simulates a voyage (``workbench simulate --hours H --ice-hours I``: station,
transit at 10 kn, 0-10 kn alternation, then ice breaking with ramming, strong intermittent
excitation and frequencies changing by 1-2 % within minutes) and identifies it three
times with identify's defaults otherwise: fixed 20-min blocks, fixed 5-min blocks (both
every 5 min) and ``--block-minutes auto`` (with the ship log). Scored against the
simulator's truth of every 5-min file (``truth_files.csv``):

* **path error** (the measure that holds error and time resolution together): the true
  frequency path sampled every 5 min (each file's true frequency at the file's centre)
  against the identified one, linearly interpolated in time between the centres of the
  blocks that found the mode; |df|/f per file and mode, over the files every run covers.
  A long block smears a fast change, a short one scatters: both show up here.
* **block error x length**: each found mode's |df|/f against its block's own truth (the
  mean of the file truths over the block's span) times the block's length in minutes;
  median over blocks and modes. Small is good: accurate and sharp in time. It grows as
  sqrt(length) where nothing changes (the error falls only as 1/sqrt(length)), so it
  favours the shortest block even in a steady stretch.
* **block error² x length** (the variance-time product): each found mode's (|df|/f)²
  against its block's own truth times the block's length in minutes; median over blocks
  and modes. For a pure 1/sqrt(length) scatter it is the same for every length, so it
  rewards a short block only where a long one would smear a change and a long block only
  where the stretch is steady: neutral between resolution and averaging.

A true mode is found in a block when a selected (non-harmonic) mode lies within
0.4 x its distance to the nearest other true mode (at most 2 %), one-to-one. Printed per
seed, stretch (``ice`` / ``open water``) and run: blocks, median block length, found share,
the median and 90th percentile of the path error, the median block error and the medians of
block error x length and block error² x length.

A second table checks what SSI reads in a fixed 20-min block whose excitation changes
(speed changes, ice): each found mode's relative error against the block's time-mean truth
and against its excitation-weighted truth (file truths weighted by the files' excitation
power from the auto run's ``excitation.csv``), by the block's excitation range. Where the
weighted truth is the closer one, the predictors should be averaged with the same weights
(``--excitation``).

A third table gives the auto run's block lengths per stretch.

Run: ``python benchmarks/bench_adaptive_blocks.py [--seeds 0,1,2] [--hours 4]
[--ice-hours 1.5] [--work /tmp/bench_adaptive]`` (a voyage and its runs are reused when
their folders exist).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

RUNS = ("fixed 20 min", "fixed 5 min", "auto")


def simulate(folder: Path, seed: int, hours: float, ice_hours: float) -> None:
    from workbench.simulate import simulate_voyage

    if not (folder / "truth_files.csv").exists():
        simulate_voyage(folder, seed=seed, hours=hours, ice_hours=ice_hours)


def identify(folder: Path, run: str) -> Path:
    """Selected table of *run* on the voyage in *folder* (identified once)."""
    from dataclasses import replace

    from workbench.identification import IdentifyOptions, identify_voyage
    from workbench.identification.adaptive import identify_adaptive

    out = folder / ("run_" + run.replace(" ", "_"))
    selected = out / "selected.parquet"
    if selected.exists():
        return selected
    options = IdentifyOptions()
    inputs = [folder / "accelerations"]
    common = {"scheduler": "synchronous", "dship": folder / "dship.tsv"}
    if run == "auto":
        identify_adaptive(inputs, out, options=options, **common)
    else:
        minutes = 20.0 if run == "fixed 20 min" else 5.0
        options = replace(options, length_s=60 * minutes, step_s=300.0)
        identify_voyage(inputs, out, options=options, **common)
    return selected


def _assign(truth: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """Estimate per true mode (NaN where not found), one-to-one within the tolerance."""
    separation = np.abs(truth[:, None] / truth[None, :] - 1.0)
    np.fill_diagonal(separation, np.inf)
    tolerance = np.minimum(0.4 * separation.min(axis=1), 0.02)
    out = np.full(truth.size, np.nan)
    if estimate.size:
        distance = np.abs(estimate[None, :] / truth[:, None] - 1.0)
        cost = np.where(distance < tolerance[:, None], distance, 1e6)
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] < 1e6
        out[rows[ok]] = estimate[cols[ok]]
    return out


def score(folder: Path, selected_path: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per (block, mode): estimate, block truth, length; per (file, mode): path error."""
    truth = pd.read_csv(folder / "truth_files.csv", parse_dates=["file_start", "file_end"])
    paths = truth.pivot(index="file_start", columns="mode", values="frequency_hz")
    file_start = pd.DatetimeIndex(paths.index)
    file_mid = file_start + pd.Timedelta(seconds=150)
    f_files = paths.to_numpy()
    selected = pd.read_parquet(selected_path)
    if "harmonic" in selected.columns:
        selected = selected[selected["harmonic"].isna()]
    rows = []
    for block, part in selected.groupby("block"):
        start = pd.Timestamp(part["block_start"].iat[0])
        end = pd.Timestamp(part["block_end"].iat[0])
        inside = (file_start >= start - pd.Timedelta(seconds=1)) & (
            file_start + pd.Timedelta(seconds=300) <= end + pd.Timedelta(seconds=1)
        )
        if not inside.any():  # a block starting inside a file: the files it overlaps
            inside = (file_start < end) & (file_start + pd.Timedelta(seconds=300) > start)
        block_truth = f_files[inside].mean(axis=0)
        estimate = _assign(block_truth, part["frequency_hz"].to_numpy(dtype=float))
        for m in range(block_truth.size):
            rows.append(
                {
                    "block": int(block),
                    "mode": m + 1,
                    "centre": start + (end - start) / 2,
                    "length_min": (end - start).total_seconds() / 60,
                    "truth_hz": block_truth[m],
                    "estimate_hz": estimate[m],
                }
            )
    blocks = pd.DataFrame(rows)
    path_rows = []
    for m in range(f_files.shape[1]):
        part = blocks[(blocks["mode"] == m + 1) & blocks["estimate_hz"].notna()]
        part = part.sort_values("centre")
        t = (pd.DatetimeIndex(part["centre"]) - file_start[0]).total_seconds().to_numpy()
        tf = (file_mid - file_start[0]).total_seconds().to_numpy()
        inside = (tf >= t.min()) & (tf <= t.max()) if t.size else np.zeros(tf.size, bool)
        estimate = np.interp(tf, t, part["estimate_hz"].to_numpy()) if t.size else tf * np.nan
        for j in np.flatnonzero(inside):
            path_rows.append(
                {
                    "file_start": file_start[j],
                    "mode": m + 1,
                    "error": abs(estimate[j] / f_files[j, m] - 1.0),
                }
            )
    return blocks, pd.DataFrame(path_rows)


def stretches(folder: Path) -> pd.DataFrame:
    cases = pd.read_csv(folder / "cases.csv", parse_dates=["start", "end"])
    return cases


def summarise(folder: Path, seed: int) -> list[dict]:
    cases = stretches(folder)
    ice = cases[cases["case"] == "ice"]
    ice_start = pd.Timestamp(ice["start"].iat[0]) if len(ice) else None
    scored = {run: score(folder, identify(folder, run)) for run in RUNS}
    # the files every run's path covers (interpolation between block centres)
    common = None
    for _, path in scored.values():
        keys = set(zip(path["file_start"], path["mode"], strict=True))
        common = keys if common is None else common & keys
    out = []
    for run, (blocks, path) in scored.items():
        keep = [k in common for k in zip(path["file_start"], path["mode"], strict=True)]
        path = path[keep]
        for stretch in ("ice", "open water", "all"):
            if stretch == "all" or ice_start is None:
                b, p = blocks, path
            elif stretch == "ice":
                b = blocks[blocks["centre"] >= ice_start]
                p = path[path["file_start"] >= ice_start]
            else:
                b = blocks[blocks["centre"] < ice_start]
                p = path[path["file_start"] < ice_start]
            found = b["estimate_hz"].notna()
            error = (b["estimate_hz"] / b["truth_hz"] - 1.0).abs()[found]
            product = error * b["length_min"][found]
            variance_time = error**2 * b["length_min"][found]
            out.append(
                {
                    "seed": seed,
                    "stretch": stretch,
                    "run": run,
                    "blocks": int(b["block"].nunique()),
                    "median length min": float(b.drop_duplicates("block")["length_min"].median()),
                    "found": float(found.mean()) if len(b) else math.nan,
                    "path median": float(p["error"].median()) if len(p) else math.nan,
                    "path p90": float(p["error"].quantile(0.9)) if len(p) else math.nan,
                    "block median": float(error.median()) if len(error) else math.nan,
                    "error x length": float(product.median()) if len(product) else math.nan,
                    "error2 x length": float(variance_time.median())
                    if len(variance_time)
                    else math.nan,
                }
            )
    return out


def weighting(folder: Path, seed: int) -> pd.DataFrame:
    """Fixed 20-min blocks: error against the time-mean and the excitation-weighted truth."""
    truth = pd.read_csv(folder / "truth_files.csv", parse_dates=["file_start"])
    paths = truth.pivot(index="file_start", columns="mode", values="frequency_hz")
    file_start = pd.DatetimeIndex(paths.index)
    excitation = pd.read_csv(folder / "run_auto" / "excitation.csv", parse_dates=["start"])
    power = (
        excitation.groupby(excitation["start"].dt.floor("300s"))["power"]
        .mean()
        .reindex(file_start)
        .to_numpy()
    )
    cases = stretches(folder)
    ice = cases.loc[cases["case"] == "ice", "start"]
    ice_start = pd.Timestamp(ice.iat[0]) if len(ice) else None
    selected = pd.read_parquet(folder / "run_fixed_20_min" / "selected.parquet")
    if "harmonic" in selected.columns:
        selected = selected[selected["harmonic"].isna()]
    rows = []
    for _, part in selected.groupby("block"):
        start, end = part["block_start"].iat[0], part["block_end"].iat[0]
        inside = (file_start >= start) & (file_start < end)
        weights = power[inside]
        if inside.sum() != 4 or not np.all(np.isfinite(weights) & (weights > 0)):
            continue
        f = paths.to_numpy()[inside]
        plain = f.mean(axis=0)
        weighted = (weights[:, None] * f).sum(axis=0) / weights.sum()
        estimate = _assign(plain, part["frequency_hz"].to_numpy(dtype=float))
        for m in np.flatnonzero(np.isfinite(estimate)):
            rows.append(
                {
                    "seed": seed,
                    "stretch": "ice"
                    if ice_start is not None and start >= ice_start
                    else "open water",
                    "range_db": 10 * np.log10(weights.max() / weights.min()),
                    "vs time mean": estimate[m] / plain[m] - 1.0,
                    "vs weighted": estimate[m] / weighted[m] - 1.0,
                }
            )
    return pd.DataFrame(rows)


def add_voyage_arguments(parser: argparse.ArgumentParser, seeds: str) -> None:
    """The ice voyages' flags (seeds, length, ice stretch, work folder), shared with
    ``bench_adaptive_forecast.py``."""
    parser.add_argument("--seeds", default=seeds, help="voyage seeds, comma-separated")
    parser.add_argument("--hours", type=float, default=4.0, help="voyage length [h]")
    parser.add_argument("--ice-hours", type=float, default=1.5, help="ice stretch [h]")
    parser.add_argument("--work", type=Path, default=Path("/tmp/bench_adaptive"))


def voyages(args: argparse.Namespace) -> list[tuple[int, Path]] | None:
    """(seed, folder) of each voyage *args* name, simulated where missing; None (the
    reason printed) when --seeds is not 1 to 20 whole numbers."""
    try:
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    except ValueError:
        print(f"--seeds {args.seeds!r} must be whole numbers separated by commas", file=sys.stderr)
        return None
    if not 1 <= len(seeds) <= 20:
        print("--seeds: give 1 to 20 seeds", file=sys.stderr)
        return None
    out = []
    for seed in seeds:
        folder = args.work / f"h{args.hours:g}_ice{args.ice_hours:g}_seed{seed}"
        simulate(folder, seed, args.hours, args.ice_hours)
        out.append((seed, folder))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_voyage_arguments(parser, "0,1,2")
    args = parser.parse_args(argv)
    voyage_list = voyages(args)
    if voyage_list is None:
        return 2
    seeds = [seed for seed, _ in voyage_list]
    rows, weights, lengths = [], [], []
    for seed, folder in voyage_list:
        rows += summarise(folder, seed)
        weights.append(weighting(folder, seed))
        blocks = pd.read_csv(folder / "run_auto" / "blocks.csv", parse_dates=["block_start"])
        cases = stretches(folder)
        ice = cases.loc[cases["case"] == "ice", "start"]
        in_ice = blocks["block_start"] >= (
            pd.Timestamp(ice.iat[0])
            if len(ice)
            else blocks["block_start"].max() + pd.Timedelta(days=1)
        )
        blocks["stretch"] = np.where(in_ice, "ice", "open water")
        lengths.append(blocks.assign(seed=seed))
    table = pd.DataFrame(rows)
    if len(seeds) > 1:
        pooled = (
            table.groupby(["stretch", "run"], sort=False)[
                [
                    "path median",
                    "path p90",
                    "block median",
                    "error x length",
                    "error2 x length",
                    "found",
                ]
            ]
            .median()
            .reset_index()
        )
        pooled.insert(0, "seed", "median")
        table = pd.concat([table, pooled], ignore_index=True)
    weights = pd.concat(weights, ignore_index=True)
    weights["excitation range"] = pd.cut(weights["range_db"], [0, 1, 3, 6, 100])
    bias = (
        weights.groupby(["stretch", "excitation range"], observed=True)
        .agg(
            modes=("vs time mean", "size"),
            median_vs_time_mean=("vs time mean", "median"),
            median_vs_weighted=("vs weighted", "median"),
            abs_vs_time_mean=("vs time mean", lambda x: np.median(np.abs(x))),
            abs_vs_weighted=("vs weighted", lambda x: np.median(np.abs(x))),
        )
        .reset_index()
    )
    lengths = pd.concat(lengths, ignore_index=True)
    lengths["minutes"] = lengths["block_length_s"] / 60
    counts = lengths.groupby(["stretch", "minutes"]).size().unstack(fill_value=0)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        print("\nfixed 20-min blocks: identified frequency against the block's truth")
        print(bias.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        print("\nauto: blocks per length [min], all seeds")
        print(counts.to_string())
    return 0


if __name__ == "__main__":
    sys.exit(main())
