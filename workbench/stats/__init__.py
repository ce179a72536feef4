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

from typing import TYPE_CHECKING

from .._lazy import attach

# eager: the command line's defaults import it anyway, and the function's name is also the
# subpackage's (a lazy name would be shadowed by the subpackage once imported)
from .stepwise import StepwiseFit, StepwiseWarning, stepwise

#: Public names and the module defining each, imported on first use (PEP 562): the command
#: line's defaults read the stepwise thresholds alone, not every statistic.
_EXPORTS = {
    "CaseFits": ".cases",
    "CaseRule": ".cases",
    "case_labels": ".cases",
    "case_training_mask": ".cases",
    "derive_cases": ".cases",
    "fit_cases": ".cases",
    "adjust_p_values": ".correlation",
    "case_masks": ".correlation",
    "correlation_table": ".correlation",
    "modal_wide": ".correlation",
    "pairwise_pearson": ".correlation",
    "read_cases": ".correlation",
    "ResidualDiagnostics": ".diagnostics",
    "durbin_watson": ".diagnostics",
    "residual_diagnostics": ".diagnostics",
    "ModeFit": ".mode_fits",
    "StatsWarning": ".mode_fits",
    "coefficient_table": ".mode_fits",
    "fit_modes": ".mode_fits",
    "fit_statistics_table": ".mode_fits",
    "StepwiseRegressor": ".stepwise",
    "parse_terms": ".terms",
}

if TYPE_CHECKING:
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
    from .stepwise import StepwiseRegressor
    from .terms import parse_terms


__getattr__, __dir__ = attach(__name__, _EXPORTS, globals())


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
