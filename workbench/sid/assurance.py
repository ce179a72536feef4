"""Modal assurance criteria: MAC and the pole-weighted MACXP for complex modes.

Both functions compare the *columns* of two mode-shape arrays and return the matrix of
criteria between every pair of columns:

- ``shapes_a`` of shape (n_channels, n_a) and ``shapes_b`` of shape (n_channels, n_b) give an
  (n_a, n_b) array;
- a 1-D shape (n_channels,) stands for a single mode, and its axis is dropped from the result
  (two 1-D shapes give a scalar 0-d array, usable as a float).

Both criteria are invariant to a complex scale factor of either shape and lie in [0, 1].
A shape with zero norm gives NaN.
"""

from __future__ import annotations

import numpy as np

__all__ = ["continuous_pole", "mac", "macxp"]


def continuous_pole(frequency_hz, damping_ratio) -> np.ndarray:
    """Continuous-time pole (eigenvalue) of a damped mode with positive imaginary part.

    Parameters
    ----------
    frequency_hz : array_like
        Undamped natural frequency f. [Hz]
    damping_ratio : array_like
        Damping ratio ζ (fraction of critical, 0 <= ζ < 1). [-]

    Returns
    -------
    ndarray of complex
        λ, broadcast over the inputs. [rad/s]

    Notes
    -----
    With ω = 2πf,

    .. math::

        λ = -ζω + iω\\sqrt{1 - ζ^2},

    so that |λ| = ω and ζ = -Re(λ)/|λ|.
    """
    omega = 2.0 * np.pi * np.asarray(frequency_hz, dtype=float)
    zeta = np.asarray(damping_ratio, dtype=float)
    return -zeta * omega + 1j * omega * np.sqrt(1.0 - zeta**2)


def _as_columns(name: str, shapes) -> tuple[np.ndarray, bool]:
    """Shapes as a complex 2-D (n_channels, n_modes) array and whether the input was 1-D."""
    array = np.asarray(shapes)
    if array.ndim == 1:
        return array.astype(complex)[:, None], True
    if array.ndim == 2:
        return array.astype(complex), False
    raise ValueError(
        f"{name} must be 1-D (n_channels,) or 2-D (n_channels, n_modes), got shape {array.shape}"
    )


def _check_channels(a: np.ndarray, b: np.ndarray) -> None:
    if a.shape[0] != b.shape[0]:
        raise ValueError(
            f"shapes_a has {a.shape[0]} channels and shapes_b has {b.shape[0]}; they must match"
        )


def _squeeze(result: np.ndarray, a_is_1d: bool, b_is_1d: bool) -> np.ndarray:
    if a_is_1d and b_is_1d:
        return result[0, 0]
    if a_is_1d:
        return result[0]
    if b_is_1d:
        return result[:, 0]
    return result


def mac(shapes_a, shapes_b) -> np.ndarray:
    """Modal assurance criterion between every column of two (complex) shape arrays.

    Parameters
    ----------
    shapes_a : array_like, shape (n_channels, n_a) or (n_channels,)
        First set of mode shapes, one per column. [-]
    shapes_b : array_like, shape (n_channels, n_b) or (n_channels,)
        Second set of mode shapes. [-]

    Returns
    -------
    ndarray, shape (n_a, n_b)
        MAC values in [0, 1]; axes of 1-D inputs are dropped (scalar for two 1-D inputs).

    Notes
    -----
    .. math::

        \\mathrm{MAC}(φ_a, φ_b) = \\frac{|φ_a^H φ_b|^2}{(φ_a^H φ_a)(φ_b^H φ_b)}

    References
    ----------
    .. [1] R. J. Allemang, "The modal assurance criterion - twenty years of use and abuse",
       Sound and Vibration 37(8), 14-23, 2003.
    """
    a, a_1d = _as_columns("shapes_a", shapes_a)
    b, b_1d = _as_columns("shapes_b", shapes_b)
    _check_channels(a, b)
    cross = np.abs(a.conj().T @ b) ** 2
    norm_a = np.einsum("ij,ij->j", a.conj(), a).real
    norm_b = np.einsum("ij,ij->j", b.conj(), b).real
    with np.errstate(divide="ignore", invalid="ignore"):
        result = cross / np.outer(norm_a, norm_b)
    return _squeeze(np.clip(result, 0.0, 1.0), a_1d, b_1d)


def mac_pairs(shapes_a: np.ndarray, shapes_b: np.ndarray) -> np.ndarray:
    """MAC of column k of *shapes_a* with column k of *shapes_b* (the diagonal of
    :func:`mac` without forming the matrix).

    Parameters
    ----------
    shapes_a, shapes_b : ndarray, shape (n_channels, n_pairs)
        Mode shapes, one pair per column. [-]

    Returns
    -------
    ndarray, shape (n_pairs,)
        MAC values in [0, 1].
    """
    a = np.asarray(shapes_a, dtype=complex)
    b = np.asarray(shapes_b, dtype=complex)
    if a.shape != b.shape or a.ndim != 2:
        raise ValueError(f"shapes_a {a.shape} and shapes_b {b.shape} must be equal 2-D shapes")
    cross = np.abs(np.einsum("ij,ij->j", a.conj(), b)) ** 2
    norm = np.einsum("ij,ij->j", a.conj(), a).real * np.einsum("ij,ij->j", b.conj(), b).real
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.clip(cross / norm, 0.0, 1.0)


