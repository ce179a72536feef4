"""Records of structures with prescribed modes: close pairs and weakly excited modes.

The identification's hard cases, built from physics rather than from a modal table: a few
uncoupled modal oscillators (frequencies, damping ratios and real mode shapes given) driven
by independent Gaussian white-noise modal forces, simulated exactly (zero-order hold, see
:mod:`workbench.simulate.dynamics`), each mode's force scaled so that its modal acceleration has a
prescribed level; the channels are the modal superposition plus white sensor noise.

* :func:`shapes_with_mac` - two real shapes whose MAC is exactly a given value (a close
  pair whose shapes are alike, 0.9, or nearly orthogonal, 0.2);
* :func:`prescribed_mode_record` - the record and its truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamics import simulate_modal_response

__all__ = ["PrescribedRecord", "prescribed_mode_record", "shapes_with_mac"]


@dataclass(frozen=True)
class PrescribedRecord:
    """A simulated record and the modes that produced it.

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        Channel accelerations with sensor noise. [m/s²]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    frequency_hz, damping_ratio : ndarray, shape (n_modes,)
        The modes' natural frequencies [Hz] and damping ratios [-].
    mode_shapes : ndarray, shape (n_channels, n_modes)
        Real mode shapes (unit norm), column k for mode k.
    level_db : ndarray, shape (n_modes,)
        RMS of each mode's modal acceleration relative to the strongest mode. [dB]
    """

    acceleration: np.ndarray
    sampling_rate_hz: float
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    mode_shapes: np.ndarray
    level_db: np.ndarray


def shapes_with_mac(base: np.ndarray, mac_value: float, rng: np.random.Generator) -> np.ndarray:
    """A unit real shape whose MAC with *base* is *mac_value*.

    Parameters
    ----------
    base : ndarray, shape (n_channels,)
        Real shape (any norm, n_channels >= 2).
    mac_value : float
        Target MAC in [0, 1]. [-]
    rng : numpy.random.Generator
        Source of the direction orthogonal to *base*.

    Returns
    -------
    ndarray, shape (n_channels,)

    Notes
    -----
    For unit real vectors MAC = cos²θ, so the shape is cos θ·b + sin θ·u with u a random
    unit vector orthogonal to b and θ = arccos(√MAC).
    """
    base = np.asarray(base, dtype=float)
    if base.ndim != 1 or base.size < 2:
        raise ValueError(f"base must be one shape of at least 2 channels, got shape {base.shape}")
    if not 0.0 <= mac_value <= 1.0:
        raise ValueError(f"mac_value={mac_value} must lie in [0, 1]")
    b = base / np.linalg.norm(base)
    u = rng.standard_normal(b.size)
    u -= (u @ b) * b
    u /= np.linalg.norm(u)
    theta = np.arccos(np.sqrt(mac_value))
    return np.cos(theta) * b + np.sin(theta) * u


def prescribed_mode_record(
    frequency_hz,
    damping_ratio,
    mode_shapes: np.ndarray,
    *,
    sampling_rate_hz: float,
    duration_s: float,
    level_db=0.0,
    sensor_noise: float = 0.05,
    seed: int = 0,
) -> PrescribedRecord:
    """White-noise response of prescribed modes, each at a prescribed level.

    Parameters
    ----------
    frequency_hz, damping_ratio : array_like, shape (n_modes,)
        Natural frequencies [Hz] and damping ratios [-].
    mode_shapes : ndarray, shape (n_channels, n_modes)
        Real mode shapes (normalised to unit length here).
    sampling_rate_hz : float
        Sampling rate. [Hz]
    duration_s : float
        Record length. [s]
    level_db : float or array_like, shape (n_modes,)
        RMS of each mode's modal acceleration relative to 1 (0 dB), e.g. -15 for a mode
        excited 15 dB below the others. [dB]
    sensor_noise : float
        Standard deviation of the white sensor noise relative to each channel's RMS. [-]
    seed : int
        Seed of the forces and the noise.

    Returns
    -------
    PrescribedRecord
    """
    f = np.asarray(frequency_hz, dtype=float)
    zeta = np.broadcast_to(np.asarray(damping_ratio, dtype=float), f.shape).copy()
    shapes = np.asarray(mode_shapes, dtype=float)
    if shapes.ndim != 2 or shapes.shape[1] != f.size:
        raise ValueError(
            f"mode_shapes must have shape (n_channels, n_modes={f.size}), got {shapes.shape}"
        )
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"duration_s={duration_s} must be a positive number of seconds")
    level = np.broadcast_to(np.asarray(level_db, dtype=float), f.shape)
    shapes = shapes / np.linalg.norm(shapes, axis=0)
    n_samples = int(round(duration_s * sampling_rate_hz))
    rng = np.random.default_rng(seed)
    # modal accelerations to unit forces (identity shapes), then each scaled to its level:
    # the response is linear in the force, so this is the response to a scaled force
    modal = simulate_modal_response(
        f, zeta, np.eye(f.size), sampling_rate_hz, n_samples, rng=rng
    ).response
    modal *= 10.0 ** (level / 20.0) / modal.std(axis=0)
    response = modal @ shapes.T
    response += sensor_noise * response.std(axis=0) * rng.standard_normal(response.shape)
    return PrescribedRecord(response, float(sampling_rate_hz), f, zeta, shapes, level.copy())
