"""Modal parameters from identified state-space models, for every model order at once.

Pure numerical functions used by both SSI variants (:mod:`workbench.sid.ssi`):

- :func:`modal_parameters`: discrete eigenvalues → natural frequency and damping ratio;
- :func:`normalise_shapes`: unit norm, largest component real and positive;
- :func:`modal_phase_collinearity`: MPC of complex shapes;
- :func:`poles_all_orders`: the poles and shapes of every model order of a stabilisation
  diagram from one observability basis (one QR, then one small eigenvalue problem per
  order).

The per-order eigenvalue problems run on the threads :mod:`workbench.sid.threads` allows.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from .threads import sid_threads

__all__ = [
    "OrderPoles",
    "modal_parameters",
    "modal_phase_collinearity",
    "normalise_shapes",
    "poles_all_orders",
]


def modal_parameters(
    discrete_eigenvalues: np.ndarray, sampling_rate_hz: float
) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequencies and damping ratios of discrete-time eigenvalues.

    Parameters
    ----------
    discrete_eigenvalues : ndarray of complex
        Eigenvalues μ of the discrete state matrix A. [-]
    sampling_rate_hz : float
        Sampling rate 1/Δt. [Hz]

    Returns
    -------
    frequency_hz : ndarray
        Undamped natural frequencies f. [Hz]
    damping_ratio : ndarray
        Damping ratios ζ (fractions; negative for growing poles). [-]

    Notes
    -----
    The continuous pole is λ = ln(μ)/Δt (principal logarithm), so

    .. math::

        f = \\frac{|\\ln μ|}{2π Δt}, \\qquad ζ = -\\frac{\\mathrm{Re}(\\ln μ)}{|\\ln μ|}.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        log_mu = np.log(np.asarray(discrete_eigenvalues, dtype=complex))
        magnitude = np.abs(log_mu)
        frequency = magnitude * sampling_rate_hz / (2.0 * np.pi)
        damping = -log_mu.real / magnitude
    return frequency, damping


def normalise_shapes(shapes: np.ndarray) -> np.ndarray:
    """Scale complex shapes (columns) to unit norm with the largest component real positive.

    Parameters
    ----------
    shapes : ndarray, shape (n_channels, n_modes)
        Complex mode shapes, one per column. [-]

    Returns
    -------
    ndarray, shape (n_channels, n_modes)
        Normalised copy. Zero columns stay zero.
    """
    shapes = np.asarray(shapes, dtype=complex)
    if shapes.size == 0:
        return shapes.copy()
    columns = np.arange(shapes.shape[1])
    largest = shapes[np.argmax(np.abs(shapes), axis=0), columns]
    norm = np.linalg.norm(shapes, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(norm > 0, np.conj(largest) / (np.abs(largest) * norm), 0.0)
    return shapes * factor


def modal_phase_collinearity(shapes: np.ndarray) -> np.ndarray:
    """Modal phase collinearity (MPC) of complex shapes (columns).

    Parameters
    ----------
    shapes : ndarray, shape (n_channels, n_modes) or (n_channels,)
        Complex mode shapes. [-]

    Returns
    -------
    ndarray, shape (n_modes,) or scalar
        MPC in [0, 1]; 1 for a mode whose components are all in phase or in antiphase
        (a real, "normal" mode), 0 for a circularly polarised one.

    Notes
    -----
    With φ = x + iy and S_xx = xᵀx, S_yy = yᵀy, S_xy = xᵀy, MPC is the squared
    normalised difference of the eigenvalues e₁ ≥ e₂ of [[S_xx, S_xy], [S_xy, S_yy]] [1]_:

    .. math::

        \\mathrm{MPC} = \\left(\\frac{e_1 - e_2}{e_1 + e_2}\\right)^2
        = \\frac{|φ^T φ|^2}{(φ^H φ)^2}.

    References
    ----------
    .. [1] R. S. Pappa, K. B. Elliott, A. Schenk, "Consistent-mode indicator for the
       eigensystem realization algorithm", Journal of Guidance, Control, and Dynamics
       16(5), 852-858, 1993. doi:10.2514/3.21092
    """
    shapes = np.asarray(shapes, dtype=complex)
    square = np.abs(np.sum(shapes * shapes, axis=0)) ** 2
    norm = np.sum(np.abs(shapes) ** 2, axis=0) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.clip(square / norm, 0.0, 1.0)


@dataclass(frozen=True)
class OrderPoles:
    """Physical poles of every model order, stacked (see :func:`poles_all_orders`).

    Parameters
    ----------
    model_order : ndarray of int, shape (n_poles,)
        Model order (state dimension) each pole belongs to.
    frequency_hz : ndarray, shape (n_poles,)
        Undamped natural frequencies. [Hz]
    damping_ratio : ndarray, shape (n_poles,)
        Damping ratios. [-]
    mode_shapes : ndarray of complex, shape (n_channels, n_poles)
        Normalised mode shapes Φ = CΨ, column k belongs to pole k. [-]
    discrete_eigenvalues : ndarray of complex, shape (n_poles,)
        Eigenvalues μ of A (positive imaginary part). [-]
    state_matrix : ndarray, shape (n_max, n_max), optional
        A = O↑⁺O↓ of the largest order in the coordinates of the observability basis
        given to :func:`poles_all_orders` (the realisation the SSI results report).
    """

    model_order: np.ndarray
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    mode_shapes: np.ndarray
    discrete_eigenvalues: np.ndarray
    state_matrix: np.ndarray | None = None


def poles_all_orders(
    observability: np.ndarray,
    n_outputs: int,
    orders: Sequence[int],
    sampling_rate_hz: float,
) -> OrderPoles:
    """Poles and mode shapes of every model order from one observability basis.

    Parameters
    ----------
    observability : ndarray, shape (n_outputs * block_rows, n_max)
        Columns spanning the extended observability matrix of the largest order, ordered
        by decreasing singular value (e.g. ``U[:, :n_max]`` of the SSI singular value
        decomposition, or ``W⁻¹ U`` for weighted variants). Any column scaling is allowed:
        it changes A by a similarity transform only.
    n_outputs : int
        Number of output channels l (rows per block row).
    orders : sequence of int
        Model orders to evaluate, each between 1 and n_max.
    sampling_rate_hz : float
        Sampling rate. [Hz]

    Returns
    -------
    OrderPoles
        Poles sorted by model order, then frequency. Only physical poles are kept: one
        per complex-conjugate pair (positive imaginary part of μ), real eigenvalues
        dropped, and 0 < f < f_s/2. Poles with negative damping are kept (they are never
        flagged stable).

    Notes
    -----
    For order n, O_n = Γ[:, :n] (first n columns). The shift structure of O_n gives
    A_n = O_n↑⁺ O_n↓ (O↑ without its last block row, O↓ without its first) and C_n its first
    block row. With one thin QR of the largest upper part, Γ↑ = Q R, the leading columns
    satisfy Γ↑[:, :n] = Q[:, :n] R[:n, :n], hence A_n = R_n^{-1} P_n with R_n = R[:n, :n]
    and P_n = (QᵀΓ↓)[:n, :n]. Because R⁻¹ is upper triangular, the leading block of the
    single matrix B = (QᵀΓ↓) R⁻¹ is

    .. math::

        B_{:n,:n} = P_n R_n^{-1} = R_n A_n R_n^{-1},

    similar to A_n: every order is the leading principal submatrix of one matrix, and an
    eigenvector χ of B_n gives ψ = R_n⁻¹χ of A_n, so the shapes are
    Φ = C_n ψ = (C R⁻¹)[:, :n] χ (again because R⁻¹ is upper triangular). After one QR and
    two triangular solves, each order costs one eigenvalue problem of size n (LAPACK
    geev), run single-threaded on :func:`thread_budget` Python threads (numpy releases
    the GIL there).
    """
    basis = np.asarray(observability, dtype=float)
    n_rows, n_max = basis.shape
    orders = [int(n) for n in orders]
    if max(orders) > n_max:
        raise ValueError(
            f"orders up to {max(orders)} need an observability basis with at "
            f"least {max(orders)} columns, got {n_max}"
        )
    upper = basis[:-n_outputs]
    lower = basis[n_outputs:]
    q, r = linalg.qr(upper, mode="economic", check_finite=False)
    projected = q.T @ lower  # P = Qᵀ Γ↓, (n_max, n_max)
    # B = P R⁻¹ and C R⁻¹ from  Bᵀ = R⁻ᵀ Pᵀ  (a lower-triangular solve)
    nested = linalg.solve_triangular(r, projected.T, trans="T", check_finite=False).T
    output = linalg.solve_triangular(r, basis[:n_outputs].T, trans="T", check_finite=False).T
    nested = np.ascontiguousarray(nested)
    state = linalg.solve_triangular(r, projected, check_finite=False)  # A = R⁻¹P, largest n

    def order_poles(n):
        mu, vectors = np.linalg.eig(nested[:n, :n])
        return _order_poles(n, mu, vectors, output, sampling_rate_hz)

    with sid_threads() as threads:
        if len(orders) >= 8 and threads > 1:
            with ThreadPoolExecutor(threads) as pool:
                # largest orders first, so that the threads finish together
                largest_first = sorted(orders, reverse=True)
                done = dict(zip(largest_first, pool.map(order_poles, largest_first), strict=True))
            parts = [done[n] for n in orders]
        else:
            parts = [order_poles(n) for n in orders]
    parts = [part for part in parts if part is not None]
    if not parts:
        return OrderPoles(
            np.zeros(0, dtype=int),
            np.zeros(0),
            np.zeros(0),
            np.zeros((n_outputs, 0), dtype=complex),
            np.zeros(0, dtype=complex),
            state,
        )
    model_order, frequency, damping, shapes, mu = (
        np.concatenate(column, axis=-1) for column in zip(*parts, strict=True)
    )
    return OrderPoles(model_order, frequency, damping, normalise_shapes(shapes), mu, state)


def _order_poles(
    n: int,
    mu: np.ndarray,
    vectors: np.ndarray,
    output: np.ndarray,
    sampling_rate_hz: float,
) -> tuple[np.ndarray, ...] | None:
    """(orders, f, ζ, shapes, μ) of the physical poles of order *n*, or None.

    *mu* and *vectors* are the eigenpairs of the order-n state matrix in the coordinates
    where *output* (its first n columns) is the output matrix.
    """
    nyquist = 0.5 * sampling_rate_hz
    keep = mu.imag > 0.0  # one per conjugate pair; real eigenvalues have Im == 0 exactly
    if not np.any(keep):
        return None
    mu = mu[keep]
    frequency, damping = modal_parameters(mu, sampling_rate_hz)
    physical = (frequency > 0.0) & (frequency < nyquist)
    if not np.any(physical):
        return None
    columns = np.flatnonzero(keep)[physical]
    mu, frequency, damping = mu[physical], frequency[physical], damping[physical]
    order = np.argsort(frequency, kind="stable")
    shapes = output[:, :n] @ vectors[:, columns[order]]
    return np.full(order.size, n), frequency[order], damping[order], shapes, mu[order]
