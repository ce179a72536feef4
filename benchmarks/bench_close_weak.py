"""Close and weakly excited modes: SSI, LSCF and their combination on prescribed modes.

Each case is a structure of five modes (1.1, 2.3, 3.4, 4.6, 5.9 Hz, damping 1 %, random
shapes on 8 channels) simulated exactly (:func:`workbench.simulate.prescribed.
prescribed_mode_record`, white-noise modal forces, white sensor noise of 20 % of each channel's RMS), 20-min blocks at
16 Hz, one block per seed:

* ``close s% MAC m``: a sixth mode (s/100)·3.4 Hz above the 3.4-Hz mode, its shape at MAC m
  with it, both at the same level;
* ``weak L dB``: the 2.3-Hz mode's modal acceleration L dB below the others.

Every block is identified as ``workbench identify`` does with its defaults
(:func:`workbench.identification.engine._identify_method`: SSI-cov orders 4-60, LSCF orders
1-15, clustering selection) and, for ``combined``, the two selections merged by
:func:`workbench.sid.combined.combine_modes`. A true mode is *found* when a selected mode
lies within 0.4 x its distance to the nearest other true mode (at most 2 %) of it,
one-to-one; every other selected mode is *spurious*. Printed per case and method: blocks,
the found rate of the case's mode of interest (the pair's upper mode or the weak mode), of
all modes, missed and spurious counts over all blocks, the median and worst |df|/f of the
found modes, and (``common``) of the modes every method found in the block (the fair
comparison of the estimates). ``combined`` is the default combination (SSI's estimate
where SSI found the mode), ``weighted`` the inverse-variance mean of SSI and LSCF.

Run: ``python benchmarks/bench_close_weak.py [--seeds 10] [--cases close,weak]``.
"""

from __future__ import annotations

import argparse
import math
import sys
from types import SimpleNamespace

import numpy as np
import pandas as pd
from scipy.optimize import linear_sum_assignment

BASE_FREQUENCY_HZ = np.array([1.1, 2.3, 3.4, 4.6, 5.9])
DAMPING = 0.01
N_CHANNELS = 8
RATE_HZ = 16.0
BLOCK_S = 1200.0
SENSOR_NOISE = 0.2


def case_list(kinds) -> list[dict]:
    cases = []
    if "close" in kinds:
        for separation in (0.01, 0.02, 0.03):
            for mac_value in (0.2, 0.5, 0.9):
                cases.append(
                    {
                        "name": f"close {100 * separation:g}% MAC {mac_value:g}",
                        "separation": separation,
                        "mac": mac_value,
                        "weak_db": 0.0,
                    }
                )
    if "weak" in kinds:
        for level in (10.0, 15.0, 20.0):
            cases.append(
                {"name": f"weak {level:g} dB", "separation": None, "mac": None, "weak_db": level}
            )
    return cases


def build(case: dict, seed: int):
    """The record of *case* for *seed*, and the index of its mode of interest."""
    from workbench.simulate.prescribed import prescribed_mode_record, shapes_with_mac

    rng = np.random.default_rng(1000 + seed)
    shapes = rng.standard_normal((N_CHANNELS, BASE_FREQUENCY_HZ.size))
    frequency = BASE_FREQUENCY_HZ.copy()
    level = np.zeros(frequency.size)
    interest = 1
    if case["separation"] is not None:
        partner = shapes_with_mac(shapes[:, 2], case["mac"], rng)
        frequency = np.append(frequency, 3.4 * (1 + case["separation"]))
        shapes = np.column_stack([shapes, partner])
        level = np.append(level, 0.0)
        interest = frequency.size - 1
    else:
        level[1] = -case["weak_db"]
    record = prescribed_mode_record(
        frequency,
        DAMPING,
        shapes,
        sampling_rate_hz=RATE_HZ,
        duration_s=BLOCK_S,
        level_db=level,
        sensor_noise=SENSOR_NOISE,
        seed=seed,
    )
    return record, interest


def tolerance(truth: np.ndarray) -> np.ndarray:
    """Largest |df|/f at which an estimate still reads each true mode: 40 % of the relative
    distance to its nearest neighbour, at most 2 %. [-]"""
    separation = np.abs(truth[:, None] / truth[None, :] - 1.0)
    np.fill_diagonal(separation, np.inf)
    return np.minimum(0.4 * separation.min(axis=1), 0.02)


