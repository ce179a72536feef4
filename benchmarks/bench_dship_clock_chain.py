"""What a ship log kept in local time (+2 h, no offset) and read as UTC does to the demo
chain, against the correct log and the same log read with ``--dship-utc-offset +02:00``.

    python -m workbench simulate --out VOYAGE --hours 12 --seed 0
    python benchmarks/bench_dship_clock_chain.py VOYAGE OUT

Identify (the demo's options; one store, so the blocks are identified once), track, fit
(stepwise R² per mode) and forecast (the demo's rolling options A and B) evaluated
against the true modes. Results: benchmarks/results/dship_clock_50.txt.
"""

import sys
import time
import warnings
from datetime import datetime, timedelta
from pathlib import Path

import pandas as pd

from data_contracts import CONTRACTS, read_table
from workbench.demo import DEMO_HARMONIC_OPTIONS, DEMO_IDENTIFY_OPTIONS
from workbench.predictors import canonical_predictors, load_predictors
from workbench.sid.tracking import label_agreement
from workbench.stages import (
    FitOptions,
    ForecastOptions,
    evaluate,
    fit,
    forecast,
    identify,
    track,
)
from workbench.stats.correlation import read_cases


def main() -> None:
    warnings.simplefilter("ignore")
    v = Path(sys.argv[1])
    out = Path(sys.argv[2])
    out.mkdir(exist_ok=True)
    lines = (v / "dship.tsv").read_text(encoding="utf-8").split("\n")
    first = next(i for i, line in enumerate(lines) if line.startswith("Date/Time")) + 1
    for i in range(first, len(lines)):
        if lines[i]:
            stamp, rest = lines[i].split("\t", 1)
            local = datetime.fromisoformat(stamp) + timedelta(hours=2)
            lines[i] = f"{local:%Y-%m-%dT%H:%M:%S}\t{rest}"
    (v / "dship_p2.tsv").write_text("\n".join(lines), encoding="utf-8")
    truth = read_table(v / "truth_modal.csv", CONTRACTS["modal"])
    cases = read_cases(v / "cases.csv")  # the demo fits per operating case too
    variants = [
        ("correct log", v / "dship.tsv", None),
        ("+2 h local log read as UTC", v / "dship_p2.tsv", None),
        ("+2 h local log, --dship-utc-offset +02:00", v / "dship_p2.tsv", "+02:00"),
    ]
    for label, log, offset in variants:
        print(f"=== {label}")
        d = out / label.split()[0].replace("+", "p").replace(" ", "") / ("o" if offset else "n")
        t = time.perf_counter()
        r = identify(
            v / "accelerations",
            d,
            options=DEMO_IDENTIFY_OPTIONS,
            harmonics=DEMO_HARMONIC_OPTIONS,
            dship=log,
            dship_utc_offset=offset,
            store_dir=out / "store",
            n_workers=2,
        )
        print(f"identify {time.perf_counter() - t:.1f} s")
        for line in r.notes + r.warnings:
            if "harmonic" in line or "vibration" in line or "shaft" in line:
                print("  ", line)
        tracked = track(d / "selected.parquet")
        agreement, mapping = label_agreement(tracked.table, truth)
        print(
            f"   tracking: {100 * agreement:.1f} % labels right; {tracked.table['mode'].nunique()} modes"
        )
        predictors = canonical_predictors(
            load_predictors(
                dship=log, onto=tracked.table, all_predictors=True, dship_utc_offset=offset
            )
        )
        fr = fit(tracked.table, predictors, cases=cases, options=FitOptions())
        for line in fr.lines:
            print("   fit:", line)
        fr.save(d / "fit")
        st = pd.read_csv(d / "fit" / "fit_statistics.csv")
        st = st.drop_duplicates("mode")
        print(
            "   fit R^2 per mode: "
            + ", ".join(
                f"{int(m)}: {r:.3f} (n={n}, {f.split('~ 1')[-1].strip(' +') or '-'})"
                for m, r, n, f in zip(
                    st["mode"], st["r_squared"], st["n_obs"], st["formula"], strict=True
                )
            )
        )
        if "--fit-only" in sys.argv:
            continue
        fc = forecast(
            tracked.table,
            predictors,
            poles=r.poles,
            options=ForecastOptions(
                options=("A", "B"), scheme="rolling", train_blocks=20, model="memory"
            ),
        )
        for line in fc.lines:
            print("   forecast:", line)
        ev = evaluate(fc.table, truth)
        for line in ev.lines:
            print("   evaluate:", line)


if __name__ == "__main__":
    main()
