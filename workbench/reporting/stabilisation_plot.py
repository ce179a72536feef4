"""Stabilisation diagram figure: poles by model order over a mode indicator function.

The background is the complex mode indicator function (CMIF, the largest singular values
of the cross-spectral density matrix at each frequency) or the average auto power
spectrum of the channels; the foreground shows every pole of an
:class:`~workbench.sid.ssi.SSIResult` at its model order, stable poles (see
:mod:`workbench.sid.stabilisation`) filled, unstable ones as small grey dots, and the modes
chosen by :func:`~workbench.sid.selection.select_modes` as vertical lines.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import matplotlib.pyplot as plt
import numpy as np
from scipy import fft, signal

from ..results import save_figure
from ..sid.selection import ModeSelection
from ..sid.ssi import SSIResult

__all__ = [
    "cross_spectral_density",
    "mode_indicator",
    "plot_stabilisation",
    "write_stabilisation_figure",
]


def cross_spectral_density(
    acceleration: np.ndarray, sampling_rate_hz: float, *, segment_length: int = 1024
) -> tuple[np.ndarray, np.ndarray]:
    """Welch estimate of the cross-spectral density matrix of all channels.

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        Accelerations, finite. [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    segment_length : int
        Samples per Hann-windowed segment (50 % overlap); frequency resolution
        f_s / segment_length.

    Returns
    -------
    frequency_hz : ndarray, shape (n_frequencies,)
        [Hz]
    csd : ndarray of complex, shape (n_frequencies, n_channels, n_channels)
        One-sided cross-spectral densities G_jk(f) = 2 E[X_j X_k^*] / (f_s Σw²),
        Hermitian at each frequency. [(m/s²)²/Hz]
    """
    data = np.asarray(acceleration, dtype=float)
    data = data - data.mean(axis=0)
    n_samples = data.shape[0]
    segment_length = int(min(segment_length, n_samples))
    step = segment_length // 2
    window = signal.windows.hann(segment_length, sym=False)
    starts = np.arange(0, n_samples - segment_length + 1, step)
    segments = np.stack([data[s : s + segment_length] for s in starts])  # (n_seg, L, l)
    spectra = fft.rfft(segments * window[None, :, None], axis=1)  # (n_seg, n_f, l)
    scale = 2.0 / (sampling_rate_hz * np.sum(window**2) * len(starts))
    csd = np.einsum("sfa,sfb->fab", spectra, spectra.conj()) * scale
    csd[0] /= 2.0
    if segment_length % 2 == 0:
        csd[-1] /= 2.0
    frequency = fft.rfftfreq(segment_length, d=1.0 / sampling_rate_hz)
    return frequency, csd


def mode_indicator(
    acceleration: np.ndarray,
    sampling_rate_hz: float,
    *,
    n_values: int = 1,
    segment_length: int = 1024,
) -> tuple[np.ndarray, np.ndarray]:
    """Complex mode indicator function: largest singular values of the CSD matrix.

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        Accelerations. [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    n_values : int
        Number of singular values per frequency (1 = the first CMIF curve).
    segment_length : int
        Welch segment length, see :func:`cross_spectral_density`.

    Returns
    -------
    frequency_hz : ndarray, shape (n_frequencies,)
    singular_values : ndarray, shape (n_frequencies, n_values)
        Largest first. [(m/s²)²/Hz]

    Notes
    -----
    The CSD matrix is Hermitian positive semi-definite, so its singular values are its
    eigenvalues; peaks of the first one mark modes [1]_.

    References
    ----------
    .. [1] C. Y. Shih, Y. G. Tsuei, R. J. Allemang, D. L. Brown, "Complex mode indication
       function and its applications to spatial domain parameter estimation", Mechanical
       Systems and Signal Processing 2(4), 367-377, 1988. doi:10.1016/0888-3270(88)90060-X
    """
    frequency, csd = cross_spectral_density(
        acceleration, sampling_rate_hz, segment_length=segment_length
    )
    values = np.linalg.eigvalsh(csd)[:, ::-1][:, :n_values]
    return frequency, np.clip(values, 0.0, None)


def plot_stabilisation(
    result: SSIResult,
    acceleration: np.ndarray | None = None,
    *,
    selection: ModeSelection | None = None,
    background: Literal["cmif", "psd"] = "cmif",
    band_hz: tuple[float, float] | None = None,
    title: str | None = None,
    ax=None,
):
    """Draw a stabilisation diagram.

    Parameters
    ----------
    result : SSIResult
        Poles of every model order.
    acceleration : ndarray, shape (n_samples, n_channels), optional
        The data the result was identified from; draws the background spectrum.
    selection : ModeSelection, optional
        Selected modes, drawn as vertical lines.
    background : {"cmif", "psd"}
        First CMIF curve, or the mean auto power spectral density of the channels.
    band_hz : (float, float), optional
        Frequency axis limits. Default 0 to Nyquist. [Hz]
    title : str, optional
        Axes title.
    ax : matplotlib Axes, optional
        Axes to draw into; default a new figure.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (close it with ``plt.close(fig)``).
    """
    if background not in ("cmif", "psd"):
        raise ValueError(f"background={background!r} must be 'cmif' or 'psd'")
    if ax is None:
        fig, ax = plt.subplots(figsize=(10, 5.5), layout="constrained")
    else:
        fig = ax.figure
    nyquist = result.sampling_rate_hz / 2
    band = band_hz if band_hz is not None else (0.0, nyquist)

    if acceleration is not None:
        spectrum_ax = ax.twinx()
        if background == "cmif":
            frequency, values = mode_indicator(acceleration, result.sampling_rate_hz)
            curve, label = values[:, 0], "CMIF (1st singular value of CSD)"
        else:
            frequency, csd = cross_spectral_density(acceleration, result.sampling_rate_hz)
            curve = np.mean(np.real(np.diagonal(csd, axis1=1, axis2=2)), axis=1)
            label = "mean auto PSD"
        inside = (frequency >= band[0]) & (frequency <= band[1]) & (curve > 0)
        spectrum_ax.semilogy(frequency[inside], curve[inside], color="0.55", lw=0.9, zorder=0)
        spectrum_ax.set_ylabel(f"{label} [(m/s²)²/Hz]", color="0.4")
        spectrum_ax.tick_params(axis="y", colors="0.4")
        ax.set_zorder(spectrum_ax.get_zorder() + 1)
        ax.patch.set_visible(False)

    poles = result.poles
    stable = poles["stable"].to_numpy(dtype=bool)
    frequency = poles["frequency_hz"].to_numpy()
    order = poles["model_order"].to_numpy()
    ax.plot(frequency[~stable], order[~stable], ".", ms=3, color="0.65", label="unstable pole")
    ax.plot(
        frequency[stable],
        order[stable],
        "o",
        ms=4,
        mfc="tab:blue",
        mec="tab:blue",
        label=(
            f"stable (Δf<{result.criteria.frequency_tol:.0%}, "
            f"Δζ<{result.criteria.damping_tol:.0%}, MAC>{result.criteria.mac_min:g})"
        ),
    )
    if selection is not None and len(selection.modes):
        for k, f in enumerate(selection.modes["frequency_hz"]):
            ax.axvline(
                f, color="tab:red", lw=0.9, ls="--", label="selected mode" if k == 0 else None
            )
        if selection.model_order is not None:
            ax.axhline(selection.model_order, color="tab:red", lw=0.6, alpha=0.5)
    ax.set_xlim(*band)
    ax.set_ylim(0, max(result.orders) + 2)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("model order")
    ax.set_title(title or f"Stabilisation diagram ({result.method}{_rows(result)})")
    ax.grid(True, alpha=0.3)
    # below the axes, so that no pole is hidden
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncols=3)
    return fig


def _rows(result) -> str:
    """The block rows ", i = 20" of an SSI result; empty for LSCF results."""
    rows = getattr(result, "block_rows", None)
    return "" if rows is None else f", i = {rows}"


def write_stabilisation_figure(
    result: SSIResult,
    path: str | os.PathLike,
    acceleration: np.ndarray | None = None,
    *,
    selection: ModeSelection | None = None,
    dpi: int = 110,
    **kwargs,
) -> Path:
    """Draw :func:`plot_stabilisation` and write it atomically as PNG to *path*."""
    fig = plot_stabilisation(result, acceleration, selection=selection, **kwargs)
    return save_figure(fig, path, dpi=dpi)
