"""Signal conditioning and blocks of accelerations.

Pure functions (:mod:`~workbench.signals.conditioning`, :mod:`~workbench.signals.moments`):
:func:`detrend`, :func:`decimate`, :func:`bandpass`, :func:`interpolate_nan_runs`,
:func:`moments`, :func:`faulty_channels`. The block builder
(:mod:`~workbench.signals.stream`): :func:`plan_blocks`, :func:`iter_blocks`,
:func:`load_block`. The NaN policy is described in :mod:`~workbench.signals.conditioning`,
the faulty-channel policy in :mod:`~workbench.signals.moments`, gaps between files in
:mod:`~workbench.signals.stream`.
"""

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
from .moments import WindowMoments, faulty_channels, moments
from .stream import (
    AccelerationBlock,
    BlockPlan,
    FileInfo,
    PlannedBlock,
    iter_blocks,
    load_block,
    plan_blocks,
    read_file_info,
)

__all__ = [
    "MAX_INTERPOLATED_NAN_RUN_S",
    "AccelerationBlock",
    "BlockPlan",
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
    "read_file_info",
]
