"""Shaft orders crossing the modes: the Kalman blend's options A and B against raw SSI.

The voyages of ``bench_harmonics.py`` (``ramps``: orders 1 and 2 and the blade pass sweep
across the modes on the speed ramps; ``sitting``: order 1 on mode 1 through the stretch at
7 kn, order 2 on mode 7 through the stretch at 10 kn), identified once each (SSI-cov, the
demo's band), marked three ways from the same store (``no log``, ``rpm``: the ship log
with its shaft speed, ``speed only``: without it), tracked (``workbench track``) and
forecast (``workbench forecast``: the stage, options A and B, the default settings).

Printed per scenario, log and option, over the seeds: the rows of the forecast phase in
the blocks where an order sits on the mode (at least 20 % of an order's energy, weighted by
speed⁴ from the true 1-s speed, within 2 % of the mode's true frequency: ``crossing``) and
elsewhere, with the sums of the relative errors [%] of raw SSI (the tracked pole) and of
the blend; for option B the rows it measured and the rows whose measured column sits on an
order line (20 % of an order's energy within 0.5 %) and is more than 0.5 % off the truth
(a harmonic taken). Then every (voyage, log, option, mode) whose blend's summed error in
its crossing blocks exceeds raw SSI's.

Run: ``python benchmarks/bench_harmonics_forecast.py [--seeds 0 1 2] [--hours 6]
[--work DIR]``; the output is kept in ``benchmarks/results/harmonics_option_b_52.txt``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_harmonics as harmonics_bench  # noqa: E402

from data_contracts import read_dship  # noqa: E402
from workbench.forecasting import ForecastOptions  # noqa: E402
from workbench.predictors import canonical_predictors, load_predictors  # noqa: E402
from workbench.sid.harmonics import HarmonicOptions, mark_harmonics  # noqa: E402
from workbench.sid.tracking import label_agreement  # noqa: E402
from workbench.stages import forecast, track  # noqa: E402

#: A measured column within this relative distance of an order line sits on it.
ON_LINE = 0.005


def voyage_rows(name: str, seed: int, hours: float, work: Path) -> pd.DataFrame:
    """Forecast rows of one voyage, per log variant and option, scored against the truth."""
    shaft = harmonics_bench.SCENARIOS[name]
    voyage, selected, poles, _ = harmonics_bench._identified(
        work / f"{name}_{seed}", shaft, seed, hours, 2
    )
    truth = pd.read_csv(voyage.truth_modal, parse_dates=["block_start", "block_end"])
    log = read_dship(voyage.dship_log)
    blocks = selected[["block", "block_start", "block_end"]].drop_duplicates("block")
    shares = harmonics_bench._order_shares(harmonics_bench._true_speed(voyage), blocks, shaft)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        predictors = canonical_predictors(
            load_predictors(dship=voyage.dship_log, onto=selected.drop_duplicates("block"))
        )
    true_hz = truth.pivot(index="block", columns="mode", values="frequency_hz")
    rows = []
    for variant, variant_log in (
        ("no log", None),
        ("rpm", log),
        ("speed only", log.drop(columns="shaft_rpm")),
    ):
        marks = mark_harmonics(selected, poles, variant_log, HarmonicOptions(blades=shaft.blades))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tracked = track(marks.selected).table
            table = forecast(
                tracked, predictors, poles=marks.poles, options=ForecastOptions(options=("A", "B"))
            ).table
        _, mapping = label_agreement(tracked, truth)
        raw = tracked[["block", "mode", "frequency_hz"]].drop_duplicates(["block", "mode"])
        part = table[table["phase"] == "forecast"].merge(
            raw.rename(columns={"frequency_hz": "tracked_hz"}), on=["block", "mode"], how="left"
        )
        for row in part.itertuples(index=False):
            if row.mode not in mapping:
                continue
            f_true = true_hz.loc[row.block, mapping[row.mode]]
            share = shares[int(row.block)]
            measured = row.ssi_frequency_hz
            on_line = bool(
                row.option == "B" and np.isfinite(measured) and share(measured, ON_LINE) >= 0.2
            )
            rows.append(
                {
                    "scenario": name,
                    "seed": seed,
                    "log": variant,
                    "option": row.option,
                    "mode": mapping[row.mode],
                    "crossing": harmonics_bench._crossed(share, f_true),
                    "raw": abs(row.tracked_hz / f_true - 1),
                    "kalman": abs(row.kalman_frequency_hz / f_true - 1),
                    "measured": bool(np.isfinite(measured)),
                    "harmonic_taken": on_line and abs(measured / f_true - 1) > ON_LINE,
                }
            )
    return pd.DataFrame(rows)


def _cell(part: pd.DataFrame, option: str) -> str:
    text = f"{len(part):5d} {100 * part['raw'].sum():7.2f} {100 * part['kalman'].sum():7.2f}"
    if option == "B":
        text += f" ({int(part['measured'].sum())}, {int(part['harmonic_taken'].sum())})"
    return text


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--hours", type=float, default=6.0)
    parser.add_argument(
        "--scenarios",
        nargs="+",
        default=list(harmonics_bench.SCENARIOS),
        choices=harmonics_bench.SCENARIOS,
    )
    parser.add_argument("--work", type=Path, help="folder for the voyages (default: temporary)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        frames = [
            voyage_rows(name, seed, args.hours, work)
            for name in args.scenarios
            for seed in args.seeds
        ]
    rows = pd.concat(frames, ignore_index=True)
    print(
        "scenario log        option | crossing blocks: rows, summed |error| [%] of raw SSI "
        "and of the blend (B: rows measured, harmonics taken) | elsewhere: the same"
    )
    for (name, log, option), part in rows.groupby(["scenario", "log", "option"], sort=False):
        print(
            f"{name:8s} {log:10s} {option:6s} | {_cell(part[part['crossing']], option):32s} "
            f"| {_cell(part[~part['crossing']], option)}"
        )
    keys = ["scenario", "seed", "log", "option", "mode"]
    sums = rows[rows["crossing"]].groupby(keys)[["raw", "kalman"]].sum()
    counts = rows[rows["crossing"]].groupby(keys).size()
    worse = sums[sums["kalman"] > sums["raw"]]
    print(f"\nblend worse than raw SSI over a mode's crossing blocks: {len(worse)} of {len(sums)}")
    for key, row in worse.iterrows():
        print(
            f"    {' '.join(map(str, key))}: raw {100 * row['raw']:.3f} %, blend "
            f"{100 * row['kalman']:.3f} % ({counts[key]} blocks)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
