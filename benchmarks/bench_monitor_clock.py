"""The ship log's clock check as the monitor runs it: when it decides, what it says, and
what it costs.

    python benchmarks/bench_monitor_clock.py --root /tmp/clock

The voyages of bench_dship_clock.py (kept in ROOT and reused: simulated, then identified
with ``--dship``). Each voyage's blocks are handed to the monitor's check
(:class:`workbench.monitor.log_clock.LiveClockCheck`) in block order, as the monitor
identifies them, with the log as it stands then: the correct log up to the newest block's
end, a log kept by a clock *s* hours ahead of UTC (its times moved by *s*, read as UTC) up
to that end plus *s* (what the logger has written by then). The check runs when due (from
24 blocks, then every 12 until it decides). Then the cost of one check on 10 days of
blocks (the 24-h voyage's channels and log repeated ten times). Results:
benchmarks/results/dship_clock_50.txt.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pandas as pd
from bench_dship_clock import SHIFTS_H, VOYAGES, voyages_root


def _named_h(warning: str | None) -> float:
    found = re.search(r"offset ([+-])(\d\d):(\d\d)$", warning or "")
    if not found:
        return np.nan
    return (int(found[2]) + int(found[3]) / 60) * (-1 if found[1] == "-" else 1)


def replay(root: Path) -> pd.DataFrame:
    from data_contracts import read_dship
    from workbench.monitor.log_clock import LiveClockCheck

    rows = []
    for name in VOYAGES:
        folder = root / name
        channels = pd.read_csv(folder / "id" / "channels.csv", parse_dates=["block_start"])
        by_block = dict(tuple(channels.groupby("block", sort=True)))
        log = read_dship(folder / "dship.tsv")
        for shift in (0.0, *SHIFTS_H):
            moved = log.assign(time=log["time"] + pd.Timedelta(hours=shift))
            check, seconds, said_at = LiveClockCheck(), [], None
            for block, table in by_block.items():
                check.add(table, 1200.0)
                if not check.due():
                    continue
                end = table["block_start"].iloc[0] + pd.Timedelta(minutes=20)
                written = moved[moved["time"] <= end + pd.Timedelta(hours=shift)]
                start = time.perf_counter()
                warning = check.check(written, "log")
                seconds.append(time.perf_counter() - start)
                if warning is not None:
                    said_at = block + 1
                if check.decided:
                    break
            rows.append(
                {
                    "voyage": name,
                    "blocks": len(by_block),
                    "shift_h": shift,
                    "named_h": _named_h(check.warning),
                    "said_at_block": said_at,
                    "checks": len(check.checked_blocks),
                    "decided_at": check.checked_blocks[-1] if check.decided else np.nan,
                    "seconds": max(seconds) if seconds else np.nan,
                }
            )
    return pd.DataFrame(rows)


def ten_days(root: Path) -> tuple[int, float, float]:
    """A check at day 10 (the 24-h voyage's blocks and log repeated ten times): the blocks
    it reads and its seconds, the median of 20 runs, with the 10-day log and with the log's
    newest 2 days."""
    from data_contracts import read_dship
    from workbench.monitor.log_clock import WINDOW_H, LiveClockCheck

    folder = root / "v24_s7"
    channels = pd.read_csv(folder / "id" / "channels.csv", parse_dates=["block_start"])
    log = read_dship(folder / "dship.tsv")
    day = pd.Timedelta(hours=24)
    n = int(channels["block"].max()) + 1
    days = [
        channels.assign(
            block=channels["block"] + k * n, block_start=channels["block_start"] + k * day
        )
        for k in range(10)
    ]
    logs = pd.concat([log.assign(time=log["time"] + k * day) for k in range(10)], ignore_index=True)
    seconds = {}
    for name, ship_log in (
        ("10 days", logs),
        ("2 days", logs[logs["time"] >= logs["time"].max() - 2 * day]),
    ):
        runs = []
        for _ in range(20):
            check = LiveClockCheck()  # days 9 and 10 held: the check lets day 9 go
            for table in days[-2:]:
                check.add(table, 1200.0)
            start = time.perf_counter()
            check.check(ship_log, "log")
            runs.append(time.perf_counter() - start)
        seconds[name] = float(np.median(runs))
    starts = days[-1]["block_start"].drop_duplicates()
    window = int((starts >= starts.max() - pd.Timedelta(hours=WINDOW_H)).sum())
    return window, seconds["10 days"], seconds["2 days"]


def summary(table: pd.DataFrame) -> list[str]:
    lines = []
    for (name, blocks), group in table.groupby(["voyage", "blocks"], sort=False):
        cells = []
        for _, row in group.iterrows():
            if np.isfinite(row["named_h"]):
                verdict = f"UTC{row['named_h']:+g} at {int(row['said_at_block'])}"
            elif np.isfinite(row["decided_at"]):
                verdict = f"agrees at {int(row['decided_at'])}"
            else:
                verdict = f"undecided ({row['checks']} checks)"
            cells.append(f"{row['shift_h']:+g}: {verdict}")
        lines.append(f"{name:<10} {blocks:>4} blocks  " + "; ".join(cells))
    correct = table[table["shift_h"] == 0]
    shifted = table[table["shift_h"] != 0]
    right = (shifted["named_h"] == shifted["shift_h"]).sum()
    wrong = (shifted["named_h"].notna() & (shifted["named_h"] != shifted["shift_h"])).sum()
    lines.append(
        f"correct logs: {int(correct['named_h'].notna().sum())} false alarms in "
        f"{len(correct)} voyages; shifted logs: {right} right offsets, {wrong} wrong, "
        f"{int(shifted['named_h'].isna().sum())} silent of {len(shifted)}"
    )
    lines.append(
        f"checks per voyage and log: median {table['checks'].median():g}, max "
        f"{table['checks'].max()}; seconds per check: max {table['seconds'].max():.4f}"
    )
    return lines


def main() -> None:
    root = voyages_root(__doc__.splitlines()[0])
    print("\n".join(summary(replay(root))))
    blocks, whole, recent = ten_days(root)
    print(
        f"a check at day 10: {blocks} blocks (the newest 24 h), {whole:.4f} s with the 10-day "
        f"log, {recent:.4f} s with its last 2 days"
    )


if __name__ == "__main__":
    main()
