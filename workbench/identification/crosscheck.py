"""SSI/LSCF cross-check of a few blocks of a voyage."""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import pandas as pd

from data_contracts.tables import write_grid_sidecar

from .engine import _cross_check_frame, _identify_data
from .export import _write_csv
from .options import IdentifyOptions
from .planning import _pick_tasks


def cross_check_blocks(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    n_blocks: int = 6,
    blocks: Sequence[int] | None = None,
) -> pd.DataFrame:
    """SSI/LSCF cross-check of a few blocks, written to ``out_dir/crosscheck.csv``.

    Each block is identified with *options* (its method) and with the other family (LSCF
    for SSI, SSI-cov for LSCF) and the selected modes are paired
    (:func:`workbench.sid.crosscheck.cross_check`). For every block of a voyage, run
    :func:`identify_voyage` with ``cross_check=True`` instead. Returns the table (empty if
    no block could be identified); :func:`workbench.sid.crosscheck.agreement_lines` and
    :func:`~workbench.sid.crosscheck.agreement_by_block` summarise it.
    """
    from threadpoolctl import threadpool_limits

    from ..sid.crosscheck import CROSS_CHECK_COLUMNS

    options = options or IdentifyOptions()
    plan, tasks, options = _pick_tasks(inputs, options, n_blocks, blocks)
    frames = []
    for task in tasks:
        try:
            with threadpool_limits(limits=1):
                _, result, selection, *other = _identify_data(
                    task, plan.grid, options, cross=True, channels=plan.channels
                )
        except ValueError:
            continue
        if result is None or other[0] is None:
            continue
        frames.append(
            _cross_check_frame(selection, other[0][1], options.method, task.block, task.block_start)
        )
    columns = ["block", "block_start", *CROSS_CHECK_COLUMNS[1:]]
    table = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_grid_sidecar(_write_csv(table, out / "crosscheck.csv"), plan.grid)
    return table
