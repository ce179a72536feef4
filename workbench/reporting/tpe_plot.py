"""Stabilisation diagram with the total prediction error (TPE) of every model order beside it.

Left: the stabilisation diagram of an SSI (or LSCF) result
(:func:`~workbench.reporting.stabilisation_plot.plot_stabilisation`); right, on the same
model-order axis: the TPE of the SSI-data innovation model
(:func:`workbench.sid.tpe.total_prediction_error`), measured on the data and as the model
expects it. Where the TPE stops falling, the physical modes are in the model; orders
above add noise modes to the diagram but no predictive power.
"""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ..results import save_figure
from ..sid.tpe import PredictionErrors
from .stabilisation_plot import plot_stabilisation

__all__ = ["plot_stabilisation_with_tpe", "write_stabilisation_tpe_figure"]


def plot_stabilisation_with_tpe(result, errors: PredictionErrors, acceleration=None, **kwargs):
    """Stabilisation diagram (left) and TPE over model order (right, shared order axis).

    Parameters
    ----------
    result : SSIResult or LSCFResult
        Poles of every model order.
    errors : PredictionErrors
        TPE per model order (:func:`workbench.sid.tpe.total_prediction_error`).
    acceleration : ndarray, optional
        Data for the background spectrum of the diagram.
    **kwargs
        Passed to :func:`~workbench.reporting.stabilisation_plot.plot_stabilisation`
        (``selection``, ``band_hz``, ``background``, ``title``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, (diagram, side) = plt.subplots(
        1,
        2,
        figsize=(12.5, 5.5),
        sharey=True,
        gridspec_kw={"width_ratios": [4, 1]},
        layout="constrained",
    )
    plot_stabilisation(result, acceleration, ax=diagram, **kwargs)
    orders = np.asarray(errors.orders)
    side.plot(
        100 * errors.total_prediction_error,
        orders,
        "o-",
        ms=3,
        color="tab:purple",
        label="on the data",
    )
    side.plot(
        100 * errors.model_prediction_error,
        orders,
        "--",
        color="0.5",
        lw=1,
        label="model's own",
    )
    side.set_xlabel("TPE [%]")
    side.set_title("Total prediction error")
    side.grid(True, alpha=0.3)
    side.legend(fontsize=8, loc="upper right")
    side.tick_params(labelleft=False)
    return fig


def write_stabilisation_tpe_figure(
    result,
    errors: PredictionErrors,
    path: str | os.PathLike,
    acceleration=None,
    *,
    dpi: int = 110,
    **kwargs,
) -> Path:
    """Draw :func:`plot_stabilisation_with_tpe` and write it atomically as PNG to *path*."""
    fig = plot_stabilisation_with_tpe(result, errors, acceleration, **kwargs)
    return save_figure(fig, path, dpi=dpi)
