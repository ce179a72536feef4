"""How SSI reads the modes of bench_close_weak.py: the data's own error and SSI's, per rule.

Issue 32 (identification_32h.txt): SSI's one spurious mode on the held-out seeds is the
upper mode of a 1 % pair read 0.41 % low (the benchmark's tolerance is 0.396 %). Whether a
rule of the selection could read it better is a question of how much of SSI's error is the
record's and how much the estimator's. For every block of the cases of
``benchmarks/bench_close_weak.py`` (the same records and SSI-cov identification,
``_identify_method`` with ``identify``'s defaults) this prints, per selected SSI mode:

* the *oracle* reading: the record projected on its true modal coordinates (the
  pseudo-inverse of the simulator's mode shapes, which no estimator knows) and each
  coordinate identified alone by SSI-cov at model order 2 (one mode, the same block rows).
  What is left in it is the record's own error (the modal forces' realisation and the
  sensor noise), not the mixing of neighbouring modes;
* the mode's frequency under other rules of reading a column of the stabilisation diagram
  (its poles, one per model order, as the selection clustered them): the median of all
  orders (what the selection reports), the lower or upper half of its orders, the mean,
  a 25 % trimmed mean, and by the poles' modal phase collinearity (a pole whose shape is
  complex is taken to mix its neighbour in: MPC-weighted median, the upper half by MPC,
  weights 1 / (1 - MPC)).

Printed per group (close 1 %, close 2-3 %, weak) and mode (pair's lower / upper mode, the
weak mode, the others): median and largest |df|/f against the truth, the readings beyond
the benchmark's tolerance, and the median |df|/f against the oracle; the oracle's own
spread and its correlation with SSI's error; every SSI reading of a pair's mode beyond
the tolerance with its oracle; and, per rule applied to the modes with a selected
neighbour within 3 % only, how many case x 60-seed cells of the benchmark's score
(found, spurious, median and worst |df|/f) it changes against all orders.

Run: ``python benchmarks/bench_pair_readings.py [--seeds 60] [--first-seed 0]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_close_weak as close_weak  # noqa: E402


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    order = np.argsort(values)
    cumulative = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])


def _half(values: np.ndarray, order: np.ndarray, upper: bool) -> float:
    ranked = values[np.argsort(order, kind="stable")]
    lower = (ranked.size + 1) // 2
    return float(np.median(ranked[ranked.size // 2 :] if upper else ranked[:lower]))


def _drift_test(f: np.ndarray, mpc: np.ndarray, order: np.ndarray) -> float:
    """LSCF's reading (identification_32g.txt): the lower half where the column drifts."""
    from workbench.sid.selection import _consistent_orders

    rank = np.argsort(np.argsort(order, kind="stable"))
    return float(np.median(f[_consistent_orders(np.arange(f.size), f, rank)]))


