"""Former home of the block planning and the block builder, kept so that old imports work.

Planning blocks from file headers lives in :mod:`workbench.signals.block_plan`
(:func:`plan_blocks`, :func:`read_file_info`, :class:`BlockPlan`), building the conditioned
blocks in :mod:`workbench.signals.block_builder` (:func:`iter_blocks`, :func:`load_block`,
:class:`AccelerationBlock`).
"""

from __future__ import annotations

from .block_builder import AccelerationBlock, iter_blocks, load_block
from .block_plan import (
    BlockPlan,
    FileInfo,
    PlannedBlock,
    plan_blocks,
    plan_file_infos,
    read_file_info,
)

__all__ = [
    "AccelerationBlock",
    "BlockPlan",
    "FileInfo",
    "PlannedBlock",
    "iter_blocks",
    "load_block",
    "plan_blocks",
    "plan_file_infos",
    "read_file_info",
]
