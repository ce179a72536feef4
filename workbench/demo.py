"""``workbench demo``: the whole chain on the built-in demo voyage, checked against its truth.

Every stage reads and writes contract files, exactly as the individual CLI commands do, so
the demo folder is also a worked example of the command-line workflow.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from data_contracts import CONTRACTS, read_accelerations, read_dship, read_table

from .reporting.index import write_index

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
        return "\n".join([*self.lines,
                          f"{self.validated} files validated against their contracts",
                          f"stages: {stages}; total {total:.1f} s",
                          f"open {self.out_dir / 'index.html'}"])


def _kind_of(path: Path) -> str | None:
    """Contract of a file written by the demo, from its name."""
    name = path.name
    if path.suffix == ".npz":
        return "accelerations"
    if path.suffix in (".tab", ".tsv"):
        return "dship"
    for kind in ("forecast", "poles", "predictors"):
        if name.startswith(kind) and path.suffix in (".csv", ".parquet"):
            return kind
    if path.suffix in (".csv", ".parquet") and ("modal" in name or name.startswith("selected")):
        return "modal"
    return None


def describe_voyage(voyage) -> str:
    """One line about a simulated voyage."""
    return (f"{voyage.hours:g} h from {voyage.start_time:%Y-%m-%d %H:%M} UTC, {voyage.n_blocks} "
            f"blocks, {len(voyage.acceleration_files)} acceleration files, seed {voyage.seed}")


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
        if kind == "accelerations":
            read_accelerations(path)
        elif kind == "dship":
            read_dship(path)
        else:
            read_table(path, CONTRACTS[kind])
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


def run_demo(out_dir: str | os.PathLike = Path("reports") / "demo", *, seed: int = 0,
             hours: float | None = None) -> DemoSummary:
    """Simulate the demo voyage into *out_dir* and run every stage on it.

    Returns
    -------
    DemoSummary
        Stage timings, number of files validated, headline numbers.
    """
    from .simulate import simulate_voyage

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = DemoSummary(out_dir)
    stage = _Stages(summary)
    voyage_dir = out_dir / "voyage"
    with stage("simulate"):
        simulation = simulate_voyage(voyage_dir, seed=seed, hours=hours)
    summary.lines.append(f"simulated voyage: {describe_voyage(simulation)}")
    tables: dict[str, pd.DataFrame] = {}
    with stage("validate"):
        summary.validated = validate_folder(out_dir)
    write_index(out_dir, title="workbench demo voyage", summary=[*summary.lines], tables=tables)
    return summary
