"""Block-wise system identification of a voyage: files -> poles and selected modes per block.

:func:`identify_voyage` plans the blocks of a set of acceleration files (reading only file
headers), runs :func:`identify_block` on every block not yet done - in parallel with Dask,
on all local cores or on an existing cluster - into a resumable :class:`~workbench.store.
BlockStore`, and exports the store as contract tables:

* ``poles.parquet`` - stabilisation diagrams (POLES contract), one row per pole, block and
  model order, with mode shapes;
* ``selected.parquet`` - the automatically selected modes of each block (input of
  ``workbench track``), with the scatter of each mode's pole cluster
  (``frequency_std_hz``, ``damping_std``, ``n_poles``; see
  :mod:`workbench.sid.selection`); with ``cross_check`` also the combined modal model of
  the two methods (``combined_frequency_hz``, ``combined_frequency_std_hz``, ...; see
  :mod:`workbench.sid.combined`), which tracking carries into the tracked modal table and
  the forecast takes as the block's measurement scatter;
* ``faults.csv`` - channels dropped per block and why;
* ``channels.csv`` - per block and channel: RMS and kurtosis of the conditioned signal;
* ``blocks.csv`` - every block: ``ok`` or ``skipped`` and the reason;
* ``crosscheck.csv`` - with ``cross_check``: the SSI and LSCF modes of every block paired
  (:func:`workbench.sid.crosscheck.cross_check`), summarised in the run's summary.

Killing the job at any moment and running it again finishes it without recomputing the
blocks already stored, and gives the same tables as an uninterrupted run (every block's
result depends only on its own data and the options, which the store checks). The store
is locked while a run works on it, and every input file is fingerprinted (size,
modification time, SHA-256 of its content): a second run on a busy store, or a rerun on
changed files, is refused instead of mixing or reusing results of other data.

Every option is checked against the files' headers before the first block (rate, band,
reference channels, block rows against the samples of a block): an option that would make
every block fail raises :class:`~workbench.errors.OptionError` at once.

The work lives in :mod:`workbench.identification`, one module per responsibility: the
options (:mod:`~workbench.identification.options`), file discovery and planning
(:mod:`~workbench.identification.planning`), the per-block engine
(:mod:`~workbench.identification.engine`), the voyage runner
(:mod:`~workbench.identification.voyage`), the export of the store
(:mod:`~workbench.identification.export`), the figures
(:mod:`~workbench.identification.figures`) and the SSI/LSCF cross-check
(:mod:`~workbench.identification.crosscheck`). This module gathers their names.
"""

from __future__ import annotations

from .identification.crosscheck import (  # noqa: F401
    cross_check_blocks,
)
from .identification.engine import (  # noqa: F401
    BlockTask,
    _block_tasks,
    _channel_statistics,
    _conditioner_settings,
    _cross_check_frame,
    _file_tasks,
    _FileTask,
    _full_channels,
    _identify_data,
    _identify_method,
    _reachable_orders,
    _reason_kind,
    _selected_frame,
    channel_check_options,
    conditioning_band,
    identify_block,
    identify_from_files,
)
from .identification.export import (  # noqa: F401
    _NothingWritten,
    _write_csv,
    _write_parquet_chunks,
    export_store,
)
from .identification.figures import (  # noqa: F401
    write_block_figures,
    write_tpe_figures,
)
from .identification.options import (  # noqa: F401
    _LOWEST_DAMPING,
    ACCELERATION_SUFFIXES,
    ANTI_ALIAS_EDGE,
    DEFAULT_MODE_CEILING_HZ,
    IdentifyOptions,
    IdentifyOptionsError,
    analysis_rate,
)
from .identification.planning import (  # noqa: F401
    _pick_tasks,
    _records,
    acceleration_files,
    input_fingerprints,
    plan_identification,
    resolved_run,
)
from .identification.voyage import (  # noqa: F401
    IdentifyResult,
    _check_run_options,
    identify_voyage,
)

__all__ = [
    "IdentifyOptions",
    "IdentifyOptionsError",
    "IdentifyResult",
    "cross_check_blocks",
    "identify_block",
    "identify_voyage",
    "write_block_figures",
    "write_tpe_figures",
]
