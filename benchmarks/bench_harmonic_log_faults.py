"""Shaft harmonics when the ship log is faulty: do harmonics leak into the tracked modes?

The voyages of ``bench_harmonics.py`` (scenarios ``ramps`` and ``sitting``), shorter (6 h:
every case of the profile, at half length), simulated with ``workbench simulate`` and
identified once with ``workbench identify`` (band 2-12 Hz) into ``--work``. Each voyage's
ship log is then damaged as a user meets it (the ``dship.tsv`` file rewritten with empty
cells, rows cut, a frozen or spiking shaft speed), read with :func:`read_dship`, and the
harmonics are marked (:class:`~workbench.sid.harmonics.HarmonicMarker`, what ``identify
--dship`` does) and the modes tracked (``workbench track``'s defaults).

Faults (hours from the voyage's start; the 6-h profile: at rest 0-1 h, 10 kn 1-2.5 h,
0 <-> 10 kn ramps 2.5-4.5 h, 7 kn 4.5-6 h):

* ``rpm nan``, ``speed nan``, ``all nan``: empty cells (shaft speed only; speed only;
  every column) for 90 min from 1.25, 3.0 or 4.5 h, and for 30 min from 3.0 h;
* ``rpm 2nd half``: the shaft-speed cells empty from 3 h on;
* ``ends early`` / ``starts late``: the log's rows cut 1 h before the accelerations end /
  until 1 h after they start; ``only the first 30 min`` / ``only the last 45 min``: a log
  that covers a few blocks of the voyage;
* ``rpm frozen``: the shaft speed stuck at its reading for 60 min from 1.25, 3.0 or 4.5 h;
* ``rpm spike``: one shaft-speed reading 10 times its value (at 1.5, 3.2 and 5 h: three
  single rows);
* ``no rpm``: the shaft-speed column left out (``simulate --no-shaft-rpm``'s log), clean
  and with the speed's cells empty as in ``speed nan``.

Printed per voyage and fault: true modes tracked (of 7), the true modes' tracked rows (and
the difference from the clean log's run), harmonic labels (tracked labels not paired with
a true mode, most of whose rows have at least 5 % of an order's energy within 2 %: the
scoring of ``bench_harmonics.py``) with their blocks, other labels, and the ship-log
warnings (:meth:`HarmonicMarker.unmarked`).

Run: ``python benchmarks/bench_harmonic_log_faults.py --work DIR [--seeds 0 1 2]``; the
output is kept in ``benchmarks/results/harmonics_log_faults_52.txt``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_harmonics import (  # noqa: E402
    SCENARIOS,
    _order_shares,
    _score,
    _steady,
    _true_speed,
)

from data_contracts import read_dship  # noqa: E402
from workbench.sid.harmonics import HarmonicMarker, HarmonicOptions  # noqa: E402
from workbench.sid.tracking import TrackingOptions, track_modes  # noqa: E402

HOURS = 6.0
RPM = "Shaft speed [rpm]"
SPEED = "Speed [kn]"


def _voyage(work: Path, name: str, seed: int) -> Path:
    """Simulate and identify one voyage (once: kept in *work*)."""
    folder = work / f"{name}_{seed}"
    shaft = SCENARIOS[name]
    run = {"check": True, "timeout": 600}
    if not (folder / "voyage" / "voyage.json").exists():
        subprocess.run(
            ["workbench", "simulate", "--out", str(folder / "voyage"), "--seed", str(seed)]
            + ["--hours", f"{HOURS:g}", "--shaft-orders", "1,2", "--blades", str(shaft.blades)]
            + ["--shaft-hz-per-kn", f"{shaft.hz_per_kn:g}", "-q"],
            **run,
        )
    if not (folder / "identify" / "selected.parquet").exists():
        subprocess.run(
            ["workbench", "identify", str(folder / "voyage" / "accelerations")]
            + ["--out", str(folder / "identify"), "--band", "2", "12", "-q"],
            **run,
        )
    return folder


def _read_raw(path: Path) -> tuple[str, pd.DataFrame]:
    """The PANGAEA header (through ``*/``) and the data rows as text cells."""
    text = path.read_text(encoding="utf-8")
    head, _, body = text.partition("*/\n")
    lines = body.splitlines()
    columns = lines[0].split("\t")
    rows = [line.split("\t") for line in lines[1:]]
    return head + "*/\n", pd.DataFrame(rows, columns=columns)


def _write_raw(path: Path, head: str, table: pd.DataFrame) -> Path:
    body = "\n".join(["\t".join(table.columns), *("\t".join(r) for r in table.to_numpy())])
    path.write_text(head + body + "\n", encoding="utf-8")
    return path


def _hours(table: pd.DataFrame, start: pd.Timestamp) -> np.ndarray:
    times = pd.to_datetime(table["Date/Time"]).dt.tz_localize("UTC")
    return ((times - start).dt.total_seconds() / 3600.0).to_numpy()


def _faults() -> list[tuple[str, object]]:
    """(name, function of (table, hours) -> damaged table)."""

    def empty(columns, start, length):
        def apply(table, hours):
            table = table.copy()
            inside = (hours >= start) & (hours < start + length)
            for column in columns(table):
                table.loc[inside, column] = ""
            return table

        return apply

    def every(table):
        return [c for c in table.columns if c != "Date/Time"]

    def frozen(start, length):
        def apply(table, hours):
            table = table.copy()
            inside = np.flatnonzero((hours >= start) & (hours < start + length))
            table.loc[table.index[inside], RPM] = table[RPM].iat[inside[0] - 1]
            return table

        return apply

    def spike(table, hours):
        table = table.copy()
        for at in (1.5, 3.2, 5.0):
            row = int(np.argmin(np.abs(hours - at)))
            table.loc[table.index[row], RPM] = f"{10 * float(table[RPM].iat[row]):.1f}"
        return table

    def cut(keep):
        def apply(table, hours):
            return table[keep(hours)].reset_index(drop=True)

        return apply

    def no_rpm(damage=None):
        def apply(table, hours):
            table = table.drop(columns=RPM)
            return damage(table, hours) if damage else table

        return apply

    stretches = [(1.25, 1.5), (3.0, 1.5), (4.5, 1.5), (3.0, 0.5)]
    faults = [("clean", lambda table, hours: table)]
    for what, columns in (
        ("rpm nan", lambda t: [RPM]),
        ("speed nan", lambda t: [SPEED]),
        ("all nan", every),
    ):
        for start, length in stretches:
            label = f"{what} {start:g}-{start + length:g} h"
            faults.append((label, empty(columns, start, length)))
    faults.append(("rpm 2nd half", empty(lambda t: [RPM], HOURS / 2, HOURS)))
    faults.append(("ends early (1 h)", cut(lambda h: h < HOURS - 1.0)))
    faults.append(("starts late (1 h)", cut(lambda h: h >= 1.0)))
    faults.append(("only the first 30 min", cut(lambda h: h < 0.5)))
    faults.append(("only the last 45 min", cut(lambda h: h >= HOURS - 0.75)))
    for start in (1.25, 3.0, 4.5):
        faults.append((f"rpm frozen {start:g}-{start + 1:g} h", frozen(start, 1.0)))
    faults.append(("rpm spike x10 (3 rows)", spike))
    faults.append(("no rpm", no_rpm()))
    for start, length in stretches:
        label = f"no rpm, speed nan {start:g}-{start + length:g} h"
        faults.append((label, no_rpm(empty(lambda t: [SPEED], start, length))))
    return faults


def _run(folder: Path, name: str, seed: int, out: Path, only=None) -> list[dict]:
    voyage = types.SimpleNamespace(
        seed=seed, hours=HOURS, start_time=pd.Timestamp("2024-03-01T00:00:00Z")
    )
    selected = pd.read_parquet(folder / "identify" / "selected.parquet").drop(
        columns=["harmonic", "harmonic_frequency_hz"], errors="ignore"
    )
    truth = pd.read_csv(
        folder / "voyage" / "truth_modal.csv", parse_dates=["block_start", "block_end"]
    )
    blocks = selected[["block", "block_start", "block_end"]].drop_duplicates("block")
    speed = _true_speed(voyage)
    shares = _order_shares(speed, blocks, SCENARIOS[name])
    steady = _steady(speed, blocks)
    options = HarmonicOptions(blades=SCENARIOS[name].blades)
    head, raw = _read_raw(folder / "voyage" / "dship.tsv")
    hours = _hours(raw, voyage.start_time)
    rows = []
    for fault, damage in _faults():
        if only and fault not in only:
            continue
        path = _write_raw(out / f"{name}_{seed}_dship.tsv", head, damage(raw, hours))
        started = time.perf_counter()
        try:
            log = read_dship(path)
        except Exception as error:  # noqa: BLE001 - reported in the table
            rows.append({"fault": fault, "error": f"{type(error).__name__}: {error}"})
            continue
        marker = HarmonicMarker(log, options)
        marked = marker.mark_selected(selected)
        tracked = track_modes(marked, options=TrackingOptions())
        score = _score(tracked, truth, shares, steady, {})
        true_rows = int(
            tracked["mode"].isin(_true_labels(tracked, truth)).sum() if len(tracked) else 0
        )
        rows.append(
            {
                "fault": fault,
                "method": marker.method,
                "modes": score["modes"],
                "true_rows": true_rows,
                "harmonic": score["harmonic"],
                "other": score["other"],
                "warnings": marker.unmarked(),
                "seconds": time.perf_counter() - started,
            }
        )
    return rows


def _true_labels(tracked: pd.DataFrame, truth: pd.DataFrame) -> list[int]:
    from workbench.sid.tracking import label_agreement

    _, mapping = label_agreement(tracked, truth)
    return list(mapping)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=SCENARIOS)
    parser.add_argument("--faults", nargs="+", help="only these faults (names as printed)")
    args = parser.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    print(
        "voyage     fault                              method      modes  true rows (vs clean)"
        "  harmonic labels (blocks)  other labels (blocks)  warning"
    )
    totals: dict[str, list] = {}
    for name in args.scenarios:
        for seed in args.seeds:
            folder = _voyage(args.work, name, seed)
            rows = _run(folder, name, seed, args.work, args.faults)
            clean = next((r for r in rows if r["fault"] == "clean"), None)
            for row in rows:
                if "error" in row:
                    print(f"{name}_{seed:<4d} {row['fault']:34s} ERROR {row['error']}")
                    continue
                diff = row["true_rows"] - clean["true_rows"] if clean else 0
                harmonic = ",".join(str(n) for n in row["harmonic"]) or "-"
                other = ",".join(str(n) for n in row["other"]) or "-"
                warning = "; ".join(w.split(":")[1].strip() for w in row["warnings"]) or "-"
                print(
                    f"{name}_{seed:<4d} {row['fault']:34s} {row['method']:11s} "
                    f"{row['modes']:3d}/7 {row['true_rows']:5d} ({diff:+4d})  "
                    f"{len(row['harmonic']):3d} ({harmonic:>10s})  "
                    f"{len(row['other']):3d} ({other:>6s})  {warning}",
                    flush=True,
                )
                total = totals.setdefault(row["fault"], [0, 0, 0, 0])
                total[0] += len(row["harmonic"])
                total[1] += sum(row["harmonic"])
                total[2] += 7 - row["modes"]
                total[3] += diff
    print("\nper fault over the voyages: harmonic labels (blocks), true modes lost, true rows")
    for fault, (labels, blocks, lost, diff) in totals.items():
        print(f"  {fault:34s} {labels:3d} ({blocks:4d})  {lost:2d}  {diff:+5d}")
    print(json.dumps({f: t[0] for f, t in totals.items()}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
