"""A hole in the acceleration record (the recorder off for 30 min to half the voyage): the
forecast against raw SSI after the hole, beside the same voyage without the hole.

Each voyage is simulated and identified once, as the README's worked example does
(``workbench simulate``, ``workbench identify --band 2 12 --dship ... --blades 5``); a hole
of H hours from ``--hole-start`` takes out the blocks whose span meets it (the blocks
``identify`` skips when those files are missing: ``skipped: no data`` or ``gap of ...``;
each block is identified from its own files, so the other blocks are the same), then
``workbench track`` and ``workbench forecast --option both`` (the command line's defaults)
run on what is left. Printed per voyage, hole and option (median and worst over the seeds):

* after: the Kalman estimate against raw SSI (1 - sum |K - truth| / sum |SSI - truth|, all
  forecast modes paired with the truth, in %) over the blocks with data in the
  ``--after-hours`` after the hole; ``nohole``: the same blocks of the voyage without it;
* whole: the same over every forecast block with data;
* in-hole: the share of the hole's rows whose truth lies within the estimate's 95 % band
  (K +- 1.96 ``kalman_std_hz``), and the RMS of (K - truth) / ``kalman_std_hz``: how honest
  the filter's variance is where it only predicts;
* ``no forecast`` where the forecast stage gives none (main: a mode's presence counted the
  hole's blocks as blocks it was absent from).

Run: ``python benchmarks/bench_forecast_hole.py --seeds 0,1,2 --work /tmp/hole``
(``benchmarks/results/forecast_hole_52.txt``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

#: (voyage hours, hole hours): the brief's 6-h voyage with 3 h (half) out, and a 12-h
#: voyage with 30 min, 3 h and 6 h (half) out.
CASES = ((6.0, 3.0), (12.0, 0.5), (12.0, 3.0), (12.0, 6.0))


def _cli(*args: str) -> int:
    from workbench.cli import main

    quiet = contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO())
    with quiet[0], quiet[1], warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return main([*args, "-q"])


def identified(work: Path, hours: float, seed: int) -> Path:
    """Folder of the simulated voyage and its identification (made once)."""
    folder = work / f"v{hours:g}h_seed{seed}"
    if not (folder / "identified" / "selected.parquet").is_file():
        assert (
            _cli("simulate", "--out", str(folder), "--hours", f"{hours:g}", "--seed", str(seed))
            == 0
        )
        code = _cli(
            "identify",
            str(folder / "accelerations"),
            "--out",
            str(folder / "identified"),
            "--band",
            "2",
            "12",
            "--dship",
            str(folder / "dship.tsv"),
            "--blades",
            "5",
        )
        assert code == 0, code
    return folder


def hole_blocks(selected: pd.DataFrame, start_h: float, hours: float) -> set[int]:
    """Blocks whose span meets the hole [start, start + hours)."""
    t0 = pd.Timestamp(selected["block_start"].min())
    lo = t0 + pd.Timedelta(hours=start_h)
    hi = lo + pd.Timedelta(hours=hours)
    spans = selected.drop_duplicates("block")
    meet = (pd.to_datetime(spans["block_start"]) < hi) & (pd.to_datetime(spans["block_end"]) > lo)
    return set(spans.loc[meet, "block"].astype(int))


def run_case(folder: Path, out: Path, drop: set[int]) -> tuple[pd.DataFrame | None, pd.DataFrame]:
    """track + forecast with the blocks *drop* taken out: the forecast table (None when the
    forecast stage gives none) and the tracked table."""
    out.mkdir(parents=True, exist_ok=True)
    for name in ("selected.parquet", "poles.parquet"):
        table = pd.read_parquet(folder / "identified" / name)
        table[~table["block"].isin(drop)].to_parquet(out / name)
    assert _cli("track", str(out / "selected.parquet"), "--out", str(out / "tracked.csv")) == 0
    code = _cli(
        "forecast",
        "--modal",
        str(out / "tracked.csv"),
        "--dship",
        str(folder / "dship.tsv"),
        "--poles",
        str(out / "poles.parquet"),
        "--option",
        "both",
        "--out",
        str(out / "forecast.csv"),
    )
    tracked = pd.read_csv(out / "tracked.csv")
    if code != 0:
        return None, tracked
    return pd.read_csv(out / "forecast.csv"), tracked


def scored(forecast: pd.DataFrame, tracked: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Forecast rows with the true frequency of their mode (the tracked labels paired with
    the true modes as ``workbench evaluate`` pairs them)."""
    from workbench.sid.tracking import label_agreement

    rows = forecast[forecast["phase"] == "forecast"]
    _, mapping = label_agreement(tracked, truth)
    rows = rows[rows["mode"].isin(mapping)].copy()
    rows["true_mode"] = rows["mode"].map(mapping)
    truth = truth.rename(columns={"mode": "true_mode", "frequency_hz": "truth_hz"})
    return rows.merge(truth[["block", "true_mode", "truth_hz"]], on=["block", "true_mode"])


