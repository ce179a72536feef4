"""Stepwise models to and from JSON (never pickle): what :meth:`StepwiseFit.predict` needs.

:meth:`StepwiseFit.to_dict` describes a model for a reader (formula, coefficients, steps,
statistics). :func:`model_to_dict` adds the ``"design"`` a program needs to predict with
intervals again (terms as predictor indices, the estimates in the search's centred units,
the centres, the slope covariance, categorical levels); :func:`model_from_dict` rebuilds the
:class:`StepwiseFit` from it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .design import Encoding, design_columns
from .stepwise import StepwiseFit

__all__ = ["design_matrix", "model_from_dict", "model_to_dict"]


def _numbers(values) -> list:
    """A float array as a nested list, non-finite values as None (strict JSON)."""
    array = np.asarray(values, dtype=float)
    return np.where(np.isfinite(array), array, None).tolist()


def _array(values) -> np.ndarray:
    return np.array(values, dtype=float) if values is not None else np.array([])


def _json_value(value):
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def model_to_dict(fit: StepwiseFit) -> dict[str, Any]:
    """:meth:`StepwiseFit.to_dict` plus the ``"design"`` that :func:`model_from_dict` reads."""
    data = fit.to_dict()
    encoding = fit.encoding
    data["design"] = {
        "model_terms": [list(map(int, term)) for term in fit.model_terms],
        "coefficient_names": list(fit.coefficient_names),
        "coefficient_terms": [list(map(int, term)) for term in fit.coefficient_terms],
        "estimates": _numbers(fit.estimates),
        "standard_errors": _numbers(fit.standard_errors),
        "search_estimates": _numbers(fit.search_estimates),
        "term_means": _numbers(fit.term_means),
        "slope_covariance": _numbers(fit.slope_covariance),
        "encoding": None
        if encoding is None
        else {
            "names": list(encoding.names),
            "levels": [None if level is None else list(level) for level in encoding.levels],
            "centres": _numbers(encoding.centres),
        },
        "step_records": [[_json_value(v) for v in record] for record in fit.step_records],
        "skipped_records": [[_json_value(v) for v in record] for record in fit.skipped_records],
    }
    return data


def _float(value) -> float:
    return math.nan if value is None else float(value)


def model_from_dict(data: dict[str, Any]) -> StepwiseFit:
    """The :class:`StepwiseFit` described by :func:`model_to_dict`'s output.

    Raises
    ------
    ValueError
        When *data* has no ``"design"`` (a description written for reading only).
    """
    design = data.get("design")
    if design is None:
        raise ValueError("the model has no 'design' entry; it cannot predict")
    encoding = design.get("encoding")
    if encoding is not None:
        encoding = Encoding(
            tuple(encoding["names"]),
            tuple(None if level is None else tuple(level) for level in encoding["levels"]),
            _array(encoding["centres"]),
        )
    n_slopes = len(design["term_means"])
    covariance = _array(design["slope_covariance"]).reshape(n_slopes, n_slopes)
    search = design.get("search_estimates")
    if search is None:
        raise ValueError("the model's 'design' has no 'search_estimates'; it cannot predict")
    return StepwiseFit(
        terms=tuple(data["terms"]),
        predictor_names=tuple(data["predictors"]),
        response_name=data["response"],
        criterion=data["criterion"],
        p_enter=_float(data["p_enter"]),
        p_remove=_float(data["p_remove"]),
        n_obs=int(data["n_obs"]),
        dfe=int(data["dfe"]),
        sse=_float(data["sse"]),
        rmse=_float(data["rmse"]),
        r_squared=_float(data["r_squared"]),
        adj_r_squared=_float(data["adj_r_squared"]),
        f_stat=_float(data["f_stat"]),
        f_p_value=_float(data["f_p_value"]),
        log_likelihood=_float(data["log_likelihood"]),
        aic=_float(data["aic"]),
        bic=_float(data["bic"]),
        model_terms=tuple(tuple(term) for term in design["model_terms"]),
        search_estimates=_array(search),
        term_means=_array(design["term_means"]),
        slope_covariance=covariance,
        step_records=tuple(
            tuple(math.nan if v is None else v for v in record) for record in design["step_records"]
        ),
        skipped_records=tuple(tuple(record) for record in design["skipped_records"]),
        coefficient_names=tuple(design["coefficient_names"]),
        coefficient_terms=tuple(tuple(term) for term in design["coefficient_terms"]),
        encoding=encoding,
        missing=data.get("missing", "candidate"),
        search_warnings=tuple(data.get("warnings", ())),
    )


def design_matrix(fit: StepwiseFit, X) -> np.ndarray:
    """Design matrix of the selected model for predictor values *X* (a DataFrame with the
    model's columns), in the search's centred units: intercept column first.

    It spans the same column space as the raw-unit design, so fitted values, leverage and
    Cook's distance computed from it are those of the model as reported.
    """
    values, _ = fit._predictor_values(X)
    return design_columns(values, fit.model_terms, fit.encoding)