RULES = {
    "all orders": lambda f, mpc, order: float(np.median(f)),
    "drift test": _drift_test,
    "lower half": lambda f, mpc, order: _half(f, order, upper=False),
    "upper half": lambda f, mpc, order: _half(f, order, upper=True),
    "mean": lambda f, mpc, order: float(np.mean(f)),
    "trimmed": lambda f, mpc, order: float(np.mean(np.sort(f)[f.size // 4 : f.size - f.size // 4])),
    "MPC-weighted": lambda f, mpc, order: _weighted_median(f, mpc),
    "MPC upper half": lambda f, mpc, order: float(np.median(f[mpc >= np.median(mpc)])),
    "1/(1-MPC)": lambda f, mpc, order: _weighted_median(f, 1.0 / np.maximum(1.0 - mpc, 1e-4)),
}


def columns(result, options) -> dict[float, np.ndarray]:
    """The poles (row positions in ``result.poles``) of each mode the selection reports,
    keyed by the mode's frequency: the selection run again with its cluster statistics
    recorded (deterministic: the same modes as ``identify``'s)."""
    import workbench.sid.selection as selection

    recorded = []
    original = selection._cluster_statistics

    def recording(f, z, members, rank=None):
        statistics = original(f, z, members, rank)
        recorded.append((statistics["frequency_hz"], f[members].copy()))
        return statistics

    selection._cluster_statistics = recording
    try:
        selection.select_modes(
            result,
            selection=options.selection,
            band_hz=options.selection_band(result.sampling_rate_hz),
            damping_limits=options.damping_limits,
        )
    finally:
        selection._cluster_statistics = original
    frequency = result.poles["frequency_hz"].to_numpy()
    return {
        mode: np.array([int(np.flatnonzero(frequency == value)[0]) for value in poles])
        for mode, poles in recorded
    }


def oracle(record, block_rows: int) -> np.ndarray:
    """Each true mode's frequency from its own modal coordinate (true shapes). [Hz]"""
    from workbench.sid import ssi_cov

    data = record.acceleration - record.acceleration.mean(axis=0)
    coordinates = data @ np.linalg.pinv(record.mode_shapes).T
    out = np.full(record.frequency_hz.size, np.nan)
    for k, truth in enumerate(record.frequency_hz):
        poles = ssi_cov(
            coordinates[:, [k]], record.sampling_rate_hz, block_rows=block_rows, orders=[2]
        ).poles
        poles = poles[poles["damping_ratio"] > 0]
        if len(poles):
            value = poles["frequency_hz"].to_numpy()
            out[k] = value[np.argmin(np.abs(value / truth - 1.0))]
    return out


def readings(cases, seeds: range) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per selected SSI mode its readings (first table); per case, 60-seed range and rule
    the benchmark's score of SSI with that rule applied to the modes that have a selected
    neighbour within 3 % (the pairs' modes; second table)."""
    from threadpoolctl import threadpool_limits

    from workbench.identification.options import IdentifyOptions

    options = IdentifyOptions()
    rows, scores = [], []
    for case in cases:
        for seed in seeds:
            record, interest = close_weak.build(case, seed)
            truth = record.frequency_hz
            tolerance = close_weak.tolerance(truth)
            with threadpool_limits(limits=1):
                result, chosen = close_weak.identify(record, ("cov",))["cov"]
                reference = oracle(record, options.block_rows)
            members = columns(result, options)
            poles = result.poles
            selected = chosen.modes["frequency_hz"].to_numpy()
            near = np.abs(selected[:, None] / selected[None, :] - 1.0)
            np.fill_diagonal(near, np.inf)
            near = near.min(axis=1, initial=np.inf) < 0.03
            by_rule = {name: selected.copy() for name in RULES}
            for j, frequency in enumerate(selected):
                k = int(np.argmin(np.abs(truth / frequency - 1.0)))
                index = members[frequency]
                if case["separation"] is not None and k in (2, truth.size - 1):
                    kind = "pair lower" if k == 2 else "pair upper"
                elif case["separation"] is None and k == 1:
                    kind = "weak"
                else:
                    kind = "other"
                row = {
                    "group": "weak"
                    if case["separation"] is None
                    else ("close 1%" if case["separation"] == 0.01 else "close 2-3%"),
                    "case": case["name"],
                    "seed": seed,
                    "mode": kind,
                    "truth": truth[k],
                    "tolerance": tolerance[k],
                    "oracle": reference[k] / truth[k] - 1.0,
                }
                f = poles["frequency_hz"].to_numpy()[index]
                mpc = poles["mpc"].to_numpy()[index]
                order = poles["model_order"].to_numpy()[index]
                for name, rule in RULES.items():
                    value = rule(f, mpc, order)
                    row[name] = value / truth[k] - 1.0
                    if near[j]:
                        by_rule[name][j] = value
                rows.append(row)
            for name, estimate in by_rule.items():
                found, error, spurious = close_weak.score(truth, estimate)
                scores.append(
                    {
                        "case": case["name"],
                        "seeds": f"{seed // 60 * 60}-{seed // 60 * 60 + 59}",
                        "rule": name,
                        "found": int(found.sum()),
                        "spurious": spurious,
                        "errors": error[found].tolist(),
                    }
                )
    return pd.DataFrame(rows), pd.DataFrame(scores)


def cells(scores: pd.DataFrame) -> pd.DataFrame:
    """Per rule, over the case x range cells: the benchmark's found, spurious, median and
    worst |df|/f of SSI with the rule on the pairs' modes against "all orders"."""
    grouped = scores.groupby(["rule", "case", "seeds"]).agg(
        found=("found", "sum"), spurious=("spurious", "sum"), errors=("errors", "sum")
    )
    grouped["median"] = grouped["errors"].apply(np.median)
    grouped["worst"] = grouped["errors"].apply(np.max)
    base = grouped.loc["all orders"]
    out = []
    for name in RULES:
        rule = grouped.loc[name]
        out.append(
            {
                "rule on the pairs' modes": name,
                "cells": len(rule),
                "found lower": int((rule["found"] < base["found"]).sum()),
                "spurious": int(rule["spurious"].sum()),
                "median worse": int((rule["median"] > base["median"]).sum()),
                "median better": int((rule["median"] < base["median"]).sum()),
                "worst worse": int((rule["worst"] > base["worst"]).sum()),
            }
        )
    return pd.DataFrame(out)


def summary(table: pd.DataFrame) -> pd.DataFrame:
    out = []
    for (group, mode), part in table.groupby(["group", "mode"]):
        for name in ["oracle", *RULES]:
            error = part[name].abs()
            out.append(
                {
                    "group": group,
                    "mode": mode,
                    "reading": name,
                    "n": len(part),
                    "median |df|/f": error.median(),
                    "max |df|/f": error.max(),
                    "beyond tolerance": int((error > part["tolerance"]).sum()),
                    "median |df|/f vs oracle": (part[name] - part["oracle"]).abs().median()
                    if name != "oracle"
                    else np.nan,
                }
            )
    return pd.DataFrame(out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=60, help="blocks (seeds) per case")
    parser.add_argument("--first-seed", type=int, default=0, help="seed of the first block")
    parser.add_argument("--cases", default="close,weak", help="close, weak or both")
    args = parser.parse_args(argv)
    if not 1 <= args.seeds <= 300:
        print(f"--seeds {args.seeds} must lie in 1..300", file=sys.stderr)
        return 2
    table, scores = readings(
        close_weak.case_list(args.cases.split(",")),
        range(args.first_seed, args.first_seed + args.seeds),
    )
    with pd.option_context("display.width", 200, "display.max_rows", 500):
        print(summary(table).to_string(index=False, float_format=lambda v: f"{v:.3g}"))
        print()
        spread = table.groupby(["group", "mode"]).apply(
            lambda part: pd.Series(
                {
                    "SSI std": part["all orders"].std(),
                    "oracle std": part["oracle"].std(),
                    "SSI - oracle std": (part["all orders"] - part["oracle"]).std(),
                    "correlation": np.corrcoef(part["all orders"], part["oracle"])[0, 1],
                }
            ),
            include_groups=False,
        )
        print(spread.to_string(float_format=lambda v: f"{v:.3g}"))
        print()
        pairs = table[table["mode"].str.startswith("pair")]
        beyond = pairs[pairs["all orders"].abs() > pairs["tolerance"]]
        print("SSI pair readings beyond the tolerance (df/f), with the oracle's:")
        print(
            beyond[
                ["case", "seed", "mode", "truth", "tolerance", "all orders", "oracle"]
            ].to_string(index=False, float_format=lambda v: f"{v:.5g}")
        )
        print()
        print(cells(scores).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
