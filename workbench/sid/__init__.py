"""System identification: stochastic subspace identification, stabilisation, MAC/MACXP.

Layers (bottom up): :mod:`workbench.sid.mac` (MAC and pole-weighted MACXP),
:mod:`workbench.sid.ssi` (covariance- and data-driven SSI, all model orders from one
decomposition), :mod:`workbench.sid.stabilisation` (stable poles between consecutive orders),
:mod:`workbench.sid.selection` (automatic choice of the physical modes of one block),
:mod:`workbench.sid.tracking` (modes followed across blocks).
"""

from workbench.sid.mac import continuous_pole, mac, macxp

__all__ = ["continuous_pole", "mac", "macxp"]
