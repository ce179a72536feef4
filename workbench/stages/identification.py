"""Identify stage: SSI (or LSCF) of every block of acceleration files, resumable, parallel.

The work itself lives in :mod:`workbench.identification` (block planning, conditioning, the
per-block store); this is its one entry point with the result every stage returns.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import pandas as pd

from data_contracts import POLES, read_table

from ..errors import WorkbenchError
from ..identification import (
    AdaptiveBlockOptions,
    IdentifyOptions,
    IdentifyResult,
    identify_voyage,
)
from ..sid.harmonics import HarmonicOptions
from ._base import StageResult, write_frame

__all__ = ["IdentifyOptions", "IdentifyStageResult", "identify"]


@dataclass
class IdentifyStageResult(StageResult):
    """Modes selected per block (``table``), the pole tables and what the run did.

    Attributes
    ----------
    run : IdentifyResult
        Run summary (blocks processed, skipped and why) and the files written.
    """

    run: IdentifyResult
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    title = "identified modes"

    @property
    def files(self) -> dict[str, Path]:
        return dict(self.run.files)

    @cached_property
    def table(self) -> pd.DataFrame:  # type: ignore[override]
        """Selected modes, one row per block and mode (the input of :func:`track`)."""
        path = self.run.files.get("selected")
        if path is None:
            return pd.DataFrame(columns=["block", "block_start", "block_end", "frequency_hz"])
        frame = pd.read_parquet(path)
        for column in ("block_start", "block_end"):
            if column in frame.columns:
                frame[column] = pd.to_datetime(frame[column], utc=True)
        return frame

    @cached_property
    def poles(self) -> pd.DataFrame:
        """Poles of every model order and block (POLES contract)."""
        path = self.run.files.get("poles")
        if path is None:
            raise ValueError("the run wrote no pole table (no block was identified)")
        return read_table(path, POLES)

    def track(self, *, reference_modes=None, options=None, progress: bool = False):
        """:func:`~workbench.stages.track` of the selected modes; the tracked result keeps
        this run's poles for the forecast's pole-cluster option (B)."""
        from .tracking import track

        result = track(
            self.table, reference_modes=reference_modes, options=options, progress=progress
        )
        result.poles = self.poles if "poles" in self.run.files else None
        return result

    def save(self, out_dir: str | os.PathLike) -> dict[str, Path]:
        """selected.parquet and poles.parquet in *out_dir*."""
        out = Path(out_dir)
        return {
            "selected": write_frame(self.table, out / "selected.parquet"),
            "poles": write_frame(self.poles, out / "poles.parquet", POLES),
        }


def identify(
    inputs: str | os.PathLike | Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    store_dir: str | os.PathLike | None = None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    progress: bool = False,
    batch_blocks: int = 16,
    keep_removed_inputs: bool = False,
    dship: str | os.PathLike | pd.DataFrame | None = None,
    dship_mapping: dict[str, str] | None = None,
    harmonics: HarmonicOptions | None = None,
    adaptive: AdaptiveBlockOptions | None = None,
    cases: str | os.PathLike | pd.DataFrame | None = None,
) -> IdentifyStageResult:
    """Identify every block of a voyage's acceleration files.

    Parameters
    ----------
    inputs : path or iterable of paths
        Acceleration files and/or folders holding them.
    out_dir : path-like
        Where poles.parquet, selected.parquet, blocks.csv, faults.csv... are written; the
        per-block store (``out_dir/store`` unless *store_dir*) makes a rerun resume.
    options : IdentifyOptions, optional
        Method, block rows, orders, band, block length... (defaults: SSI-cov, 20-min
        blocks every 5 min).
    scheduler, n_workers, progress, batch_blocks
        Parallel execution (:func:`workbench.identification.identify_voyage`).
    keep_removed_inputs : bool
        Keep the stored blocks of input files no longer given (default: drop them).
    dship, dship_mapping : optional
        The voyage's ship log and its column names: the shaft speed (or the speed) marks
        the shaft and blade-pass harmonics, which tracking keeps out of the modes.
    harmonics : HarmonicOptions, optional
        Orders and blade count of the harmonic tests (:mod:`workbench.sid.harmonics`).
    adaptive : AdaptiveBlockOptions, optional
        Block length by conditions (``--block-minutes auto``,
        :mod:`workbench.identification.adaptive`): each block's length from its
        excitation, the log's speed and *cases*; *options*' block length and step are
        then replaced.
    cases : path or DataFrame, optional
        The log's states (``case``, ``start``, ``end``: ice, transit, station, ...) for
        *adaptive*: a block does not straddle a change of state.

    Raises
    ------
    WorkbenchError
        When no block was identified and none was already in the store (every block
        skipped, e.g. every block's fit failing), naming the reasons; the run's
        ``blocks.csv`` lists each block and why.
    """
    if isinstance(inputs, str | os.PathLike):
        inputs = [inputs]
    run_options = {
        "store_dir": store_dir,
        "scheduler": scheduler,
        "n_workers": n_workers,
        "progress": progress,
        "batch_blocks": batch_blocks,
        "keep_removed_inputs": keep_removed_inputs,
        "dship": dship,
        "dship_mapping": dship_mapping,
        "harmonics": harmonics,
    }
    if adaptive is not None:
        from ..identification.adaptive import identify_adaptive

        run = identify_adaptive(
            list(inputs),
            out_dir,
            options=options or IdentifyOptions(),
            adaptive=adaptive,
            cases=cases,
            **run_options,
        )
    else:
        if cases is not None:
            raise ValueError("cases are used by the adaptive block length only (adaptive=)")
        run = identify_voyage(list(inputs), out_dir, options=options, **run_options)
    summary = run.summary
    if summary.processed == 0 and summary.already_done == 0:
        # never a silent success with nothing done: say why no block was identified
        reasons = sorted(summary.skip_reasons.items(), key=lambda item: -item[1])
        why = "; ".join(f"{reason} ({n})" for reason, n in reasons[:3]) or "no block planned"
        more = f"; {len(reasons) - 3} more reasons in blocks.csv" if len(reasons) > 3 else ""
        raise WorkbenchError(
            f"no block identified: all {summary.skipped} block(s) skipped: {why}{more}"
        )
    return IdentifyStageResult(run=run, lines=run.lines(), warnings=list(run.notices))
