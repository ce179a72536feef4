"""Figures of a few blocks identified again: stabilisation diagrams, and SSI-data's total
prediction error beside them."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import pandas as pd

from .engine import _identify_data
from .options import IdentifyOptions
from .planning import _pick_tasks


def write_block_figures(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    n_blocks: int = 3,
    blocks: Sequence[int] | None = None,
) -> list[Path]:
    """Stabilisation diagrams (over the CMIF of the block) of a few blocks, as PNG files.

    The blocks are identified again from their files with *options* (the same settings as
    the stored results give the same diagrams); by default *n_blocks* spread evenly over
    the voyage, skipping blocks that cannot be identified.
    """
    from ..reporting.stabilisation_plot import write_stabilisation_figure

    plan, tasks, options = _pick_tasks(inputs, options or IdentifyOptions(), n_blocks, blocks)
    paths = []
    for task in tasks:
        try:
            data, result, selection = _identify_data(
                task, plan.grid, options, channels=plan.channels
            )
        except ValueError:
            continue
        if result is None:
            continue
        path = Path(out_dir) / f"stabilisation_block{task.block:06d}.png"
        paths.append(
            write_stabilisation_figure(
                result,
                path,
                data.acceleration,
                selection=selection,
                band_hz=options.selection_band(data.sampling_rate_hz),
                title=_block_title(
                    task, "LSCF" if options.method == "lscf" else "SSI-" + options.method
                ),
            )
        )
    return paths


def write_tpe_figures(
    inputs: Iterable[str | os.PathLike],
    out_dir: str | os.PathLike,
    *,
    options: IdentifyOptions | None = None,
    n_blocks: int = 3,
    blocks: Sequence[int] | None = None,
) -> list[Path]:
    """Stabilisation diagram of SSI-data with the total prediction error of every model
    order beside it (:func:`workbench.sid.tpe.total_prediction_error`), for a few blocks.

    SSI-data is used whatever *options.method* says (the TPE needs its Kalman gain), with
    the block rows, orders, weighting and references of *options*.
    """

    from ..reporting.tpe_plot import write_stabilisation_tpe_figure
    from ..sid.tpe import total_prediction_error

    options = dataclasses.replace(options or IdentifyOptions(), method="data", cross_check=False)
    plan, tasks, options = _pick_tasks(inputs, options, n_blocks, blocks)
    paths = []
    for task in tasks:
        try:
            data, result, selection = _identify_data(
                task, plan.grid, options, channels=plan.channels
            )
            if result is None:
                continue
            errors = total_prediction_error(
                data.acceleration,
                data.sampling_rate_hz,
                block_rows=options.block_rows,
                orders=options.orders,
                reference_channels=result.reference_channels,
                weighting=options.weighting,
            )
        except ValueError:
            continue
        path = Path(out_dir) / f"tpe_block{task.block:06d}.png"
        paths.append(
            write_stabilisation_tpe_figure(
                result,
                errors,
                path,
                data.acceleration,
                selection=selection,
                band_hz=options.selection_band(data.sampling_rate_hz),
                title=_block_title(task, f"SSI-data/{options.weighting}"),
            )
        )
    return paths


def _block_title(task, method: str) -> str:
    """Title of a block's figure: its number, start (UTC) and *method*."""
    return f"Block {task.block} ({pd.Timestamp(task.block_start):%Y-%m-%d %H:%M} UTC), {method}"
