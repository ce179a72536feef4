"""Signal conditioning and blocks of accelerations.

Pure functions (:mod:`~workbench.signals.conditioning`, :mod:`~workbench.signals.moments`):
:func:`detrend`, :func:`decimate`, :func:`bandpass`, :func:`interpolate_nan_runs`,
:func:`moments`, :func:`faulty_channels`. Blocks: planned from the file headers
(:mod:`~workbench.signals.block_plan`: :func:`plan_blocks`, :func:`read_file_info`) and
built (:mod:`~workbench.signals.block_builder`: :func:`iter_blocks`, :func:`load_block`;
:mod:`~workbench.signals.file_conditioning` conditions each file once instead). The NaN
policy is described in :mod:`~workbench.signals.conditioning`, the faulty-channel policy in
:mod:`~workbench.signals.moments`, gaps between files in
:mod:`~workbench.signals.block_plan`.
"""

from .block_builder import AccelerationBlock, ConditioningOptions, iter_blocks, load_block
from .block_plan import (
    BlockPlan,
    FileInfo,
    PlannedBlock,
    plan_blocks,
    plan_file_infos,
    read_file_info,
)
from .conditioning import (
    MAX_INTERPOLATED_NAN_RUN_S,
    SignalWarning,
    bandpass,
    decimate,
    decimation_stages,
    detrend,
    interpolate_nan_runs,
    nan_runs,
)
from .moments import ChannelCheckOptions, WindowMoments, faulty_channels, moments

__all__ = [
    "MAX_INTERPOLATED_NAN_RUN_S",
    "AccelerationBlock",
    "BlockPlan",
    "ChannelCheckOptions",
    "ConditioningOptions",
    "FileInfo",
    "PlannedBlock",
    "SignalWarning",
    "WindowMoments",
    "bandpass",
    "decimate",
    "decimation_stages",
    "detrend",
    "faulty_channels",
    "interpolate_nan_runs",
    "iter_blocks",
    "load_block",
    "moments",
    "nan_runs",
    "plan_blocks",
    "plan_file_infos",
    "read_file_info",
]
