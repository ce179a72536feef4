"""The scikit-learn estimator around :func:`~workbench.stats.stepwise`."""

from __future__ import annotations

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from .regression import Criterion, MissingRule, stepwise

__all__ = ["StepwiseRegressor"]


class StepwiseRegressor(RegressorMixin, BaseEstimator):
    """Scikit-learn estimator around :func:`stepwise` (usable in ``cross_val_score``).

    Parameters
    ----------
    start, upper, lower, criterion, p_enter, p_remove, max_steps, missing
        As for :func:`stepwise` (the estimator sees numeric arrays only).

    Attributes
    ----------
    result_ : StepwiseFit
        The fitted model.
    feature_names_in_ : ndarray of str
        Column names when fitted on a DataFrame.
    n_features_in_ : int
        Number of predictor columns.
    """

    def __init__(
        self,
        *,
        start="constant",
        upper="interactions",
        lower="constant",
        criterion: Criterion = "sse",
        p_enter: float | None = None,
        p_remove: float | None = None,
        max_steps: int | None = None,
        missing: MissingRule = "candidate",
    ):
        self.start = start
        self.upper = upper
        self.lower = lower
        self.missing = missing
        self.criterion = criterion
        self.p_enter = p_enter
        self.p_remove = p_remove
        self.max_steps = max_steps

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True  # rows with NaN are left out of the fit
        return tags

    def _frame(self, values: np.ndarray):
        """Predictor values with the fitted column names (term names follow them)."""
        names = getattr(self, "feature_names_in_", None)
        if names is None:
            return values
        return pd.DataFrame(values, columns=[str(name) for name in names])

    def fit(self, X, y):
        """Run the stepwise search on (*X*, *y*); returns ``self``."""
        response = y.name if isinstance(y, pd.Series) and y.name is not None else None
        values, target = validate_data(
            self,
            X,
            y,
            dtype=float,
            ensure_all_finite="allow-nan",
            ensure_min_samples=2,
            y_numeric=True,
        )
        self.result_ = stepwise(
            self._frame(values),
            pd.Series(target, name=response) if response is not None else target,
            start=self.start,
            upper=self.upper,
            lower=self.lower,
            criterion=self.criterion,
            p_enter=self.p_enter,
            p_remove=self.p_remove,
            max_steps=self.max_steps,
            missing=self.missing,
        )
        return self

    @property
    def terms_(self) -> tuple[str, ...]:
        """Non-constant terms of the fitted model."""
        check_is_fitted(self, "result_")
        return self.result_.terms

    @property
    def coef_(self) -> pd.Series:
        """Estimates indexed by term, intercept included."""
        check_is_fitted(self, "result_")
        return self.result_.coefficients["estimate"]

    def predict(self, X) -> np.ndarray:
        """Predicted means for the rows of *X* (NaN where a used predictor is NaN)."""
        check_is_fitted(self, "result_")
        values = validate_data(self, X, reset=False, dtype=float, ensure_all_finite="allow-nan")
        return np.asarray(self.result_.predict(self._frame(values)), dtype=float)
