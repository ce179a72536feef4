"""``workbench demo``: the whole chain on the built-in demo voyage, checked against its truth.

Every stage reads and writes contract files, exactly as the individual CLI commands do, so
the demo folder is also a worked example of the command-line workflow.
"""

from __future__ import annotations

import logging
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

from data_contracts import CONTRACTS, read_table, validate_file

from .reporting.report import build_report

__all__ = ["DemoSummary", "run_demo", "validate_folder"]

log = logging.getLogger(__name__)


@dataclass
class DemoSummary:
    """What the demo wrote and how long each stage took."""

    out_dir: Path
    stage_seconds: dict[str, float] = field(default_factory=dict)
    validated: int = 0
    lines: list[str] = field(default_factory=list)

    def __str__(self) -> str:
        total = sum(self.stage_seconds.values())
        stages = ", ".join(f"{name} {sec:.1f} s" for name, sec in self.stage_seconds.items())
        return "\n".join(
            [
                *self.lines,
                f"{self.validated} files validated against their contracts",
                f"stages: {stages}; total {total:.1f} s",
                f"open {self.out_dir / 'index.html'}",
            ]
        )


def _kind_of(path: Path) -> str | None:
    """Contract of a file written by the demo, from its name."""
    name = path.name
    if path.suffix == ".npz":
        return "accelerations"
    if path.suffix in (".tab", ".tsv"):
        return "dship"
    for kind in ("forecast", "poles", "predictors", "selected"):
        if name.startswith(kind) and path.suffix in (".csv", ".parquet"):
            return kind
    if path.suffix in (".csv", ".parquet") and "modal" in name:
        return "modal"
    return None


def describe_voyage(voyage) -> str:
    """One line about a simulated voyage."""
    return (
        f"{voyage.hours:g} h from {voyage.start_time:%Y-%m-%d %H:%M} UTC, {voyage.n_blocks} "
        f"blocks, {len(voyage.acceleration_files)} acceleration files, seed {voyage.seed}"
    )


def validate_folder(root: Path) -> int:
    """Validate every contract file below *root*; return how many were checked.

    Raises
    ------
    ContractError
        For the first file that violates its contract.
    """
    count = 0
    for path in sorted(root.rglob("*")):
        kind = _kind_of(path)
        if kind is None or not path.is_file():
            continue
        validate_file(kind, path)
        count += 1
    return count


class _Stages:
    def __init__(self, summary: DemoSummary):
        self.summary = summary

    def __call__(self, name: str):
        stages = self

        class _Timer:
            def __enter__(self):
                log.info("demo: %s ...", name)
                self.start = time.perf_counter()

            def __exit__(self, *exc):
                stages.summary.stage_seconds[name] = time.perf_counter() - self.start
                return False

        return _Timer()


def _demo_identify_options():
    from .identification import IdentifyOptions

    # the structure-level setting of the demo hull: its global modes lie in 2-12 Hz
    return IdentifyOptions(band_hz=(2.0, 12.0))


DEMO_IDENTIFY_OPTIONS = _demo_identify_options()


def _demo_harmonic_options():
    from .sid.harmonics import HarmonicOptions

    # the demo ship's propeller has 5 blades (workbench.simulate.ShaftHarmonics)
    return HarmonicOptions(blades=5)


DEMO_HARMONIC_OPTIONS = _demo_harmonic_options()


