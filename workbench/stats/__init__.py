"""Statistics of tracked modes against ship-log predictors.

* :func:`stepwise` - stepwise linear regression with two-way interactions (MATLAB
  ``stepwiselm`` rules), returning a :class:`StepwiseFit`; :class:`StepwiseRegressor` is
  the scikit-learn estimator around it; :func:`parse_terms` reads model formulas (never
  evaluated).
* :func:`correlation_table` - Pearson r, p-value and n of every mode quantity against every
  predictor and among predictors, per operating case (:func:`read_cases`), with
  ``significant``/``useful`` flags; :func:`modal_wide` spreads the modal table per block.
"""

from .correlation import (
    adjust_p_values,
    case_masks,
    correlation_table,
    modal_wide,
    pairwise_pearson,
    read_cases,
)
from .stepwise import StepwiseFit, StepwiseRegressor, stepwise
from .terms import parse_terms

__all__ = [
    "StepwiseFit",
    "StepwiseRegressor",
    "adjust_p_values",
    "case_masks",
    "correlation_table",
    "modal_wide",
    "pairwise_pearson",
    "parse_terms",
    "read_cases",
    "stepwise",
]
