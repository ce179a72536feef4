"""A predictive model with memory: stepwise terms, coefficients by weighted least squares with
exponential forgetting over the whole history the ship has seen.

Term selection stays stepwise with interactions (:func:`workbench.stats.stepwise`, MATLAB
``stepwiselm`` semantics) on the most recent ``selection_blocks`` measured blocks, redone
every ``reselect_blocks``; the coefficients of the selected terms are re-estimated at every
refit from *all* earlier measured blocks, block k weighted λ^(age), λ = exp(-1 / memory).
That is exactly the estimate of recursive least squares with forgetting factor λ [1]_
(computed in batch, so a refit can change the terms), and unlike a 20-block window it keeps
the speed law learnt at other speeds while the ship holds one speed.

References
----------
.. [1] L. Ljung, T. Söderström, "Theory and Practice of Recursive Identification", MIT
   Press, 1983, ch. 2 (RLS with exponential forgetting = exponentially weighted LS).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["MemoryModel", "constant_model", "select_terms"]


@dataclass(frozen=True)
class MemoryModel:
    """A fitted model with memory for one mode.

    Parameters
    ----------
    kind : {"memory", "constant"}
    columns : tuple of int
        Positions of the candidate predictors in the predictor matrix.
    names : tuple of str
        Their names.
    terms : tuple of tuple of int
        Terms as positions into *columns*: () intercept, (a,) main effect, (a, b) product.
    mean, scale : ndarray
        Normalisation of *columns* (z-scores), from the selection window.
    coefficients : ndarray
        Estimates per term (normalised predictors). [Hz]
    covariance : ndarray
        (XᵀWX)⁻¹ with weights relative to the newest block (multiply by s²).
    residual_variance : float
        s² of the newest block. [Hz²]
    dof : float
        Effective residual degrees of freedom n_eff - p, n_eff = (Σw)² / Σw².
    n_train : int
        Measured blocks used.
    """

    kind: str
    columns: tuple[int, ...]
    names: tuple[str, ...]
    terms: tuple[tuple[int, ...], ...]
    mean: np.ndarray = field(repr=False)
    scale: np.ndarray = field(repr=False)
    coefficients: np.ndarray = field(repr=False)
    covariance: np.ndarray = field(repr=False)
    residual_variance: float
    dof: float
    n_train: int

    def needed_columns(self) -> list[int]:
        """Positions in the predictor matrix of the predictors its terms use."""
        return sorted({self.columns[c] for term in self.terms for c in term})

    def term_names(self) -> tuple[str, ...]:
        return tuple(":".join(self.names[c] for c in term) for term in self.terms if term)

    def design(self, X: np.ndarray, limit: float) -> np.ndarray:
        """Design matrix of raw predictor rows *X* (all columns), z-scores clipped ±limit."""
        with np.errstate(invalid="ignore", divide="ignore"):
            z = np.clip((X[:, list(self.columns)] - self.mean) / self.scale, -limit, limit)
        out = np.empty((X.shape[0], len(self.terms)))
        for k, term in enumerate(self.terms):
            if not term:
                out[:, k] = 1.0
            elif len(term) == 1:
                out[:, k] = z[:, term[0]]
            else:
                out[:, k] = z[:, term[0]] * z[:, term[1]]
        return out

    def predict(self, X: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
        """Mean [Hz] and mean-prediction variance s² x (XᵀWX)⁻¹ xᵀ [Hz²] of rows *X*."""
        D = self.design(X, limit)
        mean = D @ self.coefficients
        variance = self.residual_variance * np.einsum("ij,jk,ik->i", D, self.covariance, D)
        return mean, variance

    @classmethod
    def unfitted(
        cls,
        columns: Sequence[int],
        names: Sequence[str],
        terms: Sequence[Sequence[int]],
        mean: np.ndarray,
        scale: np.ndarray,
    ) -> MemoryModel:
        """The selected *terms* of predictors *columns* (*names*, z-scored with *mean* and
        *scale*) before any estimate: :meth:`refit` estimates its coefficients."""
        return cls(
            "memory",
            tuple(columns),
            tuple(names),
            tuple(tuple(t) for t in terms),
            np.asarray(mean, dtype=float),
            np.asarray(scale, dtype=float),
            np.empty(0),
            np.empty((0, 0)),
            math.nan,
            math.nan,
            0,
        )

    def refit(
        self, X: np.ndarray, y: np.ndarray, age: np.ndarray, *, memory_blocks: float, limit: float
    ) -> MemoryModel | None:
        """This model's terms and normalisation, the coefficients estimated again by
        exponentially weighted least squares of *y* on them.

        Parameters
        ----------
        X : ndarray, shape (n, n_predictors)
            Raw predictor rows of the measured blocks.
        y : ndarray, shape (n,)
            Measurements. [Hz]
        age : ndarray, shape (n,)
            Blocks between each row and the newest training block (0 for the newest). [blocks]
        memory_blocks : float
            Forgetting time constant, λ = exp(-1/memory_blocks). [blocks]
        limit : float
            Clipping of the z-scores (:meth:`design`).

        Returns
        -------
        MemoryModel or None when the rows cannot determine the terms.
        """
        D = self.design(X, limit)
        ok = np.isfinite(D).all(axis=1) & np.isfinite(y)
        D, y, age = D[ok], y[ok], age[ok]
        p = D.shape[1]
        w = np.exp(-age / memory_blocks)  # w = λ^age, newest block 1
        n_eff = w.sum() ** 2 / (w @ w) if w.size else 0.0
        if n_eff < p + 3:
            return None
        Dw = D * w[:, None]
        normal = Dw.T @ D  # XᵀWX
        solved = _solve_well_conditioned(normal, Dw.T @ y)
        if solved is not None:
            # β = (XᵀWX)⁻¹ XᵀWy: the same estimate as the SVD path below, to round-off
            beta, covariance = solved
        else:
            sw = np.sqrt(w)
            # β = argmin Σ w_k (y_k - x_k β)²
            beta, _, rank, _ = np.linalg.lstsq(D * sw[:, None], y * sw, rcond=None)
            if rank < p:
                return None
            covariance = np.linalg.pinv(normal)  # (XᵀWX)⁻¹
        resid = y - D @ beta
        dof = n_eff - p
        s2 = float((w * resid**2).sum() / w.sum() * n_eff / dof)  # weighted residual variance
        return replace(
            self,
            kind="memory",
            coefficients=beta,
            covariance=covariance,
            residual_variance=s2,
            dof=float(dof),
            n_train=int(ok.sum()),
        )


def select_terms(
    Z: pd.DataFrame, y: np.ndarray, stepwise_options: Mapping[str, Any] | None
) -> tuple[tuple[int, ...], ...]:
    """Stepwise (with interactions by default) term selection on z-scored predictors *Z*."""
    from workbench.stats import stepwise

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = stepwise(Z, y, **dict(stepwise_options or {}))
    terms = tuple(tuple(int(c) for c in term) for term in fit.model_terms)
    return terms if () in terms else ((), *terms)


#: Largest condition number of XᵀWX solved through the normal equations; beyond it (rank
#: doubtful) the SVD least squares decides the rank as before. At 1e8 the normal equations
#: lose at most ~1e8 x eps ~ 1e-8 relative, far below the model's own uncertainty.
_MAX_NORMAL_CONDITION = 1e8


def _solve_well_conditioned(
    normal: np.ndarray, rhs: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """(XᵀWX)⁻¹ XᵀWy and (XᵀWX)⁻¹ by Cholesky, or None when XᵀWX is ill-conditioned.

    A few terms and thousands of rows: forming XᵀWX (n p² flops) and factoring p x p is
    much cheaper than the SVD of the n x p weighted design that ``lstsq`` and ``pinv`` did
    at every refit, and equal to round-off when the condition number is moderate.
    """
    if not np.isfinite(normal).all():
        return None
    diagonal = np.sqrt(np.diag(normal))
    if not (diagonal > 0).all():
        return None
    # equilibrate (unit diagonal) so the condition number reflects collinearity, not units
    scaled = normal / np.outer(diagonal, diagonal)
    eigenvalues = np.linalg.eigvalsh(scaled)
    if eigenvalues[0] <= eigenvalues[-1] / _MAX_NORMAL_CONDITION:
        return None
    try:
        factor = np.linalg.cholesky(scaled)
    except np.linalg.LinAlgError:
        return None
    inverse_scaled = np.linalg.inv(factor)
    inverse_scaled = inverse_scaled.T @ inverse_scaled  # (L Lᵀ)⁻¹ = L⁻ᵀ L⁻¹
    covariance = inverse_scaled / np.outer(diagonal, diagonal)
    return covariance @ rhs, covariance


def constant_model(y: np.ndarray, age: np.ndarray, memory_blocks: float) -> MemoryModel | None:
    """Exponentially weighted mean of the measurements (no usable predictor)."""
    ok = np.isfinite(y)
    if not ok.any():
        return None
    y, w = y[ok], np.exp(-age[ok] / memory_blocks)
    level = float((w * y).sum() / w.sum())
    n_eff = w.sum() ** 2 / (w @ w)
    s2 = float((w * (y - level) ** 2).sum() / w.sum() * n_eff / max(n_eff - 1, 1.0))
    return MemoryModel(
        "constant",
        (),
        (),
        ((),),
        np.empty(0),
        np.empty(0),
        np.array([level]),
        np.array([[1.0 / w.sum()]]),
        s2,
        float(max(n_eff - 1, 1.0)),
        int(ok.sum()),
    )
