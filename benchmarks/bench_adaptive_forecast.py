"""The forecast on blocks of varying length: Kalman against raw SSI, with and without the
block-length measurement scale.

Each seed's ice voyage of :mod:`bench_adaptive_blocks` (same folders, identified once with
``--block-minutes auto``) is tracked, its ship log averaged onto the blocks with the auto
run's excitation weights (``--excitation``), and forecast with the defaults (model memory,
option A, rolling). Four forecasts per seed:

* ``no poles``: the tracked pole only, every block's measurement variance alike (before)
  or T_ref / T_k with the block length (after,
  :func:`~workbench.forecasting.measurement.length_scales`);
* ``poles``: with the pole table, the cluster scatter across model orders as the recorded
  per-block uncertainty (before), or the length's scale where the recorded scatter does not
  explain the residuals at least as well (after,
  :func:`~workbench.forecasting.measurement.recorded_uncertainty_holds`).

"Before" runs the same code with the block lengths withheld from the forecast (they are
then one length to it). The scale was measured and not kept (identification_32d.txt); on a
tree without it, one forecast per measurement is printed (``length scale`` "none"). Scored on the forecast rows against each block's truth (the
simulator's file truths averaged over the block's span, as in
:mod:`bench_adaptive_blocks`); a tracked mode is the true mode nearest its median
frequency (within 2 %). Printed per seed and stretch: the median and 90th percentile of
|df|/f of the raw SSI estimate and of the Kalman estimate, and Kalman vs SSI = 1 -
median Kalman / median SSI (positive: the Kalman estimate is the better).

Where identify recorded the blocks' halves (``half_difference_hz``), each forecast runs with
the SSI guard (``guard`` "on", :mod:`workbench.forecasting.ssi_guard`) and with the column
withheld ("off"); tables identified before the column read "none".

``--runs`` adds the fixed-length runs of the same voyages (``fixed 20 min``, the product's
default, and ``fixed 5 min``; their log averaged over each block's span): the blend
against raw SSI where an unlogged ice load moves the modes by 1-2 % with a 4-minute
correlation (:data:`workbench.simulate.voyage.ICE_FREQUENCY_DROP`).

Run: ``python benchmarks/bench_adaptive_forecast.py [--seeds 0,1,2,3,4] [--hours 4]
[--ice-hours 1.5] [--work /tmp/bench_adaptive] [--runs "auto,fixed 20 min,fixed 5 min"]``.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import warnings
from pathlib import Path
from unittest import mock

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_adaptive_blocks as adaptive  # noqa: E402


def _has_length_scale() -> bool:
    """Whether the forecast has the block-length scale (commit 70c0fe9 of issue-32-s39;
    not kept: benchmarks/results/identification_32d.txt)."""
    from workbench.forecasting.memory import forecast

    return hasattr(forecast, "block_lengths_s")


def _forecast(modal, predictors, poles, *, lengths: bool) -> pd.DataFrame:
    from workbench.forecasting import ForecastOptions
    from workbench.stages.forecasting import forecast

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if lengths:
            result = forecast(modal, predictors, poles=poles, options=ForecastOptions())
        else:  # the block lengths withheld: every block one length to the forecast
            with mock.patch(
                "workbench.forecasting.memory.forecast.block_lengths_s", lambda grid: None
            ):
                result = forecast(modal, predictors, poles=poles, options=ForecastOptions())
    table = result.table
    return table[table["phase"] == "forecast"]


def run_seed(folder: Path, seed: int, run: str = "auto") -> list[dict]:
    from workbench.predictors import load_predictors
    from workbench.stages.tracking import track

    selected = adaptive.identify(folder, run)
    blocks, _ = adaptive.score(folder, selected)
    truth = blocks.pivot(index="block", columns="mode", values="truth_hz")
    modal = track(selected).table
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        predictors = load_predictors(
            dship=folder / "dship.tsv",
            onto=modal,
            excitation=folder / "run_auto" / "excitation.csv" if run == "auto" else None,
        )
    poles = pd.read_parquet(selected.parent / "poles.parquet")
    cases = adaptive.stretches(folder)
    ice = cases.loc[cases["case"] == "ice", "start"]
    ice_start = pd.Timestamp(ice.iat[0]) if len(ice) else None
    level = truth.median()
    rows = []
    # the SSI guard measures against the blocks' halves (identify's half_difference_hz);
    # "off" is the same forecast with the column withheld
    guards = ("off", "on") if "half_difference_hz" in modal.columns else ("none",)
    for recorded, lengths, guard in itertools.product(
        ("no poles", "poles"), (False, True) if _has_length_scale() else (True,), guards
    ):
        table = _forecast(
            modal if guard != "off" else modal.drop(columns="half_difference_hz"),
            predictors,
            poles if recorded == "poles" else None,
            lengths=lengths,
        )
        scored = []
        for _, part in table.groupby("mode"):
            f = part["ssi_frequency_hz"].median()
            nearest = int((level / f - 1).abs().idxmin())
            if abs(level[nearest] / f - 1) > 0.02:
                continue
            t = truth[nearest].reindex(part["block"]).to_numpy()
            scored.append(
                pd.DataFrame(
                    {
                        "block_start": pd.to_datetime(part["block_start"], utc=True),
                        "ssi": np.abs(part["ssi_frequency_hz"].to_numpy() / t - 1),
                        "kalman": np.abs(part["kalman_frequency_hz"].to_numpy() / t - 1),
                    }
                )
            )
        scored = pd.concat(scored, ignore_index=True)
        scored = scored[np.isfinite(scored["ssi"]) & np.isfinite(scored["kalman"])]
        for stretch in ("ice", "open water", "all"):
            if stretch == "all" or ice_start is None:
                part = scored
            elif stretch == "ice":
                part = scored[scored["block_start"] >= ice_start]
            else:
                part = scored[scored["block_start"] < ice_start]
            ssi, kalman = part["ssi"].median(), part["kalman"].median()
            rows.append(
                {
                    "seed": seed,
                    "blocks": run,
                    "stretch": stretch,
                    "measurement": recorded,
                    "length scale": ("on" if lengths else "off") if _has_length_scale() else "none",
                    "guard": guard,
                    "rows": len(part),
                    "ssi median": ssi,
                    "ssi p90": part["ssi"].quantile(0.9),
                    "kalman median": kalman,
                    "kalman p90": part["kalman"].quantile(0.9),
                    "kalman vs ssi %": 100 * (1 - kalman / ssi),
                }
            )
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    adaptive.add_voyage_arguments(parser, "0,1,2,3,4")
    parser.add_argument(
        "--runs",
        default="auto",
        help="block runs, comma-separated: auto, 'fixed 20 min', 'fixed 5 min'",
    )
    args = parser.parse_args(argv)
    runs = [r.strip() for r in args.runs.split(",") if r.strip()]
    unknown = [r for r in runs if r not in adaptive.RUNS]
    if unknown or not runs:
        print(f"--runs: give some of {', '.join(adaptive.RUNS)}", file=sys.stderr)
        return 2
    voyage_list = adaptive.voyages(args)
    if voyage_list is None:
        return 2
    seeds = [seed for seed, _ in voyage_list]
    rows = []
    for seed, folder in voyage_list:
        for run in runs:
            rows += run_seed(folder, seed, run)
    table = pd.DataFrame(rows)
    keys = ["blocks", "stretch", "measurement", "length scale", "guard"]
    if len(seeds) > 1:
        values = ["ssi median", "kalman median", "kalman vs ssi %"]
        median = table.groupby(keys, sort=False)[values].median().reset_index()
        median.insert(0, "seed", "median")
        worst = table.groupby(keys, sort=False).agg(
            **{
                "ssi median": ("ssi median", "max"),
                "kalman median": ("kalman median", "max"),
                "kalman vs ssi %": ("kalman vs ssi %", "min"),
            }
        )
        worst = worst.reset_index()
        worst.insert(0, "seed", "worst")
        table = pd.concat([table, median, worst], ignore_index=True)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