def gain(rows: pd.DataFrame) -> float:
    rows = rows.dropna(subset=["ssi_frequency_hz"])
    ssi = (rows["ssi_frequency_hz"] - rows["truth_hz"]).abs().sum()
    kalman = (rows["kalman_frequency_hz"] - rows["truth_hz"]).abs().sum()
    return float(100.0 * (1.0 - kalman / ssi)) if ssi > 0 else float("nan")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0,1,2")
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--hole-start", type=float, default=2.0, help="[h] from the voyage's start")
    parser.add_argument("--after-hours", type=float, default=2.0)
    parser.add_argument("--out", type=Path, help="CSV of the rows")
    args = parser.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    records = []
    runs = args.work / "runs"
    for hours, hole_h in CASES:
        for seed in seeds:
            folder = identified(args.work, hours, seed)
            selected = pd.read_parquet(folder / "identified" / "selected.parquet")
            truth = pd.read_csv(folder / "truth_modal.csv")
            drop = hole_blocks(selected, args.hole_start, hole_h)
            tag = f"{hours:g}h_hole{hole_h:g}h_seed{seed}"
            nohole, nohole_tracked = run_case(folder, runs / f"{hours:g}h_seed{seed}_nohole", set())
            holed, holed_tracked = run_case(folder, runs / tag, drop)
            end = max(drop) + 1
            after_end = end + int(round(args.after_hours * 12))
            for option in ("A", "B"):
                record = {
                    "voyage_h": hours,
                    "hole_h": hole_h,
                    "seed": seed,
                    "option": option,
                    "hole_blocks": len(drop),
                }
                base = scored(nohole[nohole["option"] == option], nohole_tracked, truth)
                after = base["block"].between(end, after_end - 1)
                record["nohole_after"] = gain(base[after])
                record["nohole_whole"] = gain(base)
                if holed is None:
                    record["forecast"] = "no forecast"
                else:
                    rows = scored(holed[holed["option"] == option], holed_tracked, truth)
                    record["forecast"] = f"{rows['mode'].nunique()} modes"
                    record["after"] = gain(rows[rows["block"].between(end, after_end - 1)])
                    record["whole"] = gain(rows)
                    inside = rows[rows["block"].isin(drop)]
                    z = (inside["kalman_frequency_hz"] - inside["truth_hz"]) / inside[
                        "kalman_std_hz"
                    ]
                    record["in_hole_within_95"] = float(100.0 * (np.abs(z) <= 1.96).mean())
                    record["in_hole_rms_z"] = float(np.sqrt(np.mean(z**2)))
                records.append(record)
                print(record, file=sys.stderr, flush=True)
    table = pd.DataFrame(records)
    if args.out:
        table.to_csv(args.out, index=False)
    pd.set_option("display.width", 200)
    print(table.to_string(index=False, float_format=lambda v: f"{v:+.1f}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
