"""Identify stage: SSI (or LSCF) of every block of acceleration files, resumable, parallel.

The work itself lives in :mod:`workbench.identification` (block planning, conditioning, the
per-block store) and its result (:class:`~workbench.identification.IdentifyResult`); this is
its one entry point, refusing a run that identified nothing.
"""

from __future__ import annotations

import os
from collections.abc import Iterable

import pandas as pd

from ..errors import WorkbenchError
from ..identification import (
    AdaptiveBlockOptions,
    IdentifyOptions,
    IdentifyResult,
    identify_voyage,
)
from ..sid.harmonics import HarmonicOptions

__all__ = ["IdentifyOptions", "IdentifyResult", "identify"]


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
    dship_utc_offset: str | None = None,
    harmonics: HarmonicOptions | None = None,
    adaptive: AdaptiveBlockOptions | None = None,
    cases: str | os.PathLike | pd.DataFrame | None = None,
) -> IdentifyResult:
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
        When the blocks' vibration level follows the log's speed clearly better with the
        log shifted by whole or half hours, a warning names the likely UTC offset of its
        times (:mod:`workbench.predictors.clock`).
    dship_utc_offset : str, optional
        UTC offset of the log's times written without one (``"+02:00"``; default UTC).
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
        When no block was identified, now or by an earlier run into the store (every
        block skipped, e.g. every block's fit failing or every block needing a file that
        cannot be read), naming the reasons; the run's ``blocks.csv`` lists each block
        and why.
    """
    if isinstance(inputs, str | os.PathLike):
        inputs = [inputs]
    log = dship
    if dship is not None and not isinstance(dship, pd.DataFrame):
        from data_contracts import read_dship

        log = read_dship(dship, mapping=dship_mapping, utc_offset=dship_utc_offset)
    run_options = {
        "store_dir": store_dir,
        "scheduler": scheduler,
        "n_workers": n_workers,
        "progress": progress,
        "batch_blocks": batch_blocks,
        "keep_removed_inputs": keep_removed_inputs,
        "dship": log,
        "dship_mapping": dship_mapping,
        "harmonics": harmonics,
    }
    if adaptive is not None:
        from ..identification.adaptive import identify_adaptive

        result = identify_adaptive(
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
        result = identify_voyage(list(inputs), out_dir, options=options, **run_options)
    summary = result.run
    if summary.processed == 0 and (summary.already_done == 0 or "poles" not in result.files):
        # never a silent success with nothing done: say why no block was identified (a
        # rerun over blocks an earlier run skipped gives the reasons it stored)
        skip_reasons = summary.skip_reasons
        if not skip_reasons and "blocks" in result.files:
            blocks = pd.read_csv(result.files["blocks"], usecols=["reason"], dtype=str)
            skip_reasons = blocks["reason"].dropna().value_counts().to_dict()
        reasons = sorted(skip_reasons.items(), key=lambda item: -item[1])
        why = "; ".join(f"{reason} ({n})" for reason, n in reasons[:3]) or "no block planned"
        more = f"; {len(reasons) - 3} more reasons in blocks.csv" if len(reasons) > 3 else ""
        raise WorkbenchError(
            f"no block identified: all {summary.skipped + summary.already_done} block(s) "
            f"skipped: {why}{more}"
        )
    if log is not None and "channels" in result.files:
        from data_contracts.dship_names import parse_utc_offset

        from ..predictors.clock import log_clock_warning

        offset = None if dship_utc_offset is None else parse_utc_offset(dship_utc_offset)
        source = "the ship log" if isinstance(dship, pd.DataFrame) else str(dship)
        warning = log_clock_warning(
            result.files["channels"], log, source, offset, result.files.get("blocks")
        )
        result.warnings += [warning] * bool(warning)
    return result
