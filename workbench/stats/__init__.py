"""Statistics of tracked modes against ship-log predictors.

* :func:`stepwise` - stepwise linear regression with two-way interactions (MATLAB
  ``stepwiselm`` rules), returning a :class:`StepwiseFit`; :class:`StepwiseRegressor` is
  the scikit-learn estimator around it.
* :func:`parse_terms` - model terms from a name, formula text or term list (never eval).
"""

from .stepwise import StepwiseFit, StepwiseRegressor, stepwise
from .terms import parse_terms

__all__ = ["StepwiseFit", "StepwiseRegressor", "parse_terms", "stepwise"]
