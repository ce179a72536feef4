"""Ship-log predictors on the block grid.

* :func:`block_predictors` -- average the canonical ship log (read it with
  :func:`read_dship`) over the blocks: coverage threshold, circular means for directions,
  despiking; returns the PREDICTORS table. :func:`block_coverage` gives the coverage.
* :func:`flag_faulty` -- spikes (robust rolling z-score), faulty stretches and columns.
* :class:`Normaliser` -- z-scores whose parameters are kept (JSON) for new data.
"""

from data_contracts import read_dship

from ._common import PredictorWarning
from .averaging import block_coverage, block_predictors, circular_mean_deg
from .faults import FaultFlags, flag_faulty
from .normalise import Normaliser

__all__ = [
    "FaultFlags",
    "Normaliser",
    "PredictorWarning",
    "block_coverage",
    "block_predictors",
    "circular_mean_deg",
    "flag_faulty",
    "read_dship",
]
