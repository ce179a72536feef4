"""Gaps in the ship's log: the forecast with every predictor missing for a stretch.

A ship's data system drops out (a network switch, a logger restart): for that stretch the
log has timestamps and empty cells. Each case is an 8-h voyage of ``workbench simulate``
(its own sensor dropouts included: water temperature or wind missing for 20-40 min) whose
log is cut again, every column empty, for

* ``none``  — nothing more cut (the voyage as simulated),
* ``short`` — 40 min (03:20-04:00),
* ``long``  — 2 h (03:00-05:00),

(``--gaps`` places other cuts: in every seed of the simulator the ship stops at 03:20 and
runs again at about 03:40, so ``short`` always begins with a stop the log does not record;
``--gaps short=150-190`` cuts 40 min in which the ship holds its speed), then run through
the command line as a user runs it (``workbench forecast --option both``,
``workbench evaluate`` against the simulator's true modal table). Printed per seed, gap and
option: the Kalman estimate against raw SSI over the whole voyage (``workbench evaluate``'s
summary), the same over the gap's blocks only, and the share of the gap's blocks whose
model bounds (95 %) hold the truth; Kalman against SSI over the cut's edge blocks too (those
it overlaps by at most half, averaged over their logged part: ``edge``). Beside each gap
row: the same voyage with its log complete (``complete``: the forecast that knows the
missing values, the reachable), over the gap's blocks.

Run: ``python benchmarks/bench_log_gaps.py --seeds 1,2,3,4 --work /tmp/log_gaps``
(about 10 minutes on 2 quiet cores).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_forecast_new_user import _workbench  # noqa: E402

#: Cut stretches [minute of the voyage, end minute).
GAPS = {"none": None, "short": (200, 240), "long": (180, 300)}


def cut_log(source: Path, target: Path, minutes: tuple[int, int] | None) -> None:
    """*source* (a PANGAEA-style DSHIP export) with every value of the rows whose time of day
    falls in *minutes* removed (the timestamps kept)."""
    lines = source.read_text(encoding="utf-8").split("\n")
    header = next(k for k, line in enumerate(lines) if line.startswith("*/")) + 1
    out = lines[: header + 1]
    for line in lines[header + 1 :]:
        fields = line.split("\t")
        if minutes is not None and line:
            minute = int(fields[0][11:13]) * 60 + int(fields[0][14:16])
            if minutes[0] <= minute < minutes[1]:
                fields = [fields[0]] + [""] * (len(fields) - 1)
        out.append("\t".join(fields))
    target.write_text("\n".join(out), encoding="utf-8")


def _overlap(forecast: pd.DataFrame, minutes: tuple[int, int]) -> np.ndarray:
    """Minutes of each row's 20-min block inside the cut stretch."""
    start = pd.to_datetime(forecast["block_start"], utc=True)
    minute = (start - start.min()).dt.total_seconds() / 60.0
    return (np.minimum(minute + 20, minutes[1]) - np.maximum(minute, minutes[0])).to_numpy()


def gap_blocks(forecast: pd.DataFrame, minutes: tuple[int, int] | None) -> np.ndarray:
    """Blocks whose 20-min span overlaps the cut stretch by more than half (their log
    averages are missing)."""
    if minutes is None:
        return np.array([], dtype=int)
    return np.unique(forecast.loc[_overlap(forecast, minutes) > 10, "block"].to_numpy())


def edge_blocks(forecast: pd.DataFrame, minutes: tuple[int, int] | None) -> np.ndarray:
    """Blocks whose span overlaps the cut stretch by at most half: their log averages are
    of the logged part only (``block_predictors``' coverage of 0.5), the forecast takes them
    as the block's."""
    if minutes is None:
        return np.array([], dtype=int)
    overlap = _overlap(forecast, minutes)
    return np.unique(forecast.loc[(overlap > 0) & (overlap <= 10), "block"].to_numpy())


def scores(forecast: pd.DataFrame, truth: pd.DataFrame, blocks: np.ndarray | None) -> dict:
    """Kalman against SSI [%] and the bounds' coverage on *blocks* (None: all) per option."""
    rows = forecast[forecast["phase"] == "forecast"].merge(
        truth[["block", "mode", "frequency_hz"]].rename(columns={"frequency_hz": "true"}),
        on=["block", "mode"],
    )
    if blocks is not None:
        rows = rows[rows["block"].isin(blocks)]
    out = {}
    for option, part in rows.groupby("option"):
        both = part.dropna(subset=["ssi_frequency_hz", "kalman_frequency_hz"])
        ssi = (both["ssi_frequency_hz"] - both["true"]).abs().sum()
        kalman = (both["kalman_frequency_hz"] - both["true"]).abs().sum()
        inside = (part["model_lower_hz"] <= part["true"]) & (part["true"] <= part["model_upper_hz"])
        out[option] = (100.0 * (1.0 - kalman / ssi) if ssi > 0 else np.nan, inside.mean())
    return out