def _as_poles(name: str, poles, n_modes: int, is_1d: bool) -> np.ndarray:
    array = np.atleast_1d(np.asarray(poles, dtype=complex))
    if array.ndim != 1 or array.size != n_modes:
        expected = "a scalar" if is_1d else f"{n_modes} values"
        raise ValueError(
            f"{name} must hold one pole per shape ({expected}), got shape {np.shape(poles)}"
        )
    if np.any(array.real >= 0.0) or np.any(array.imag == 0.0):
        raise ValueError(
            f"{name} must be complex poles with Re < 0 and Im != 0 (damped "
            f"oscillating modes), got {array.tolist()}"
        )
    return array


def macxp(shapes_a, poles_a, shapes_b, poles_b) -> np.ndarray:
    """Pole-weighted modal assurance criterion MACXP for complex modes.

    Parameters
    ----------
    shapes_a : array_like, shape (n_channels, n_a) or (n_channels,)
        First set of (complex) mode shapes, one per column. [-]
    poles_a : array_like, shape (n_a,) or scalar
        Continuous-time poles of *shapes_a*, λ = -ζω + iω√(1-ζ²), see
        :func:`continuous_pole`. [rad/s]
    shapes_b : array_like, shape (n_channels, n_b) or (n_channels,)
        Second set of mode shapes. [-]
    poles_b : array_like, shape (n_b,) or scalar
        Continuous-time poles of *shapes_b*. [rad/s]

    Returns
    -------
    ndarray, shape (n_a, n_b)
        MACXP values in [0, 1]; axes of 1-D inputs are dropped (scalar for two 1-D inputs).

    Notes
    -----
    MACXP is the squared cosine between the free responses (impulse responses)
    x(t) = φ e^{λt} + φ^* e^{λ^* t} of the two modes in L²(0, ∞), maximised over the
    phase of each shape [1]_:

    .. math::

        \\mathrm{MACXP}(a, b) = \\frac{
            \\left(\\frac{|φ_a^H φ_b|}{|λ_a^* + λ_b|}
                 + \\frac{|φ_a^T φ_b|}{|λ_a + λ_b|}\\right)^2}{
            \\left(\\frac{φ_a^H φ_a}{2|\\mathrm{Re}\\,λ_a|}
                 + \\frac{|φ_a^T φ_a|}{2|λ_a|}\\right)
            \\left(\\frac{φ_b^H φ_b}{2|\\mathrm{Re}\\,λ_b|}
                 + \\frac{|φ_b^T φ_b|}{2|λ_b|}\\right)}

    By the Cauchy-Schwarz inequality it lies in [0, 1]; MACXP(a, a) = 1, it is symmetric
    and invariant to a complex scale of either shape. The weights 1/|λ_a^* + λ_b| make
    modes with distant poles (frequency or damping) dissimilar even when their shapes are
    alike, which helps pairing with few sensors.

    References
    ----------
    .. [1] P. Vacher, B. Jacquier, A. Bucharles, "Extensions of the MAC criterion to complex
       modes", Proceedings of ISMA 2010, Leuven, 2713-2726, 2010.
    """
    a, a_1d = _as_columns("shapes_a", shapes_a)
    b, b_1d = _as_columns("shapes_b", shapes_b)
    _check_channels(a, b)
    lam_a = _as_poles("poles_a", poles_a, a.shape[1], a_1d)
    lam_b = _as_poles("poles_b", poles_b, b.shape[1], b_1d)

    hermitian = np.abs(a.conj().T @ b)  # |φ_a^H φ_b|
    transpose = np.abs(a.T @ b)  # |φ_a^T φ_b|
    numerator = (
        hermitian / np.abs(lam_a.conj()[:, None] + lam_b[None, :])
        + transpose / np.abs(lam_a[:, None] + lam_b[None, :])
    ) ** 2

    def self_term(shapes: np.ndarray, lam: np.ndarray) -> np.ndarray:
        # φ^H φ / (2|Re λ|) + |φ^T φ| / (2|λ|)
        norm = np.einsum("ij,ij->j", shapes.conj(), shapes).real
        square = np.abs(np.einsum("ij,ij->j", shapes, shapes))
        return norm / (2.0 * np.abs(lam.real)) + square / (2.0 * np.abs(lam))

    with np.errstate(divide="ignore", invalid="ignore"):
        result = numerator / np.outer(self_term(a, lam_a), self_term(b, lam_b))
    return _squeeze(np.clip(result, 0.0, 1.0), a_1d, b_1d)
