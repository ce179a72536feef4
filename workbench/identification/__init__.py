"""Block-wise system identification of a voyage, one module per responsibility.

:mod:`~workbench.identification.options` (what a run is asked to do),
:mod:`~workbench.identification.planning` (which files, which blocks),
:mod:`~workbench.identification.engine` (one block identified),
:mod:`~workbench.identification.voyage` (every block, in parallel and resumable),
:mod:`~workbench.identification.adaptive` (block length by conditions),
:mod:`~workbench.identification.export` (the store as contract tables),
:mod:`~workbench.identification.figures` and :mod:`~workbench.identification.crosscheck`
(a few blocks identified again). The package gathers their public names.
"""

from __future__ import annotations

from .adaptive import AdaptiveBlockOptions, identify_adaptive
from .crosscheck import cross_check_blocks
from .engine import identify_block, identify_from_files
from .export import export_store
from .figures import write_block_figures, write_tpe_figures
from .options import IdentifyOptions, IdentifyOptionsError, analysis_rate
from .planning import acceleration_files, input_fingerprints, plan_identification, resolved_run
from .voyage import IdentifyResult, identify_voyage

__all__ = [
    "AdaptiveBlockOptions",
    "IdentifyOptions",
    "IdentifyOptionsError",
    "IdentifyResult",
    "acceleration_files",
    "analysis_rate",
    "cross_check_blocks",
    "export_store",
    "identify_adaptive",
    "identify_block",
    "identify_from_files",
    "identify_voyage",
    "input_fingerprints",
    "plan_identification",
    "resolved_run",
    "write_block_figures",
    "write_tpe_figures",
]
