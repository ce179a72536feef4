"""Ship-log predictors on the block grid.

* :func:`block_predictors` -- average the canonical ship log (read it with
  :func:`read_dship`) over the blocks: coverage threshold, circular means for directions,
  despiking; returns the PREDICTORS table. :func:`block_coverage` gives the coverage;
  :func:`excitation_weighted_predictors` weights the average by the excitation, as SSI
  reads a block.
* :func:`flag_faulty` -- spikes (robust rolling z-score), faulty stretches and columns.
* :class:`Normaliser` -- z-scores whose parameters are kept (JSON) for new data.
* :func:`load_predictors` -- the PREDICTORS table of a stage, read or averaged from a
  DSHIP log; :func:`canonical_predictors` keeps the canonical columns.
"""

from data_contracts import read_dship

from ._common import PredictorWarning
from .averaging import (
    block_coverage,
    block_predictors,
    circular_mean_deg,
    excitation_weighted_predictors,
)
from .faults import FaultFlags, LogFaultOptions, flag_faulty
from .normalise import Normaliser
from .tables import canonical_predictors, load_predictors

__all__ = [
    "FaultFlags",
    "LogFaultOptions",
    "Normaliser",
    "PredictorWarning",
    "block_coverage",
    "block_predictors",
    "canonical_predictors",
    "circular_mean_deg",
    "excitation_weighted_predictors",
    "flag_faulty",
    "load_predictors",
    "read_dship",
]
