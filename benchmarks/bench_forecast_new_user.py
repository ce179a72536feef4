"""Issue 27's own setup: block-level voyages through the command line, as a new user runs them.

Each case is a block-level voyage of ``forecast_regimes.py`` with all seven modes of the
demo hull, labelled 0-6 (0-based), a pole table without mode shapes and the default
settings; the files are written as CSV and the forecast and its evaluation are run with
the ``workbench`` command line in a subprocess::

    workbench forecast --modal modal.csv --predictors predictors.csv --poles poles.csv \\
        --option both --out forecast.csv
    workbench evaluate --forecast forecast.csv --truth truth.csv --out evaluation.csv

Printed per case, seed and option: the Kalman estimate against raw SSI summed over the
modes from ``workbench evaluate`` (its SSI column is the measurement each option used:
the tracked pole for A, the chosen pole cluster for B), the same against the tracked pole
as ``workbench evaluate`` reports it (``improvement_vs_tracked_pct``'s sums) and as
``bench_forecast_accuracy.py`` scores it, and what the knowing filter (oracle) reaches on
the same rows.

Run: ``python benchmarks/bench_forecast_new_user.py --seeds 3 --work /tmp/new_user``
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_forecast_accuracy import score  # noqa: E402
from child_library import pin_library  # noqa: E402
from forecast_regimes import UNRECORDED, make_regime  # noqa: E402

pin_library()  # child processes import this library, not the current folder's

#: The issue's table: slow rise, held step, 40-min wander of twice the SSI scatter.
CASES = ("rise_0.8pct_12h", "step_-0.6pct", "wander_40min_2x")


def _workbench(*args: str) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "workbench.cli", "-q", *args],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        raise RuntimeError(f"workbench {args[0]} exit {done.returncode}: {done.stderr.strip()}")


def run_case(case: str, seed: int, folder: Path, n_blocks: int) -> list[dict]:
    data = make_regime(
        case, seed, n_blocks=n_blocks, shapes=False, mode_index=tuple(range(7)), first_label=0
    )
    folder.mkdir(parents=True, exist_ok=True)
    data.tracked.to_csv(folder / "modal.csv", index=False)
    data.poles.to_csv(folder / "poles.csv", index=False)
    data.predictors.to_csv(folder / "predictors.csv", index=False)
    truth = data.truth.merge(data.predictors[["block", "block_start"]], on="block")
    truth.to_csv(folder / "truth.csv", index=False)
    _workbench(
        "forecast",
        "--modal",
        str(folder / "modal.csv"),
        "--predictors",
        str(folder / "predictors.csv"),
        "--poles",
        str(folder / "poles.csv"),
        "--option",
        "both",
        "--out",
        str(folder / "forecast.csv"),
    )
    _workbench(
        "evaluate",
        "--forecast",
        str(folder / "forecast.csv"),
        "--truth",
        str(folder / "truth.csv"),
        "--out",
        str(folder / "evaluation.csv"),
    )
    forecast = pd.read_csv(folder / "forecast.csv")
    evaluation = pd.read_csv(folder / "evaluation.csv")
    rows = []
    for option, part in evaluation.groupby("option"):
        cli = 100 * (
            1 - part["kalman_cumulative_error_hz"].sum() / part["ssi_cumulative_error_hz"].sum()
        )
        # `workbench evaluate` against the tracked pole (option A's SSI column)
        cli_tracked = 100 * (
            1
            - part["kalman_cumulative_error_tracked_hz"].sum()
            / part["tracked_cumulative_error_hz"].sum()
        )
        table = forecast[forecast["option"] == option]
        suite = score(table, data.truth, data.tracked, data.oracle)
        rows.append(
            {
                "case": case,
                "seed": seed,
                "option": option,
                "modes": int(part["mode"].nunique()),
                "cli_kalman_vs_ssi": cli,
                "cli_kalman_vs_tracked": cli_tracked,
                "kalman_vs_tracked": suite["kalman_vs_ssi"],
                "model_vs_tracked": suite["model_vs_ssi"],
                "oracle_vs_tracked": suite["oracle_vs_ssi"],
            }
        )
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--blocks", type=int, default=432, help="blocks per voyage (36 h)")
    parser.add_argument("--cases", default=",".join(CASES), help=f"of {', '.join(UNRECORDED)}")
    parser.add_argument("--work", type=Path, required=True, help="folder for the voyages' files")
    parser.add_argument("--out", type=Path, help="write every run's scores as CSV")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    rows = []
    for case in (c.strip() for c in args.cases.split(",") if c.strip()):
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            rows += run_case(case, seed, args.work / f"{case}_seed{seed}", args.blocks)
            print(f"  {case} seed {seed} done", file=sys.stderr, flush=True)
    runs = pd.DataFrame(rows)
    if args.out is not None:
        runs.to_csv(args.out, index=False)
    with pd.option_context("display.width", 200, "display.max_rows", 500):
        print(runs.to_string(index=False, float_format=lambda v: f"{v:+.1f}"))
    print(f"{len(runs)} runs in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
