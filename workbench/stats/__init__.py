"""Statistics of tracked modes against ship-log predictors.

* :func:`stepwise` - stepwise linear regression with two-way interactions (MATLAB
  ``stepwiselm`` rules), returning a :class:`StepwiseFit`; :class:`StepwiseRegressor` is
  the scikit-learn estimator around it; :func:`parse_terms` reads model formulas (never
  evaluated).
* :func:`correlation_table` - Pearson r, p-value and n of every mode quantity against every
  predictor and among predictors, per operating case (:func:`read_cases`), with
  ``significant``/``useful`` flags; :func:`modal_wide` spreads the modal table per block.
* :func:`fit_cases` - those models per operating case (a ``case,start,end`` table, a
  column, or cases derived from the predictors by :class:`CaseRule`) beside the stitched
  model; :func:`case_training_mask` is the sliding forecast's per-case hook.
* :func:`fit_modes` - one stepwise model per mode with residual diagnostics
  (:func:`residual_diagnostics`: Durbin-Watson, Shapiro-Wilk, Jarque-Bera);
  :func:`coefficient_table` (one column per term, 0 where a term is not in a model) and
  :func:`fit_statistics_table`.
"""

from .cases import (
    CaseFits,
    CaseRule,
    case_labels,
    case_training_mask,
    derive_cases,
    fit_cases,
)
from .correlation import (
    adjust_p_values,
    case_masks,
    correlation_table,
    modal_wide,
    pairwise_pearson,
    read_cases,
)
from .diagnostics import ResidualDiagnostics, durbin_watson, residual_diagnostics
from .mode_fits import ModeFit, StatsWarning, coefficient_table, fit_modes, fit_statistics_table
from .stepwise import StepwiseFit, StepwiseWarning, stepwise
from .terms import parse_terms

__all__ = [
    "CaseFits",
    "CaseRule",
    "case_labels",
    "case_training_mask",
    "derive_cases",
    "fit_cases",
    "ModeFit",
    "ResidualDiagnostics",
    "StatsWarning",
    "StepwiseFit",
    "StepwiseRegressor",
    "StepwiseWarning",
    "adjust_p_values",
    "case_masks",
    "coefficient_table",
    "correlation_table",
    "durbin_watson",
    "fit_modes",
    "fit_statistics_table",
    "modal_wide",
    "pairwise_pearson",
    "parse_terms",
    "read_cases",
    "residual_diagnostics",
    "stepwise",
]


def __getattr__(name: str):
    """:class:`StepwiseRegressor` on first use (scikit-learn is imported for it only)."""
    if name == "StepwiseRegressor":
        from .stepwise import StepwiseRegressor

        return StepwiseRegressor
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), "StepwiseRegressor"})