def run_demo(
    out_dir: str | os.PathLike = Path("reports") / "demo",
    *,
    seed: int = 0,
    hours: float | None = None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    progress: bool = False,
) -> DemoSummary:
    """Simulate the demo voyage into *out_dir* and run every stage on it.

    Stages: simulate -> identify (SSI-cov on every block, in parallel) -> track ->
    predictors (DSHIP log onto the blocks) -> correlate -> fit (stepwise per mode) ->
    forecast (rolling scheme, options A and B) -> evaluate against the truth -> the run's
    report (``index.html``, :func:`workbench.reporting.report.build_report`).

    Returns
    -------
    DemoSummary
        Stage timings, number of files validated, headline numbers.
    """
    from data_contracts import PREDICTORS, write_table

    from .predictors import canonical_predictors, load_predictors
    from .simulate import simulate_voyage
    from .stages import (
        CorrelateOptions,
        FitOptions,
        ForecastOptions,
        correlate,
        evaluate,
        fit,
        forecast,
        identify,
        relabel_truth,
        track,
    )

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = DemoSummary(out_dir)
    stage = _Stages(summary)
    voyage_dir = out_dir / "voyage"
    with stage("simulate"):
        simulation = simulate_voyage(voyage_dir, seed=seed, hours=hours)
    from .config import write_demo_config

    config_path = write_demo_config(out_dir, voyage_dir.name)
    summary.lines.append(f"example configuration: {config_path} (workbench run {config_path})")
    summary.lines.append(f"simulated voyage: {describe_voyage(simulation)}")
    truth = read_table(simulation.truth_modal, CONTRACTS["modal"])

    # the folder of the acceleration files (the voyage folder also holds the ship log and
    # the true tables, which a folder scan would list as text files left out)
    accelerations_dir = Path(simulation.acceleration_files[0]).parent
    identify_dir = out_dir / "identify"
    # the voyage was just (re)written: results of an earlier demo run must not be resumed
    shutil.rmtree(identify_dir, ignore_errors=True)
    with stage("identify"):
        identified = identify(
            accelerations_dir,
            identify_dir,
            options=DEMO_IDENTIFY_OPTIONS,
            dship=simulation.dship_log,
            harmonics=DEMO_HARMONIC_OPTIONS,
            scheduler=scheduler,
            n_workers=n_workers,
            progress=progress,
        )
    summary.lines.append(
        f"identify: {identified.run.processed} blocks identified, "
        f"{identified.run.skipped} skipped, {identified.n_selected} modes selected"
    )
    summary.lines += identified.notes

    with stage("SSI/LSCF cross-check"):
        from .identification import cross_check_blocks
        from .sid.crosscheck import agreement_lines

        cross = cross_check_blocks([accelerations_dir], identify_dir, n_blocks=6)
    summary.lines += agreement_lines(cross) if len(cross) else ["cross-check: no block"]

    with stage("track"):
        tracked = track(identify_dir / "selected.parquet")
        path = tracked.save(out_dir / "tracked_modal.csv")["tracked"]
    summary.lines += tracked.lines
    summary.lines.append(f"tracked modal table: {path}")
    from .sid.tracking import label_agreement

    agreement, mapping = label_agreement(tracked.table, truth)
    summary.lines.append(
        f"tracking: {100 * agreement:.1f} % of tracked (block, mode) pairs carry the true "
        f"mode's label (labels -> true modes {mapping})"
    )

    with stage("predictors"):
        predictors = load_predictors(
            dship=simulation.dship_log, onto=tracked.table, all_predictors=True
        )
        write_table(predictors, out_dir / "predictors.csv", PREDICTORS)
    predictors = canonical_predictors(predictors)

    with stage("correlate"):
        correlated = correlate(
            tracked.table, predictors, cases=simulation.cases, options=CorrelateOptions()
        )
        correlated.save(out_dir / "correlation")
    with stage("fit"):
        fit(tracked.table, predictors, cases=simulation.cases, options=FitOptions()).save(
            out_dir / "fit"
        )

    with stage("forecast"):
        forecasted = forecast(
            tracked.table,
            predictors,
            poles=identified.poles,
            options=ForecastOptions(
                options=("A", "B"),
                scheme="rolling",
                train_blocks=20,
                # the default model (memory: measures best on
                # benchmarks/bench_forecast_accuracy.py, demo voyages included)
                model="memory",
            ),
        )
        paths = forecasted.save(
            out_dir / "forecast.csv",
            figures=out_dir / "forecast",
            truth=relabel_truth(truth, mapping),
        )
    summary.lines += forecasted.lines
    summary.lines.append(f"forecast table: {paths['forecast']}")
    with stage("evaluate"):
        evaluation = evaluate(forecasted.table, truth)
        evaluation.save(out_dir / "evaluation.csv")
    summary.lines += evaluation.lines
    with stage("validate"):
        summary.validated = validate_folder(out_dir)
    with stage("report"):
        build_report(
            out_dir,
            out=out_dir / "index.html",
            title="workbench demo voyage",
            summary_lines=summary.lines,
            correlation=correlated,
        )
    return summary
