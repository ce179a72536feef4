"""Where a run's tables are: :func:`find_run` locates them in a folder (:class:`RunFiles`);
:class:`ReportSection` is one section of the page, and :func:`register_section` lets other
stages add theirs."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd


@dataclass
class RunFiles:
    """The tables of a run found in a folder (None where a stage did not run)."""

    root: Path
    identify: Path | None = None
    tracked: Path | None = None
    predictors: Path | None = None
    dship: Path | None = None
    cases: Path | None = None
    geometry: Path | None = None
    accelerations: list[Path] = field(default_factory=list)
    correlation: Path | None = None
    fit: Path | None = None
    forecast: Path | None = None
    evaluation: Path | None = None
    truth: Path | None = None


@dataclass
class ReportSection:
    """A section of the report: title, paragraphs (plain text), tables and figures.

    ``tables`` are ``(caption, DataFrame)`` pairs (shown with their column names);
    ``figures`` are ``(caption, path relative to the report)``.
    """

    id: str
    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[tuple[str, pd.DataFrame]] = field(default_factory=list)
    figures: list[tuple[str, str]] = field(default_factory=list)
    details: list[tuple[str, str]] = field(default_factory=list)
    figures_first: bool = False


def _first(root: Path, names: Sequence[str], *, depth: int = 2) -> Path | None:
    """First file named like one of *names* at depth 0, then 1, ... below *root*, outside
    the simulator's truth folder (a folder with ``voyage.json``) unless asked for."""
    for level in range(depth + 1):
        pattern = "/".join(["*"] * level)
        for name in names:
            for path in sorted(root.glob(f"{pattern}/{name}" if pattern else name)):
                if path.is_file() and "store" not in path.relative_to(root).parts[:-1]:
                    return path
    return None


def find_run(
    root: str | os.PathLike,
    *,
    accelerations: Sequence[str | os.PathLike] = (),
    dship: str | os.PathLike | None = None,
    cases: str | os.PathLike | None = None,
    geometry: str | os.PathLike | None = None,
) -> RunFiles:
    """Locate a run's tables in *root* (the folder given to the stages' ``--out``).

    Looked for (in *root*, then one and two folders down): ``blocks.csv`` next to
    ``poles.parquet``/``selected.parquet`` (identification), ``tracked_modal.*``,
    ``predictors.*``, the correlate stage's folder (``correlation.json``),
    ``fit_statistics.csv``, ``forecast.*``, ``evaluation.csv``,
    ``cases.csv``, ``sensor_geometry.csv``, a DSHIP log (``*.tsv``/``*.tab``) and an
    ``accelerations`` folder. Explicit arguments win.
    """
    from data_contracts.formats import acceleration_files

    root = Path(root)
    run = RunFiles(root)
    blocks = _first(root, ["blocks.csv"])
    run.identify = blocks.parent if blocks is not None else None
    run.tracked = _first(
        root, ["tracked_modal.csv", "tracked_modal.parquet", "tracked*.csv"], depth=1
    )
    if run.tracked is not None and (run.tracked.parent / "voyage.json").exists():
        run.tracked = None  # the simulator's imitation, not a result of this run
    run.predictors = _first(root, ["predictors.csv", "predictors.parquet"], depth=1)
    run.dship = Path(dship) if dship else _first(root, ["dship.tsv", "*.tab", "*.tsv"])
    run.cases = Path(cases) if cases else _first(root, ["cases.csv"])
    run.geometry = Path(geometry) if geometry else _first(root, ["sensor_geometry.csv"])
    correlation = _first(root, ["correlation.json"])
    run.correlation = correlation.parent if correlation is not None else None
    fit = _first(root, ["fit_statistics.csv"])
    run.fit = fit.parent if fit is not None else None
    run.forecast = _first(root, ["forecast.csv", "forecast.parquet"], depth=1)
    run.evaluation = _first(root, ["evaluation.csv"], depth=1)
    run.truth = _first(root, ["truth_modal.csv"])
    if accelerations:
        run.accelerations = acceleration_files(accelerations)
    else:
        folder = next((p for p in sorted(root.rglob("accelerations")) if p.is_dir()), None)
        if folder is not None:
            run.accelerations = acceleration_files([folder])
    return run