def score(truth: np.ndarray, estimate: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Found mask of the true modes, |df|/f of the found ones, number of spurious modes."""
    limit = tolerance(truth)
    found = np.zeros(truth.size, dtype=bool)
    error = np.full(truth.size, np.nan)
    if estimate.size:
        distance = np.abs(estimate[None, :] / truth[:, None] - 1.0)
        cost = np.where(distance < limit[:, None], distance, 1e6)
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] < 1e6
        found[rows[ok]] = True
        error[rows[ok]] = distance[rows[ok], cols[ok]]
    return found, error, int(estimate.size - found.sum())


def identify(record, methods):
    """Selected frequencies per method (and the selections, for combining)."""
    from workbench.identification.engine import _identify_method
    from workbench.identification.options import IdentifyOptions

    options = IdentifyOptions()
    data = SimpleNamespace(
        acceleration=record.acceleration - record.acceleration.mean(axis=0),
        sampling_rate_hz=record.sampling_rate_hz,
        channels=tuple(f"ch{j}" for j in range(record.acceleration.shape[1])),
    )
    out = {}
    for method in methods:
        result, selection = _identify_method(method, data, None, options)
        out[method] = (result, selection)
    return out


def run(cases, seeds, combine=True, first_seed=0, second_look=True) -> pd.DataFrame:
    import functools

    from threadpoolctl import threadpool_limits

    import workbench.sid

    if not second_look:  # the selection as it was before its second look (A/B)
        workbench.sid.select_modes = functools.partial(
            workbench.sid.selection.select_modes, second_look=False
        )

    rows = []
    for case in cases:
        tally: dict[str, dict] = {}
        for seed in range(first_seed, first_seed + seeds):
            record, interest = build(case, seed)
            with threadpool_limits(limits=1):
                results = identify(record, ("cov", "lscf"))
            estimates = {
                "SSI": results["cov"][1].modes["frequency_hz"].to_numpy(),
                "LSCF": results["lscf"][1].modes["frequency_hz"].to_numpy(),
            }
            if combine:
                from workbench.sid.combined import combine_modes

                pair = {"ssi": results["cov"][1], "lscf": results["lscf"][1]}
                estimates["combined"] = combine_modes(pair)["frequency_hz"].to_numpy()
                for variant in ("weighted", "reference"):
                    other = combine_modes(pair, estimate=variant)
                    estimates[variant] = other["frequency_hz"].to_numpy()
            scored = {m: score(record.frequency_hz, e) for m, e in estimates.items()}
            common = np.logical_and.reduce([found for found, _, _ in scored.values()])
            for method, (found, error, spurious) in scored.items():
                t = tally.setdefault(
                    method,
                    {
                        "interest": 0,
                        "found": 0,
                        "missed": 0,
                        "spurious": 0,
                        "errors": [],
                        "common": [],
                    },
                )
                t["interest"] += int(found[interest])
                t["found"] += int(found.sum())
                t["missed"] += int((~found).sum())
                t["spurious"] += spurious
                t["errors"].extend(error[found].tolist())
                t["common"].extend(error[common].tolist())
        for method, t in tally.items():
            errors = np.array(t["errors"])
            rows.append(
                {
                    "case": case["name"],
                    "method": method,
                    "blocks": seeds,
                    "interest found": f"{t['interest']}/{seeds}",
                    "found": t["found"],
                    "missed": t["missed"],
                    "spurious": t["spurious"],
                    "median |df|/f": float(np.median(errors)) if errors.size else math.nan,
                    "max |df|/f": float(np.max(errors)) if errors.size else math.nan,
                    "common median": float(np.median(t["common"])) if t["common"] else math.nan,
                    "common max": float(np.max(t["common"])) if t["common"] else math.nan,
                }
            )
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=10, help="blocks (seeds) per case")
    parser.add_argument("--cases", default="close,weak", help="close, weak or both")
    parser.add_argument("--no-combined", action="store_true", help="SSI and LSCF only")
    parser.add_argument("--first-seed", type=int, default=0, help="seed of the first block")
    parser.add_argument(
        "--no-second-look", action="store_true", help="selection without its second look"
    )
    args = parser.parse_args(argv)
    if not 1 <= args.seeds <= 200:
        print(f"--seeds {args.seeds} must lie in 1..200", file=sys.stderr)
        return 2
    table = run(
        case_list(args.cases.split(",")),
        args.seeds,
        combine=not args.no_combined,
        first_seed=args.first_seed,
        second_look=not args.no_second_look,
    )
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
