"""Contracts of the structural-health chart: per-block statistic and alarm episodes."""

from __future__ import annotations

import pandas as pd

from ._core import Column, TableContract, Violation

__all__ = ["ALARMS", "HEALTH"]


def _end_not_before_start(frame: pd.DataFrame) -> list[Violation]:
    bad = (frame["end_block"] < frame["start_block"]).to_numpy(dtype=bool, na_value=False)
    if not bad.any():
        return []
    rows = tuple(frame.index[bad][:5].tolist())
    return [Violation("end_block", "alarm ends before it starts", rows, int(bad.sum()))]


HEALTH = TableContract(
    name="health",
    description="Control chart of the standardised frequency residuals (measured minus "
    "operational/environmental model), one row per block: the chart's statistic (per-mode "
    "CUSUM, or MEWMA T²), its control limit and whether it alarms.",
    columns=(
        Column("block", "int", "Block number on the voyage's block grid.", minimum=0),
        Column("block_start", "time", "Start of the block, UTC.", unit="UTC"),
        Column(
            "phase",
            "str",
            "'reference' while the chart learns the in-control state, 'monitor' after.",
            allowed=("reference", "monitor"),
        ),
        Column("n_modes", "int", "Modes with a residual in this block.", minimum=0),
        Column(
            "statistic",
            "float",
            "CUSUM chart (default): max_j S_j / H_j of the modes' lower one-sided CUSUMs "
            "S_j over their decision intervals H_j (limit 1). MEWMA chart: Hotelling "
            "T² = zᵀ (Σ_z + D)⁻¹ z of the EWMA z of the residuals (D: the model's own "
            "uncertainty at the block; z reflected at 0 when only decreases are charted).",
            minimum=0.0,
        ),
        Column("limit", "float", "Control limit of the statistic.", minimum=0.0),
        Column("alarm", "bool", "statistic > limit in the monitoring phase."),
    ),
    unique=("block",),
)

ALARMS = TableContract(
    name="alarms",
    description="Alarm episodes of the health chart (consecutive alarming blocks), with "
    "their evidence.",
    columns=(
        Column("alarm", "int", "Episode number (1-based).", minimum=1),
        Column("start_block", "int", "First alarming block.", minimum=0),
        Column("end_block", "int", "Last alarming block.", minimum=0),
        Column("start_time", "time", "Start of the first alarming block, UTC.", unit="UTC"),
        Column("end_time", "time", "Start of the last alarming block, UTC.", unit="UTC"),
        Column("peak_block", "int", "Block of the largest statistic.", minimum=0),
        Column("peak_statistic", "float", "Largest statistic of the episode.", minimum=0.0),
        Column("limit", "float", "Control limit.", minimum=0.0),
        Column(
            "modes",
            "str",
            "Modes contributing most at the peak, with their share of the statistic "
            "(e.g. '3 (91 %); 5 (6 %)').",
        ),
        Column("top_mode", "int", "Mode with the largest contribution at the peak.", minimum=1),
        Column(
            "top_mode_shift_percent",
            "float",
            "Estimated change of the top mode's frequency: CUSUM, its mean relative "
            "residual since the CUSUM last left 0 (the estimated change point); MEWMA, "
            "its median relative residual over the episode minus its reference median. [%]",
            unit="%",
            nullable=True,
        ),
    ),
    unique=("alarm",),
    checks=(_end_not_before_start,),
)
