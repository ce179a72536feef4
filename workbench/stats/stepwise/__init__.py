"""Stepwise linear regression with two-way interactions, following MATLAB ``stepwiselm``.

:func:`stepwise` searches between a start model and an upper model by partial F-tests
(criterion ``"sse"``) or by the change in AIC/BIC, with MATLAB's rules: add first, remove
only when nothing enters, hierarchy in both directions, no immediate undo, intercept kept.
Every search ends: one that returns to a model it visited (rows with NaN make the sample
change with the model) stops at the best model of the cycle with a :class:`StepwiseWarning`,
and a default step limit is the second guard. It returns a :class:`StepwiseFit`
(coefficients, step history, goodness of fit, ``predict`` with confidence or prediction
intervals). :class:`StepwiseRegressor` wraps it as a scikit-learn estimator.

The search works on the cross-product matrix of the centred and scaled candidate columns
and the response, built once per fit, with Goodnight's sweep operator: after sweeping the
model's terms the matrix holds every candidate's residual cross-products (so each candidate's
residual sum of squares costs a division) and, for the model's terms, the coefficients and
(X'X)⁻¹. A step costs O(m²) for m candidate terms, independent of the number of rows; a
20-row search over 5 predictors and their 10 interactions takes a few hundred microseconds,
which matters because the sliding forecast refits a model for every mode and window.

The package, one module per responsibility: :mod:`.regression` (:func:`stepwise`: options,
model specifications and data checked, the search run), :mod:`.search` (the search with
MATLAB's step rules), :mod:`.sweep` (the sweep operator and the cross-product matrix of
one row set), :mod:`.layout` (columns and hierarchy of the upper model's terms),
:mod:`.result` (:class:`StepwiseFit`: coefficients, steps, prediction intervals, summary)
and :mod:`.estimator` (:class:`StepwiseRegressor`).
"""

from .regression import stepwise
from .result import StepwiseFit, StepwiseWarning

__all__ = ["StepwiseFit", "StepwiseRegressor", "StepwiseWarning", "stepwise"]


def __getattr__(name: str):
    """:class:`StepwiseRegressor` on first use: scikit-learn is imported for the estimator
    only, so a command that fits none does not pay for its import (0.13 s of CPU)."""
    if name == "StepwiseRegressor":
        from .estimator import StepwiseRegressor

        return StepwiseRegressor
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), "StepwiseRegressor"})
