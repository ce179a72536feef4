"""A ship log whose clock is not the accelerations': false alarms and power of identify's
clock check, and what a +2 h local log does to the chain.

    python benchmarks/bench_dship_clock.py --root /tmp/clock        # the check
    python benchmarks/bench_dship_clock_chain.py VOYAGE OUT          # the demo chain

Voyages (simulated, then identified with ``--dship``; kept in ROOT and reused): open water
of 4, 6, 6, 12, 12, 12 and 24 h, 8 h ending in 3 h of ice, and two 6-h voyages at rest
(the profile's stationary case throughout). For each voyage, its whole length, its
stationary stretches and its 3-, 4- and 6-h windows are checked with the correct log
(shift 0) and with the log as a clock 2, -3, 5.5, 1 and 0.5 h ahead of UTC would have
written it without an offset (its times moved by that much, read as UTC): a false alarm
is a warning on the correct log; on a shifted one the warning should name that shift.
Results: benchmarks/results/dship_clock_50.txt.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

VOYAGES = {
    "v4_s4": ["--hours", "4", "--seed", "4"],
    "v6_s2": ["--hours", "6", "--seed", "2"],
    "v6_s3": ["--hours", "6", "--seed", "3"],
    "v12_s0": ["--hours", "12", "--seed", "0"],
    "v12_s1": ["--hours", "12", "--seed", "1"],
    "v12_s6": ["--hours", "12", "--seed", "6"],
    "v24_s7": ["--hours", "24", "--seed", "7"],
    "ice8_s5": ["--hours", "8", "--ice-hours", "3", "--seed", "5"],
    "stat6_s10": None,  # at rest throughout
    "stat6_s11": None,
}
SHIFTS_H = (2.0, -3.0, 5.5, 1.0, 0.5)


def _workbench(*argv) -> None:
    subprocess.run([sys.executable, "-m", "workbench", *argv], check=True, capture_output=True)


def _stationary_voyage(folder: Path, seed: int, hours: float) -> None:
    import workbench.simulate.profile as profile
    from workbench.simulate import simulate_voyage

    profile.CASE_FRACTIONS = (("stationary", 1.0),)
    simulate_voyage(folder, seed=seed, hours=hours)


def make_voyages(root: Path) -> None:
    for name, argv in VOYAGES.items():
        folder = root / name
        if (folder / "id" / "channels.csv").exists():
            continue
        if argv is None:
            seed = int(name.split("_s")[1])
            code = "import sys; sys.path.insert(0, 'benchmarks'); import bench_dship_clock as b; "
            code += f"b._stationary_voyage(__import__('pathlib').Path({str(folder)!r}), {seed}, 6)"
            subprocess.run([sys.executable, "-c", code], check=True)
        else:
            _workbench("simulate", "--out", str(folder), *argv, "-q")
        _workbench(
            "identify", str(folder / "accelerations"), "--out", str(folder / "id"),
            "--dship", str(folder / "dship.tsv"), "-q", "--stabilisation-figures", "0",
        )  # fmt: skip


def _subsets(level: pd.DataFrame, cases: pd.DataFrame) -> dict[str, pd.DataFrame]:
    starts = level["block_start"]
    block = pd.Timedelta(minutes=20)
    out = {"all": level}
    inside = np.zeros(len(level), bool)
    for _, case in cases[cases["case"] == "stationary"].iterrows():
        inside |= ((starts >= case["start"]) & (starts + block <= case["end"])).to_numpy()
    out["stationary"] = level[inside]
    for hours in (3, 4, 6):
        for k in range(0, 48, hours):
            lo = starts.min() + pd.Timedelta(hours=k)
            window = level[(starts >= lo) & (starts + block <= lo + pd.Timedelta(hours=hours))]
            if len(window) >= 12 * hours - 6:
                out[f"{hours}h window from {k} h"] = window
    return out


def check(root: Path) -> pd.DataFrame:
    from data_contracts import read_dship
    from workbench.predictors.clock import block_level, clock_shift_scores, clock_warning

    rows = []
    for name in VOYAGES:
        folder = root / name
        level = block_level(pd.read_csv(folder / "id" / "channels.csv"))
        log = read_dship(folder / "dship.tsv")
        cases = pd.read_csv(folder / "cases.csv")
        for column in ("start", "end"):
            cases[column] = pd.to_datetime(cases[column], utc=True)
        for subset, blocks in _subsets(level, cases).items():
            for shift in (0.0, *SHIFTS_H):
                moved = log.assign(time=log["time"] + pd.Timedelta(hours=shift))
                start = time.perf_counter()
                scores = clock_shift_scores(blocks, 1200.0, moved)
                warning = clock_warning(scores, "log")
                seconds = time.perf_counter() - start
                found = re.search(r"offset ([+-])(\d\d):(\d\d)$", warning or "")
                named = np.nan
                if found:
                    named = (int(found[2]) + int(found[3]) / 60) * (-1 if found[1] == "-" else 1)
                rows.append(
                    {
                        "voyage": name,
                        "subset": subset,
                        "blocks": len(blocks),
                        "shift_h": shift,
                        "named_h": named,
                        "seconds": seconds,
                    }
                )
    return pd.DataFrame(rows)


def summary(table: pd.DataFrame) -> list[str]:
    lines = []
    correct, shifted = table[table["shift_h"] == 0], table[table["shift_h"] != 0]
    lines.append(
        f"correct logs: {len(correct)} checks on {correct['voyage'].nunique()} voyages, "
        f"{int(correct['named_h'].notna().sum())} false alarms"
    )
    kind = shifted["voyage"].str.extract(r"^(ice|stat)")[0].fillna("open water")
    kind = kind.where(shifted["subset"] != "stationary", "stationary stretch")
    result = np.where(
        shifted["named_h"].isna(),
        "silent",
        np.where(shifted["named_h"] == shifted["shift_h"], "right offset", "wrong offset"),
    )
    span = np.where(shifted["subset"] == "all", "whole voyage", shifted["subset"].str[:2])
    lines.append("shifted logs (+2, -3, +5.5, +1, +0.5 h), warnings by voyage kind and span:")
    crossed = pd.crosstab([kind.rename("kind"), pd.Series(span, index=shifted.index, name="span")],
                          pd.Series(result, index=shifted.index, name="result"))  # fmt: skip
    lines += crossed.to_string().splitlines()
    lines.append(
        f"seconds per check (scores + decision): median {table['seconds'].median():.4f}, "
        f"max {table['seconds'].max():.4f}"
    )
    return lines


def voyages_root(description: str) -> Path:
    """``--root`` of the command line (*description*: its help), with the voyages made
    there (kept and reused)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--root", type=Path, required=True)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    args.root.mkdir(parents=True, exist_ok=True)
    make_voyages(args.root)
    return args.root


def main() -> None:
    root = voyages_root(__doc__.splitlines()[0])
    print("\n".join(summary(check(root))))


if __name__ == "__main__":
    main()
