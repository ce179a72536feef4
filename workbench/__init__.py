"""workbench: hull vibration monitoring for ships.

Stages (each reads and writes the tables of :mod:`data_contracts`):
:mod:`workbench.signals` (conditioning, blocks), :mod:`workbench.sid` (stochastic subspace
identification, stabilisation, MAC/MACXP, tracking), :mod:`workbench.predictors` (ship log
onto blocks), :mod:`workbench.stats` (correlation, stepwise regression),
:mod:`workbench.forecast` (sliding model, Kalman blending), :mod:`workbench.reporting`.
"""

__version__ = "0.1.0"