def parse_gaps(text: str) -> dict:
    """``NAME=START-END,...`` (minutes of the voyage) as a gaps dict, ``none`` first."""
    gaps: dict = {"none": None}
    for item in text.split(","):
        name, _, span = item.partition("=")
        start, _, end = span.partition("-")
        if not (name and name != "none" and start.isdigit() and end.isdigit()) or int(start) >= int(
            end
        ):
            raise ValueError(f"--gaps item {item!r}: NAME=START-END in minutes, START < END")
        gaps[name] = (int(start), int(end))
    return gaps


def run_seed(seed: int, work: Path, gaps: dict = GAPS) -> list[dict]:
    folder = work / f"seed{seed}"
    voyage = folder / "voyage"
    if not (voyage / "truth_modal.csv").is_file():
        _workbench("simulate", "--out", str(voyage), "--hours", "8", "--seed", str(seed))
    truth = pd.read_csv(voyage / "truth_modal.csv")
    tables = {}
    for gap, minutes in gaps.items():
        log = folder / f"dship_{gap}.tsv"
        cut_log(voyage / "dship.tsv", log, minutes)
        out = folder / f"forecast_{gap}.csv"
        _workbench(
            "forecast", "--modal", str(voyage / "tracked_modal.csv"), "--dship", str(log),
            "--poles", str(voyage / "poles.parquet"), "--option", "both", "--out", str(out),
        )  # fmt: skip
        tables[gap] = pd.read_csv(out)
    rows = []
    for gap, minutes in gaps.items():
        blocks = gap_blocks(tables[gap], minutes)
        edges = edge_blocks(tables[gap], minutes)
        whole = scores(tables[gap], truth, None)
        inside = scores(tables[gap], truth, blocks) if blocks.size else {}
        reach = scores(tables["none"], truth, blocks) if blocks.size else {}
        edge = scores(tables[gap], truth, edges) if edges.size else {}
        for option, (gain, _) in whole.items():
            rows.append(
                {
                    "seed": seed,
                    "gap": gap,
                    "option": option,
                    "K_vs_ssi_pct": gain,
                    "gap_blocks": blocks.size,
                    "in_gap_K_vs_ssi_pct": inside.get(option, (np.nan, np.nan))[0],
                    "in_gap_bounds_hold": inside.get(option, (np.nan, np.nan))[1],
                    "complete_log_in_gap_pct": reach.get(option, (np.nan, np.nan))[0],
                    "edge_K_vs_ssi_pct": edge.get(option, (np.nan, np.nan))[0],
                }
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1,2,3,4", help="comma-separated seeds")
    parser.add_argument("--work", type=Path, default=Path("/tmp/log_gaps"))
    parser.add_argument(
        "--gaps",
        default="short=200-240,long=180-300",
        help="cut stretches NAME=START-END in minutes of the voyage, comma-separated",
    )
    args = parser.parse_args()
    try:
        gaps = parse_gaps(args.gaps)
    except ValueError as error:
        parser.error(str(error))  # one line, exit 2
    rows = []
    for seed in (int(s) for s in args.seeds.split(",")):
        rows += run_seed(seed, args.work, gaps)
    table = pd.DataFrame(rows)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.round(3).to_string(index=False))
        summary = table.groupby(["gap", "option"]).agg(
            median=("K_vs_ssi_pct", "median"),
            worst=("K_vs_ssi_pct", "min"),
            in_gap_median=("in_gap_K_vs_ssi_pct", "median"),
            in_gap_worst=("in_gap_K_vs_ssi_pct", "min"),
            bounds_hold=("in_gap_bounds_hold", "median"),
            complete_log=("complete_log_in_gap_pct", "median"),
            edge_median=("edge_K_vs_ssi_pct", "median"),
            edge_worst=("edge_K_vs_ssi_pct", "min"),
        )
        print()
        print(summary.round(3).to_string())


if __name__ == "__main__":
    main()
