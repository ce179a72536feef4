"""Poly-reference least-squares complex frequency-domain identification (pLSCF, PolyMAX).

A second, independent identification method beside SSI (:mod:`workbench.sid.ssi`), for
cross-checks. The output correlations are those SSI-cov computes
(:func:`workbench.sid.ssi.hankel._lagged_products`, exact sums by segmented FFT); their positive
half-spectra are fitted in a frequency band by a right matrix-fraction model in the
z-domain, the poles are the eigenvalues of the companion matrix of its denominator and the
mode shapes follow from the residues of the fitted model.

Layers: :func:`half_spectra` (windowed correlations → positive half-spectra),
:func:`lscf` (the estimator over all model orders) and :class:`LSCFResult` (poles in the
same table as :class:`~workbench.sid.ssi.SSIResult`, so :func:`~workbench.sid.stabilise`,
:func:`~workbench.sid.select_modes` and the stabilisation plot take either).

References
----------
.. [1] B. Peeters, H. Van der Auweraer, P. Guillaume, J. Leuridan, "The PolyMAX frequency-
   domain method: a new standard for modal parameter estimation?", Shock and Vibration
   11(3-4), 395-409, 2004. doi:10.1155/2004/523692
.. [2] P. Guillaume, P. Verboven, S. Vanlanduit, H. Van der Auweraer, B. Peeters, "A
   poly-reference implementation of the least-squares complex frequency-domain
   estimator", Proc. IMAC XXI, 2003.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import fft, linalg

from .modal import modal_parameters, modal_phase_collinearity, normalise_shapes
from .ssi.hankel import _lagged_products
from .ssi.preparation import _prepare
from .ssi.results import PoleTableMixin
from .stabilisation import StabilityCriteria, stability_flags
from .threads import sid_threads, thread_budget

__all__ = ["HalfSpectra", "LSCFResult", "half_spectra", "lscf"]

#: Default polynomial orders p of the right matrix-fraction model (state dimension p·r).
DEFAULT_ORDERS = range(1, 21)
#: Default number of correlation lags (capped by a quarter of the record).
DEFAULT_LAGS = 512
#: Value of the exponential window at the last lag.
DEFAULT_WINDOW_END = 0.01


@dataclass(frozen=True, eq=False)
class HalfSpectra:
    """Positive half-spectra S⁺(ω) = Σ_k w_k R_k e^{-iωkΔt} of standardised channels.

    Parameters
    ----------
    frequency_hz : ndarray, shape (n_lines,)
        Spectral lines (all lines from 0 to the Nyquist frequency). [Hz]
    spectra : ndarray of complex, shape (n_lines, n_channels, n_references)
        S⁺ of the channels divided by *channel_scale* (unit variance).
    channel_scale : ndarray, shape (n_channels,)
        Standard deviation of every channel. [unit of the channel]
    decay : float
        β of the exponential window w_k = e^{-βk} (w_0 = 1/2). [-]
    n_lags : int
        Correlation lags used (0 .. n_lags - 1).
    """

    frequency_hz: np.ndarray
    spectra: np.ndarray
    channel_scale: np.ndarray
    decay: float
    n_lags: int


def half_spectra(
    data: np.ndarray,
    sampling_rate_hz: float,
    references: np.ndarray,
    n_lags: int,
    window_end: float = DEFAULT_WINDOW_END,
) -> HalfSpectra:
    """Positive half-spectra of mean-free *data* (n_samples, n_channels).

    Every channel is scaled to unit variance first (velocity and acceleration channels
    then weigh alike in the fit). Correlations R_k = Σ_m y_{m+k} y_{m,ref}ᵀ / (N - k) are the
    exact lagged sums of SSI-cov; the exponential window e^{-βk} with e^{-β(n_lags-1)} =
    *window_end* makes the truncated correlation decay, and multiplies every discrete pole
    by e^{-β}, which :func:`lscf` undoes exactly. Lines are spaced f_s / (2·n_lags).
    """
    n_samples = data.shape[0]
    scale = data.std(axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    standard = data / scale
    sums = _lagged_products(standard, n_lags - 1, references)
    correlations = sums / (n_samples - np.arange(n_lags))[:, None, None]
    decay = -np.log(window_end) / max(n_lags - 1, 1)
    window = np.exp(-decay * np.arange(n_lags))
    window[0] = 0.5  # S = S⁺ + S⁺ᴴ
    n_fft = 2 * n_lags
    spectra = fft.rfft(correlations * window[:, None, None], n=n_fft, axis=0)
    frequency = fft.rfftfreq(n_fft, 1.0 / sampling_rate_hz)
    return HalfSpectra(frequency, spectra, scale, float(decay), int(n_lags))


@dataclass(frozen=True, eq=False)
class LSCFResult(PoleTableMixin):
    """Poles of every model order of one pLSCF run (a stabilisation diagram).

    Parameters
    ----------
    poles : pandas.DataFrame
        One row per physical pole, sorted by model order then frequency: ``model_order``
        (state dimension p·r of the order-p model with r references), ``frequency_hz`` [Hz],
        ``damping_ratio`` [-], ``stable``, ``mpc`` — the pole-table contract without
        ``block``, as for SSI.
    mode_shapes : ndarray of complex, shape (n_channels, n_poles)
        Shapes from the residues of the fitted model, unit norm, largest component real
        and positive, in the units of the input channels.
    participation_factors : ndarray of complex, shape (n_references, n_poles)
        Right null vectors of the denominator at each pole (unit norm).
    sampling_rate_hz : float
        Sampling rate of the data. [Hz]
    orders : tuple of int
        State dimensions p·r of the diagram (what ``model_order`` holds).
    polynomial_orders : tuple of int
        Polynomial orders p of the fitted models.
    band_hz : (float, float)
        Band of the fit; only poles inside it are kept. [Hz]
    n_lags : int
        Correlation lags of the half-spectra.
    reference_channels : tuple of int
        Input columns used as references.
    method : str
        ``"lscf"``.
    criteria : StabilityCriteria
        Criteria behind the ``stable`` column.
    """

    poles: pd.DataFrame
    mode_shapes: np.ndarray
    participation_factors: np.ndarray
    sampling_rate_hz: float
    orders: tuple[int, ...]
    polynomial_orders: tuple[int, ...]
    band_hz: tuple[float, float]
    n_lags: int
    reference_channels: tuple[int, ...]
    method: str = "lscf"
    criteria: StabilityCriteria = field(default_factory=StabilityCriteria)


def lscf(
    acceleration: np.ndarray,
    sampling_rate_hz: float,
    *,
    orders: Sequence[int] = DEFAULT_ORDERS,
    band_hz: tuple[float, float] | None = None,
    n_lags: int | None = None,
    reference_channels: Sequence[int] | None = None,
    window_end: float = DEFAULT_WINDOW_END,
) -> LSCFResult:
    """Poly-reference least-squares complex frequency-domain estimator (PolyMAX).

    Parameters
    ----------
    acceleration : ndarray, shape (n_samples, n_channels)
        Measured responses, finite (drop dead channels first); channels are scaled to unit
        variance internally, so mixed units are fine. [m/s² or m/s]
    sampling_rate_hz : float
        Sampling rate. [Hz]
    orders : sequence of int
        Polynomial orders p of the model (each gives p·r poles with r references).
    band_hz : (float, float), optional
        Band of the fit (default 0 to Nyquist); poles outside it are dropped. [Hz] The
        basis z^j is well conditioned when the band covers most of 0..Nyquist; in a
        narrow band high orders lose precision (normal equations): decimate first, or fit
        the whole range and select the modes in the band (:func:`~workbench.sid.
        select_modes` ``band_hz``); on the KOMA shear frame a narrow band left too few
        stable poles to select from, the whole range found every mode
        (``benchmarks/results/docstring_numbers.txt``).
    n_lags : int, optional
        Correlation lags 0..n_lags-1 (default 512, at most a quarter of the record). More
        lags give a finer frequency grid and a weaker window (less added damping).
    reference_channels : sequence of int, optional
        Columns used as references. Default: all.
    window_end : float
        Value of the exponential correlation window at the last lag, in (0, 1].

    Returns
    -------
    LSCFResult

    Raises
    ------
    ValueError
        NaN/inf in a channel (the message names its column index), too few samples,
        bad orders, band or lags.

    Notes
    -----
    For every output o the half-spectrum row H_o(ω) (1 × r) is modelled as
    B_o(z)A(z)^{-1} with z = e^{iωΔt}, B_o(z) = Σ_j β_{oj} z^j and A(z) = Σ_j α_j z^j
    (α_j: r × r), j = 0..p. This is exact for the correlations of a linear system:
    S⁺(z) = Λ₀/2 + C(zI - A)^{-1}G. The linearised error B_o - H_o A at the N_f lines of the
    band gives, per output, the normal-equation blocks

    .. math::

        R = \\mathrm{Re}(X^H X), \\quad S_o = \\mathrm{Re}(X^H Y_o),
        \\quad T_o = \\mathrm{Re}(Y_o^H Y_o),

    with X_{f,j} = z_f^j and Y_o = -X ⊗ H_o. β_o = -R^{-1}S_oα is eliminated, leaving
    M α = 0 with M = Σ_o (T_o - S_oᵀR^{-1}S_o), solved with α_p = I [1]_. All three
    blocks are (block) Toeplitz in j, k: they are built from the 2p + 1 moments
    Σ_f z_f^d (·), d = -p..p, so the cost does not grow with the number of lines. The
    poles μ are the eigenvalues of the block companion matrix of A(z); the participation
    factor v is the null vector of A(μ) (A(μ)v = 0, the first block of the companion
    eigenvector, here the right singular vector of A(μ) of its smallest singular value)
    and the residue of B A^{-1} at μ is proportional to B(μ)v wᵀ (wᵀA(μ) = 0), so the
    mode shape is φ = B(μ)v. The exponential window multiplied every μ by e^{-β}:
    μ ← μ e^{β}.
    """
    data, references, _ = _prepare(acceleration, sampling_rate_hz, 2, (1,), reference_channels)
    n_samples, n_channels = data.shape
    n_refs = references.size
    nyquist = 0.5 * float(sampling_rate_hz)
    orders = list(orders)
    poly_orders = sorted({int(p) for p in orders})
    if not poly_orders or poly_orders[0] < 1:
        raise ValueError(f"orders={orders!r} must be positive polynomial orders")
    if n_lags is None:
        n_lags = min(DEFAULT_LAGS, n_samples // 4)
    if int(n_lags) != n_lags or n_lags < 8 or n_lags > n_samples // 2:
        raise ValueError(
            f"n_lags={n_lags} must be an integer between 8 and half the record "
            f"({n_samples // 2} samples)"
        )
    n_lags = int(n_lags)
    if not (0.0 < window_end <= 1.0):
        raise ValueError(f"window_end={window_end} must lie in (0, 1]")
    limits = (0.0, nyquist) if band_hz is None else band_hz
    values = [float(v) for v in limits]
    if len(values) != 2 or not (0.0 <= values[0] < values[1] <= nyquist):
        raise ValueError(
            f"band_hz={band_hz!r} must be (low, high) with "
            f"0 <= low < high <= {nyquist:g} Hz (Nyquist)"
        )
    band = (values[0], values[1])
    with sid_threads():
        spectra = half_spectra(data, sampling_rate_hz, references, n_lags, window_end)
        lines = (spectra.frequency_hz >= band[0]) & (spectra.frequency_hz <= band[1])
        n_lines = int(lines.sum())
        p_max = poly_orders[-1]
        if n_lines < 2 * (p_max + 1):
            raise ValueError(
                f"orders up to {p_max} need more spectral lines than the {n_lines} in "
                f"band_hz={band}: widen the band or raise n_lags"
            )
        parts = _fit_orders(
            spectra.spectra[lines],
            spectra.frequency_hz[lines],
            float(sampling_rate_hz),
            poly_orders,
            spectra.decay,
            band,
        )
    model_order, frequency, damping, shapes, participation = _stack(parts, n_channels, n_refs)
    shapes = normalise_shapes(shapes * spectra.channel_scale[:, None])
    state_orders = tuple(p * n_refs for p in poly_orders)
    criteria = StabilityCriteria()
    frame = pd.DataFrame(
        {
            "model_order": model_order.astype(np.int64),
            "frequency_hz": frequency,
            "damping_ratio": damping,
            "stable": stability_flags(
                model_order, frequency, damping, shapes, state_orders, criteria
            ),
            "mpc": modal_phase_collinearity(shapes),
        }
    )
    return LSCFResult(
        poles=frame,
        mode_shapes=shapes,
        participation_factors=participation,
        sampling_rate_hz=float(sampling_rate_hz),
        orders=state_orders,
        polynomial_orders=tuple(poly_orders),
        band_hz=(float(band[0]), float(band[1])),
        n_lags=n_lags,
        reference_channels=tuple(int(c) for c in references),
        criteria=criteria,
    )


def _fit_orders(
    spectra: np.ndarray,
    frequency_hz: np.ndarray,
    sampling_rate_hz: float,
    poly_orders: list[int],
    decay: float,
    band: tuple[float, float],
) -> list[tuple]:
    """(orders, f, ζ, shapes, participation) of the in-band physical poles of each order."""
    n_lines, n_channels, n_refs = spectra.shape
    p_max = poly_orders[-1]
    z = np.exp(2j * np.pi * frequency_hz / sampling_rate_hz)
    lags = np.arange(-p_max, p_max + 1)
    powers = z[None, :] ** lags[:, None]  # (2p+1, N_f): z_f^d
    # moments Σ_f z^d, Σ_f z^d H_oc, Σ_f z^d (H^H H)_ce for d = -p_max..p_max
    moment_r = powers.sum(axis=1).real
    moment_s = (powers @ spectra.reshape(n_lines, -1)).real.reshape(-1, n_channels, n_refs)
    gram = np.einsum("foc,foe->fce", spectra.conj(), spectra)
    moment_t = (powers @ gram.reshape(n_lines, -1)).real.reshape(-1, n_refs, n_refs)

    def fit(p):
        return _fit_order(p, p_max, moment_r, moment_s, moment_t, sampling_rate_hz, decay, band)

    threads = thread_budget()
    if threads > 1 and len(poly_orders) >= 4:
        with ThreadPoolExecutor(threads) as pool:  # LAPACK releases the GIL
            largest_first = sorted(poly_orders, reverse=True)
            done = dict(zip(largest_first, pool.map(fit, largest_first), strict=True))
        parts = [done[p] for p in poly_orders]
    else:
        parts = [fit(p) for p in poly_orders]
    return [part for part in parts if part is not None]


def _fit_order(p, p_max, moment_r, moment_s, moment_t, sampling_rate_hz, decay, band):
    """Fit the order-p model from the moments and return its in-band physical poles."""
    n_channels, n_refs = moment_s.shape[1:]
    size = (p + 1) * n_refs
    j, k = np.meshgrid(np.arange(p + 1), np.arange(p + 1), indexing="ij")
    shift = p_max + k - j  # index of d = k - j
    r = moment_r[shift]  # R[j, k] = Re Σ z^{k-j}
    # S_o[j, (k, c)] = -Re Σ z^{k-j} H_oc  -> (o, j, k, c)
    s = -moment_s[shift].transpose(2, 0, 1, 3).reshape(n_channels, p + 1, size)
    # T[(j, c), (k, e)] = Re Σ z^{k-j} (HᴴH)_ce (summed over outputs)
    t = moment_t[shift].transpose(0, 2, 1, 3).reshape(size, size)
    try:
        chol = linalg.cholesky(r, lower=True, check_finite=False)  # R = LLᵀ
    except linalg.LinAlgError:  # too few or too close lines for this order
        return None
    # W_o = L⁻¹S_o for all outputs at once
    w = linalg.solve_triangular(
        chol, s.transpose(1, 0, 2).reshape(p + 1, -1), lower=True, check_finite=False
    ).reshape(p + 1, n_channels, size)
    flat = w.transpose(1, 0, 2).reshape(-1, size)
    m = t - flat.T @ flat  # M = Σ_o T_o - S_oᵀ R⁻¹ S_o
    m = 0.5 * (m + m.T)
    head = p * n_refs
    # α_p = I:  M[:pn, :pn] α_{0..p-1} = -M[:pn, pn:]
    try:
        with warnings.catch_warnings():
            # high orders over a narrow band are ill-conditioned; the poles stay usable
            # and the stabilisation diagram sorts them out
            warnings.simplefilter("ignore", linalg.LinAlgWarning)
            alpha_low = -linalg.solve(m[:head, :head], m[:head, head:], assume_a="sym")
    except (linalg.LinAlgError, ValueError):
        return None
    alpha = np.vstack([alpha_low, np.eye(n_refs)])  # ((p+1) r, r)
    companion = np.zeros((head, head))
    companion[: head - n_refs, n_refs:] = np.eye(head - n_refs)
    companion[head - n_refs :] = (
        -alpha_low.reshape(p, n_refs, n_refs).transpose(1, 0, 2).reshape(n_refs, head)
    )
    mu_window = linalg.eigvals(companion, overwrite_a=True, check_finite=False)
    mu_window = mu_window[mu_window.imag > 0]
    if not mu_window.size:
        return None
    mu = mu_window * np.exp(decay)  # undo the exponential window
    frequency, damping = modal_parameters(mu, sampling_rate_hz)
    inside = (frequency >= band[0]) & (frequency <= band[1]) & (frequency > 0)
    inside &= frequency < 0.5 * sampling_rate_hz
    if not np.any(inside):
        return None
    order = np.argsort(frequency[inside], kind="stable")
    mu_window = mu_window[inside][order]
    frequency, damping = frequency[inside][order], damping[inside][order]
    # participation: the null vector v of A(μ_w) = Σ_j α_j μ_w^j (the first block of the
    # companion eigenvector), as the right singular vector of the smallest singular value
    mu_powers = mu_window[None, :] ** np.arange(p + 1)[:, None]  # (p+1, m)
    denominator = np.einsum("jm,jab->mab", mu_powers, alpha.reshape(p + 1, n_refs, n_refs))
    participation = np.linalg.svd(denominator)[2][:, -1, :].conj().T  # (r, m), unit norm
    # φ_o = B_o(μ_w)v with β_o = -R⁻¹S_oα = -L⁻ᵀW_oα, evaluated at the windowed pole μ_w
    weighted = w @ (alpha @ participation)  # (p+1, o, m): W_o α v
    coefficients = linalg.solve_triangular(
        chol, weighted.reshape(p + 1, -1), lower=True, trans="T", check_finite=False
    ).reshape(p + 1, n_channels, -1)
    shapes = -np.einsum("jom,jm->om", coefficients, mu_powers)
    return (
        np.full(frequency.size, p * n_refs),
        frequency,
        damping,
        shapes,
        participation,
    )


def _stack(parts, n_channels, n_refs):
    if not parts:
        return (
            np.zeros(0, dtype=np.int64),
            np.zeros(0),
            np.zeros(0),
            np.zeros((n_channels, 0), dtype=complex),
            np.zeros((n_refs, 0), dtype=complex),
        )
    return tuple(np.concatenate(column, axis=-1) for column in zip(*parts, strict=True))
