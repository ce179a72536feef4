"""System identification: stochastic subspace identification, stabilisation, MAC/MACXP.

Layers (bottom up): :mod:`workbench.sid.assurance` (MAC and pole-weighted MACXP),
:mod:`workbench.sid.modal` (modal parameters of every model order from one observability
basis), :mod:`workbench.sid.ssi` (covariance- and data-driven SSI),
:mod:`workbench.sid.stabilisation` (stable poles between consecutive orders),
:mod:`workbench.sid.selection` (automatic choice of the physical modes of one block; its
pole clustering in :mod:`workbench.sid.pole_clustering`),
:mod:`workbench.sid.tracking` (modes followed across blocks). Second method and checks:
:mod:`workbench.sid.plscf` (poly-reference LSCF), :mod:`workbench.sid.crosscheck` (SSI and
LSCF modes paired per block), :mod:`workbench.sid.tpe` (total prediction error per order).
"""

from workbench.sid.assurance import continuous_pole, mac, macxp
from workbench.sid.combined import combine_modes
from workbench.sid.crosscheck import agreement_by_block, cross_check
from workbench.sid.modal import modal_phase_collinearity, normalise_shapes
from workbench.sid.plscf import LSCFResult, lscf
from workbench.sid.selection import ModeSelection, select_modes
from workbench.sid.ssi import SSIResult, SSIWarning, StochasticStateSpace, ssi_cov, ssi_data
from workbench.sid.stabilisation import StabilityCriteria, stabilise, stability_flags
from workbench.sid.tpe import PredictionErrors, total_prediction_error

__all__ = [
    "LSCFResult",
    "ModeSelection",
    "PredictionErrors",
    "SSIResult",
    "SSIWarning",
    "StabilityCriteria",
    "StochasticStateSpace",
    "agreement_by_block",
    "combine_modes",
    "continuous_pole",
    "cross_check",
    "lscf",
    "mac",
    "macxp",
    "modal_phase_collinearity",
    "normalise_shapes",
    "select_modes",
    "ssi_cov",
    "ssi_data",
    "stabilise",
    "stability_flags",
    "total_prediction_error",
]
