"""What SSI returns: the poles of every model order (:class:`SSIResult`, the pole table
shared with LSCF through :class:`PoleTableMixin`) and the state-space model of the largest
order (:class:`StochasticStateSpace`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from data_contracts import shapes_to_frame

from ..assurance import continuous_pole
from ..stabilisation import StabilityCriteria

__all__ = ["PoleTableMixin", "SSIResult", "SSIWarning", "StochasticStateSpace"]


class SSIWarning(UserWarning):
    """A secondary SSI product (noise covariances, Kalman gain) could not be computed."""


@dataclass(frozen=True, eq=False)
class StochasticStateSpace:
    """Identified stochastic state-space model at the largest model order.

    Channels are in the order of the input columns. Matrices are those of the forward model
    x_{k+1} = A x_k + w_k, y_k = C x_k + v_k with covariances Q = E[w wᵀ], R = E[v vᵀ],
    S = E[w vᵀ], and of its innovation form x̂_{k+1} = A x̂_k + K e_k, y_k = C x̂_k + e_k.
    Fields that a variant does not estimate are None: SSI-cov gives A, C, G (reference
    columns) and Λ₀; SSI-data gives all of them (see :func:`ssi_data`).

    Parameters
    ----------
    state_matrix : ndarray, shape (n, n)
        A (discrete time).
    output_matrix : ndarray, shape (n_channels, n)
        C. [m/s² per state unit]
    next_state_output_covariance : ndarray, shape (n, n_columns)
        G = E[x_{k+1} y_kᵀ]; for SSI-cov only the columns of the reference channels.
    output_covariance : ndarray, shape (n_channels, n_channels)
        Λ₀ = E[y_k y_kᵀ]. [(m/s²)²]
    reference_channels : tuple of int
        Input columns of the references (the columns of G for SSI-cov).
    process_noise_covariance, measurement_noise_covariance, cross_noise_covariance : ndarray
        Q (n, n), R (n_channels, n_channels), S (n, n_channels) (SSI-data).
    state_covariance : ndarray, shape (n, n)
        Σ = E[x xᵀ], the solution of the Lyapunov equation Σ = AΣAᵀ + Q (SSI-data, stable A).
    predicted_state_covariance : ndarray, shape (n, n)
        P = E[x̂ x̂ᵀ] of the steady-state Kalman predictor, from a discrete algebraic
        Riccati equation.
    kalman_gain : ndarray, shape (n, n_channels)
        K of the innovation form.
    innovation_covariance : ndarray, shape (n_channels, n_channels)
        E[e eᵀ]. [(m/s²)²]
    """

    state_matrix: np.ndarray
    output_matrix: np.ndarray
    next_state_output_covariance: np.ndarray
    output_covariance: np.ndarray
    reference_channels: tuple[int, ...]
    process_noise_covariance: np.ndarray | None = None
    measurement_noise_covariance: np.ndarray | None = None
    cross_noise_covariance: np.ndarray | None = None
    state_covariance: np.ndarray | None = None
    predicted_state_covariance: np.ndarray | None = None
    kalman_gain: np.ndarray | None = None
    innovation_covariance: np.ndarray | None = None

    @property
    def model_order(self) -> int:
        return int(self.state_matrix.shape[0])

    def output_correlation(self, lag: int) -> np.ndarray:
        """Model output correlation R_k = C A^{k-1} G (k ≥ 1) or Λ₀ (k = 0)."""
        if lag == 0:
            return self.output_covariance
        return (
            self.output_matrix
            @ np.linalg.matrix_power(self.state_matrix, lag - 1)
            @ self.next_state_output_covariance
        )


class PoleTableMixin:
    """What every identification result with ``poles`` (one row per pole: model_order,
    frequency_hz, damping_ratio, ...) and ``mode_shapes`` (n_channels x n_poles) offers:
    SSI (:class:`SSIResult`) and LSCF (:class:`~workbench.sid.plscf.LSCFResult`)."""

    poles: pd.DataFrame
    mode_shapes: np.ndarray

    @property
    def n_channels(self) -> int:
        return int(self.mode_shapes.shape[0])

    @property
    def continuous_poles(self) -> np.ndarray:
        """Continuous-time poles λ = -ζω + iω√(1-ζ²) of the rows of *poles*. [rad/s]"""
        return continuous_pole(
            self.poles["frequency_hz"].to_numpy(), self.poles["damping_ratio"].to_numpy()
        )

    def poles_frame(self, channels: Sequence[str], block: int | None = None) -> pd.DataFrame:
        """The poles with mode-shape columns, ready for the pole-table contract.

        Parameters
        ----------
        channels : sequence of str
            Names of the input columns (length n_channels).
        block : int, optional
            Block number; adds the ``block`` column first (required by the contract).

        Returns
        -------
        pandas.DataFrame
            ``[block,] model_order, frequency_hz, damping_ratio, stable, mpc``,
            ``shape_re_<channel>``..., ``shape_im_<channel>``...
        """
        return _with_shapes(self.poles, self.mode_shapes, channels, block)


def _with_shapes(
    table: pd.DataFrame, mode_shapes: np.ndarray, channels: Sequence[str], block: int | None
) -> pd.DataFrame:
    """*table* (one row per column of *mode_shapes*) with ``[block,]`` first and the
    ``shape_re_<channel>``, ``shape_im_<channel>`` columns last."""
    channels = list(channels)
    if len(channels) != mode_shapes.shape[0]:
        raise ValueError(
            f"channels has {len(channels)} names for {mode_shapes.shape[0]} identified channels"
        )
    frame = table.reset_index(drop=True)
    if block is not None:
        frame.insert(0, "block", np.full(len(frame), int(block), dtype=np.int64))
    shapes = shapes_to_frame(channels, mode_shapes.T, index=frame.index)
    return pd.concat([frame, shapes], axis=1)


@dataclass(frozen=True, eq=False)
class SSIResult(PoleTableMixin):
    """Poles of every model order of one SSI run (a stabilisation diagram).

    Parameters
    ----------
    poles : pandas.DataFrame
        One row per physical pole (one per complex-conjugate pair), sorted by model order
        then frequency: ``model_order``, ``frequency_hz`` [Hz], ``damping_ratio`` [-],
        ``stable`` (against the previous order, see :mod:`workbench.sid.stabilisation`),
        ``mpc`` (modal phase collinearity) — the pole-table contract without ``block``.
    mode_shapes : ndarray of complex, shape (n_channels, n_poles)
        Φ = CΨ, unit norm, largest component real and positive; column k belongs to row k
        of *poles*.
    sampling_rate_hz : float
        Sampling rate of the data. [Hz]
    block_rows : int
        Number of block rows i.
    orders : tuple of int
        Model orders of the diagram (also those without physical poles).
    singular_values : ndarray
        Leading singular values of the (weighted) matrix decomposed (the largest model
        order plus ten, or all if fewer).
    reference_channels : tuple of int
        Input columns used as references.
    method : str
        ``"ssi-cov"`` or ``"ssi-data/<weighting>"``.
    system : StochasticStateSpace
        The state-space model of the largest order.
    criteria : StabilityCriteria
        Criteria behind the ``stable`` column.
    output_correlations : ndarray, shape (2·block_rows, n_channels, n_references), optional
        SSI-cov: the estimated output correlations R_0 .. R_{2i-1} the block Toeplitz
        matrix is built from (R_k = Σ y_{m+k} y_{m,ref}ᵀ / (N - k), the data centred);
        :func:`~workbench.sid.ssi.covariance_driven.ssi_cov_halves` starts from them.
        None for SSI-data. [(m/s²)²]
    """

    poles: pd.DataFrame
    mode_shapes: np.ndarray
    sampling_rate_hz: float
    block_rows: int
    orders: tuple[int, ...]
    singular_values: np.ndarray
    reference_channels: tuple[int, ...]
    method: str
    system: StochasticStateSpace
    criteria: StabilityCriteria = field(default_factory=StabilityCriteria)
    output_correlations: np.ndarray | None = field(default=None, repr=False)
