"""Goodnight's sweep operator and the cross-product matrix of the centred, scaled candidate
columns and the response on one set of rows (see :func:`~workbench.stats.stepwise`, Notes)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: A candidate is collinear with the model (never added) when the fraction of its centred
#: sum of squares left unexplained by the model's terms, 1 - R²_j, is at most this.
COLLINEARITY_TOLERANCE = 1e-10


def _sweep(matrix: np.ndarray, pivot: int) -> None:
    """Sweep the symmetric *matrix* in place on *pivot* (Goodnight 1979; Dempster's SWP).

    With a = A[:, k] and d = A[k, k]: A ← A - a aᵀ / d, then A[:, k] = A[k, :] = a / d and
    A[k, k] = -1 / d. Sweeping the model's columns of [[XᵀX, Xᵀy], [yᵀX, yᵀy]] leaves the
    residual cross-products of the other columns, the coefficients in the pivot rows of the
    last column, -(XᵀX)⁻¹ in the pivot block and the residual sum of squares in the corner.
    """
    column = matrix[:, pivot].copy()
    pivot_value = column[pivot]
    scaled = column / pivot_value
    matrix -= column[:, None] * scaled  # the outer product a aᵀ / d
    matrix[:, pivot] = scaled
    matrix[pivot, :] = scaled
    matrix[pivot, pivot] = -1.0 / pivot_value


@dataclass
class _Problem:
    """Centred and scaled candidate columns and their cross-product matrix (one per row set)."""

    n: int
    centred: np.ndarray  # candidate columns minus their means (n x m; column 0 intercept: 0)
    means: np.ndarray  # column means (m,)
    scale: np.ndarray  # norms of the centred columns, 1 where a column is constant
    y_mean: float
    y_centred: np.ndarray
    sst: float
    cross: np.ndarray  # [[ZᵀZ, Zᵀy_c], [y_cᵀZ, y_cᵀy_c]] with Z = centred / scale


def _problem(candidates: np.ndarray, y: np.ndarray) -> _Problem:
    n, m = candidates.shape
    means = candidates.sum(axis=0) / n
    centred = candidates - means
    scale = np.sqrt(np.einsum("ij,ij->j", centred, centred))
    # a column constant up to rounding carries no information beyond the intercept; a
    # column with NaN on these rows is never a candidate here (zeroed)
    threshold = np.abs(means)
    threshold *= math.sqrt(n)
    np.maximum(threshold, 1e-300, out=threshold)
    threshold *= 1e-13
    flat = np.logical_not(scale > threshold)
    flat[0] = True  # the intercept is handled by the centring
    scale = np.where(flat, 1.0, scale)
    y_mean = float(y.sum() / n)
    augmented = np.empty((n, m + 1))
    y_centred = np.subtract(y, y_mean, out=augmented[:, m])
    np.divide(centred, scale, out=augmented[:, :m])
    if flat[1:].any():  # column 0, the intercept's, is 0 already (1 - 1)
        augmented[:, :m][:, flat] = 0.0
    cross = augmented.T @ augmented
    sst = float(cross[-1, -1])
    return _Problem(n, centred, means, scale, y_mean, y_centred, sst, cross)
