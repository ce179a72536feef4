"""Fit stage: one stepwise regression per mode, its residual diagnostics, per case.

The results read like statsmodels' regression results: :class:`FitResult` holds every
mode's model (``result[mode]`` is a :class:`ModeResults` with ``params``, ``bse``,
``pvalues``, ``conf_int()``, ``rsquared``, ``get_prediction(X).summary_frame()``,
``get_influence()``), and tables across modes (``result.params``, ``result.rsquared``).
Models are written as JSON (``fit.json``) and read back with :func:`read_fit`; never
pickled.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
from scipy import stats as _scipy_stats

from data_contracts import MODAL, PREDICTORS

from ..predictors.directions import with_direction_components
from ..results import StageResult, Summary, read_any_table, shown_once
from ..sid.presence import persistent_modes
from ..stats.cases import STITCHED, CaseFits, fit_cases
from ..stats.fit_io import design_matrix, model_from_dict, model_to_dict
from ..stats.mode_fits import ModeFit, coefficient_table, fit_modes, fit_statistics_table
from ..stats.stepwise import StepwiseFit

__all__ = ["FitOptions", "FitResult", "ModeResults", "PredictionResults", "fit", "read_fit"]


@dataclass(frozen=True)
class FitOptions:
    """Options of :func:`fit` (the stepwise search follows MATLAB ``stepwiselm``).

    Parameters
    ----------
    quantity : str
        Modelled column of the modal table: ``frequency_hz`` [Hz] or ``damping_ratio`` [-].
    upper : str
        Largest model: ``constant``, ``linear``, ``interactions`` or a formula.
    p_enter, p_remove : float, optional
        F-test p-values to enter and to remove a term (default 0.05 and 0.10).
    criterion : str
        Search criterion (``sse``: F-tests; ``aic``, ``bic``, ``rsquared``, ``adjrsquared``).
    predictors_used : tuple of str, optional
        Candidate predictors; default every numeric predictor column.
    modes : tuple of int, optional
        Modes to fit; default every persistent mode.
    min_presence : float
        Only modes measured in at least this share of the blocks are fitted.
    errors : {"warn", "raise"}
        A mode without enough data: left out with a warning, or an error.
    min_case_blocks : int
        Blocks a case needs for its own models (with cases).
    """

    quantity: str = "frequency_hz"
    upper: str = "interactions"
    p_enter: float | None = None
    p_remove: float | None = None
    criterion: str = "sse"
    predictors_used: tuple[str, ...] | None = None
    modes: tuple[int, ...] | None = None
    min_presence: float = 0.5
    errors: Literal["warn", "raise"] = "warn"
    min_case_blocks: int = 10

    def __post_init__(self) -> None:
        if not 0.0 <= self.min_presence <= 1.0:
            raise ValueError(f"min_presence={self.min_presence} must be in [0, 1]")
        enter = 0.05 if self.p_enter is None else self.p_enter
        remove = 0.10 if self.p_remove is None else self.p_remove
        if self.criterion == "sse" and not 0.0 < enter < remove < 1.0:
            raise ValueError(
                f"p_enter={enter} and p_remove={remove}: need 0 < p_enter < p_remove < 1"
            )
        if self.errors not in ("warn", "raise"):
            raise ValueError(f"errors={self.errors!r} must be 'warn' or 'raise'")

    def stepwise_options(self) -> dict[str, Any]:
        """The options of :func:`~workbench.stats.stepwise` that differ from its defaults."""
        options: dict[str, Any] = {}
        if self.p_enter is not None:
            options["p_enter"] = self.p_enter
        if self.p_remove is not None:
            options["p_remove"] = self.p_remove
        if self.upper != "interactions":
            options["upper"] = self.upper
        if self.criterion != "sse":
            options["criterion"] = self.criterion
        return options


def _model_inputs(exog):
    """*exog* with a direction column as its cosine (a DataFrame), else as given."""
    return with_direction_components(exog) if isinstance(exog, pd.DataFrame) else exog


class PredictionResults:
    """Predictions of one model with standard errors and intervals (statsmodels-like)."""

    def __init__(self, model: StepwiseFit, exog: pd.DataFrame):
        self._model = model
        self._exog = exog

    @property
    def predicted_mean(self) -> np.ndarray | pd.Series:
        """Predicted means: a Series on the index of a DataFrame given, else an array."""
        return _as_given(self._model.predict(self._exog), self._exog, "predicted_mean")

    @property
    def se_mean(self) -> np.ndarray:
        """Standard error of the predicted mean, s √h."""
        return self._model.predict(self._exog, interval="confidence")["mean_se"].to_numpy()

    def summary_frame(self, alpha: float = 0.05) -> pd.DataFrame:
        """mean, mean_se, mean_ci_lower/upper (the mean response) and obs_ci_lower/upper
        (a new observation), with confidence ``1 - alpha``."""
        mean = self._model.predict(self._exog, interval="confidence", alpha=alpha)
        obs = self._model.predict(self._exog, interval="prediction", alpha=alpha)
        return pd.DataFrame(
            {
                "mean": mean["mean"],
                "mean_se": mean["mean_se"],
                "mean_ci_lower": mean["lower"],
                "mean_ci_upper": mean["upper"],
                "obs_ci_lower": obs["lower"],
                "obs_ci_upper": obs["upper"],
            }
        )


@dataclass
class ModeResults:
    """One mode's fitted model, read like statsmodels' ``RegressionResults``.

    Attributes
    ----------
    mode : int
    model : StepwiseFit
        The selected model (:func:`~workbench.stats.stepwise`).
    fit : ModeFit, optional
        The model with its data and residual diagnostics (None when read from JSON).
    exog : DataFrame, optional
        Predictor values of the blocks fitted (index block), for influence measures.
    """

    mode: int
    model: StepwiseFit
    fit: ModeFit | None = None
    exog: pd.DataFrame | None = None
    #: The fit.json the model was read from (None: fitted in this session).
    source: Path | None = None

    # coefficients -------------------------------------------------------------------
    @property
    def params(self) -> pd.Series:
        """Coefficient estimates in raw units, indexed by term."""
        return self.model.coefficients["estimate"].rename(None)

    @property
    def bse(self) -> pd.Series:
        """Standard errors of the coefficients."""
        return self.model.coefficients["se"].rename(None)

    @property
    def tvalues(self) -> pd.Series:
        return self.model.coefficients["t_stat"].rename(None)

    @property
    def pvalues(self) -> pd.Series:
        """Two-sided p-values of the coefficients (Student's t, ``df_resid``)."""
        return self.model.coefficients["p_value"].rename(None)

    def conf_int(self, alpha: float = 0.05) -> pd.DataFrame:
        """Confidence intervals of the coefficients: columns 0 (lower) and 1 (upper)."""
        if not 0.0 < alpha < 1.0:
            raise ValueError(f"alpha={alpha} must be in (0, 1)")
        half = _scipy_stats.t.ppf(1.0 - alpha / 2.0, self.df_resid) * self.bse
        return pd.DataFrame({0: self.params - half, 1: self.params + half})

    # goodness of fit ----------------------------------------------------------------
    @property
    def nobs(self) -> int:
        return int(self.model.n_obs)

    @property
    def df_resid(self) -> int:
        return int(self.model.dfe)

    @property
    def df_model(self) -> int:
        """Coefficients besides the intercept."""
        return len(self.params) - 1

    @property
    def ssr(self) -> float:
        """Residual sum of squares."""
        return float(self.model.sse)

    @property
    def mse_resid(self) -> float:
        return float(self.model.sse / self.model.dfe) if self.model.dfe > 0 else np.nan

    @property
    def rsquared(self) -> float:
        return float(self.model.r_squared)

    @property
    def rsquared_adj(self) -> float:
        return float(self.model.adj_r_squared)

    @property
    def fvalue(self) -> float:
        return float(self.model.f_stat)

    @property
    def f_pvalue(self) -> float:
        return float(self.model.f_p_value)

    @property
    def llf(self) -> float:
        return float(self.model.log_likelihood)

    @property
    def aic(self) -> float:
        return float(self.model.aic)

    @property
    def bic(self) -> float:
        return float(self.model.bic)

    @property
    def formula(self) -> str:
        return self.model.formula

    # data ---------------------------------------------------------------------------
    def _needs_data(self, what: str) -> ModeFit:
        if self.fit is None:
            raise FitDataMissing(
                f"{what} of mode {self.mode} needs the fitted blocks' data (observed, fitted, "
                f"residuals), which {self.source or 'fit.json'} does not keep (it keeps the "
                "model: params, bse, pvalues, predict); fit the tables again with wb.fit"
            )
        return self.fit

    @property
    def resid(self) -> pd.Series:
        """Residuals of the fitted blocks (index block)."""
        item = self._needs_data("resid")
        return pd.Series(item.residuals, index=pd.Index(item.blocks, name="block"))

    @property
    def fittedvalues(self) -> pd.Series:
        item = self._needs_data("fittedvalues")
        return pd.Series(item.fitted, index=pd.Index(item.blocks, name="block"))

    @property
    def diagnostics(self):
        """Residual diagnostics (Durbin-Watson, Jarque-Bera, Shapiro-Wilk)."""
        return self._needs_data("diagnostics").diagnostics

    # prediction ---------------------------------------------------------------------
    def predict(self, exog: pd.DataFrame) -> pd.Series | np.ndarray:
        """Predicted means for new predictor values (columns named as in the fit; a
        direction in degrees, ``wind_dir_rel_deg``, is taken as the cosine the
        fit uses): a Series on *exog*'s index when *exog* is a DataFrame, else an array."""
        exog = _model_inputs(exog)
        return _as_given(self.model.predict(exog), exog, self.model.response_name)

    def get_prediction(self, exog: pd.DataFrame) -> PredictionResults:
        """Predictions with standard errors and intervals (``.summary_frame(alpha)``)."""
        return PredictionResults(self.model, _model_inputs(exog))

    def get_influence(self):
        """Influence measures of the fitted blocks: statsmodels ``OLSInfluence`` of the
        selected model (``cooks_distance``, ``hat_matrix_diag`` (leverage),
        ``resid_studentized_external``, ``summary_frame()``).

        The model's design in the search's centred units spans the same column space as
        the raw one, so fitted values, leverage and Cook's distance are those of the
        model as reported.
        """
        from statsmodels.regression.linear_model import OLS

        item = self._needs_data("get_influence")
        if self.exog is None:
            raise ValueError("get_influence needs the predictor values of the fitted blocks")
        design = design_matrix(self.model, self.exog.loc[item.blocks])
        ols = OLS(np.asarray(item.observed, dtype=float), design).fit()
        return ols.get_influence()

    def summary(self) -> Summary:
        """The model's coefficients and fit (and residual diagnostics when fitted here)."""
        lines = [f"Mode {self.mode}", *str(self.model.summary()).splitlines()]
        if self.fit is not None:
            lines += ["", "Residual diagnostics", *self.fit.diagnostics.summary().splitlines()]
        return Summary(f"mode {self.mode}: {self.formula}", lines)

    def __repr__(self) -> str:
        return f"<ModeResults mode {self.mode}: {self.formula}, R² {self.rsquared:.3f}>"


@dataclass
class FitResult(StageResult):
    """Per-mode stepwise models (stitched over the cases) and, with cases, per case.

    Attributes
    ----------
    models : dict of int -> ModeResults
        The model of each mode (``result[mode]``).
    by_case : CaseFits, optional
        Models per operating case beside the stitched ones.
    options : FitOptions
    """

    models: dict[int, ModeResults]
    options: FitOptions
    by_case: CaseFits | None = None
    lines: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    title = "stepwise models per mode"

    def __getitem__(self, mode: int) -> ModeResults:
        try:
            return self.models[int(mode)]
        except KeyError:
            raise KeyError(f"no model of mode {mode}; modes: {sorted(self.models)}") from None

    def __iter__(self) -> Iterator[int]:
        """The modes, ascending (``for mode in fit: fit[mode]``)."""
        return iter(self.modes)

    def __len__(self) -> int:
        """Number of modes with a model."""
        return len(self.models)

    def __contains__(self, mode: object) -> bool:
        try:
            return int(mode) in self.models  # type: ignore[call-overload]
        except (TypeError, ValueError):
            return False

    def items(self) -> Iterator[tuple[int, ModeResults]]:
        """(mode, model) pairs, ascending by mode."""
        return ((mode, self.models[mode]) for mode in self.modes)

    @property
    def modes(self) -> list[int]:
        return sorted(self.models)

    @property
    def fits(self) -> dict[int, ModeFit]:
        """The :class:`~workbench.stats.mode_fits.ModeFit` of each mode (fitted here, not read)."""
        return {m: r.fit for m, r in self.models.items() if r.fit is not None}

    @property
    def table(self) -> pd.DataFrame:
        """Goodness of fit and residual diagnostics, one row per mode (index mode)."""
        fits = self.fits
        if len(fits) == len(self.models):
            return fit_statistics_table(fits)
        return fit_statistics_table({m: r.model for m, r in self.models.items()})

    def _across(self, column: str) -> pd.DataFrame:
        frames = {m: r.model.coefficients[column] for m, r in sorted(self.models.items())}
        table = pd.DataFrame(frames).T
        order = coefficient_table({m: r.model for m, r in self.models.items()}).columns
        table = table.reindex(columns=list(order))
        table.index.name = "mode"
        return table

    @property
    def params(self) -> pd.DataFrame:
        """Estimates, one row per mode, one column per term (NaN: term not in the model)."""
        return self._across("estimate")

    @property
    def bse(self) -> pd.DataFrame:
        return self._across("se")

    @property
    def pvalues(self) -> pd.DataFrame:
        return self._across("p_value")

    @property
    def rsquared(self) -> pd.Series:
        return pd.Series({m: r.rsquared for m, r in sorted(self.models.items())}, name="rsquared")

    @property
    def coefficients(self) -> pd.DataFrame:
        """Estimates side by side, 0 where a term is not in a model (coefficients.csv)."""
        return coefficient_table({m: r.model for m, r in self.models.items()})

    def influence_table(self) -> pd.DataFrame:
        """Influence of each fitted block on its mode's model: leverage (hat value),
        Cook's distance and the externally studentized residual (statsmodels
        ``OLSInfluence``), one row per mode and block.

        A Cook's distance above about 4/n marks a block that moves the model (a
        mis-tracked pole, a spike in the ship log).
        """
        frames = []
        for mode, item in sorted(self.models.items()):
            if item.fit is None or item.exog is None:
                continue
            influence = item.get_influence()
            frames.append(
                pd.DataFrame(
                    {
                        "mode": mode,
                        "block": np.asarray(item.fit.blocks, dtype="int64"),
                        "leverage": influence.hat_matrix_diag,
                        "cooks_distance": influence.cooks_distance[0],
                        "studentized_residual": influence.resid_studentized_external,
                    }
                )
            )
        if not frames:
            raise ValueError("influence needs the fitted data; models read from JSON have none")
        return pd.concat(frames, ignore_index=True)

    def summary(self) -> Summary:
        """The lines of the stage and the models side by side (formula, blocks, R², RMSE)."""
        summary = super().summary()
        summary.tables.append(("", self.table[["formula", "n_obs", "r_squared", "rmse"]]))
        return summary

    def plot(self, mode: int | None = None):
        """Residual diagnostics figure of *mode* (default the first mode)."""
        from ..reporting.diagnostics_plot import plot_residual_diagnostics

        item = self[self.modes[0] if mode is None else mode]
        data = item._needs_data("plot")
        return shown_once(
            plot_residual_diagnostics(
                data.residuals,
                data.fitted,
                diagnostics=data.diagnostics,
                title=f"Mode {item.mode}: {item.formula}",
                unit="Hz" if data.quantity.endswith("_hz") else "",
            )
        )

    def to_dict(self) -> dict[str, Any]:
        """The fit.json payload: options, each mode's model and diagnostics (and per case)."""
        payload: dict[str, Any] = {
            "quantity": self.options.quantity,
            "options": self.options.stepwise_options(),
            "modes": [_mode_dict(r) for _, r in sorted(self.models.items())],
        }
        if self.by_case is not None:
            payload["cases"] = {
                case: [item.to_dict() for item in case_fits.values()]
                for case, case_fits in self.by_case.fits.items()
                if case != STITCHED
            }
            payload["case_left_out"] = self.by_case.left_out
        return payload

    def save(
        self, out_dir: str | os.PathLike, *, figures: bool = True, dpi: int = 100
    ) -> dict[str, Path]:
        """coefficients.csv, fit_statistics.csv, influence.csv, fit_summary.txt, fit.json
        (read back by :func:`read_fit`), with cases case_models.csv and
        case_coefficients.csv, and with *figures* one residual diagnostics PNG per mode."""
        from ..reporting.diagnostics_plot import write_fit_report

        return write_fit_report(self, out_dir, figures=figures, dpi=dpi)


def _mode_dict(result: ModeResults) -> dict[str, Any]:
    if result.fit is not None:
        data = result.fit.to_dict()
    else:
        data = {"mode": int(result.mode), "quantity": None}
    data["model"] = model_to_dict(result.model)
    return data


def fit(
    modal: pd.DataFrame | str | os.PathLike,
    predictors: pd.DataFrame | str | os.PathLike,
    *,
    cases=None,
    options: FitOptions | None = None,
) -> FitResult:
    """Stepwise linear model with interactions of each mode on the block predictors.

    Parameters
    ----------
    modal : DataFrame
        Tracked modal table (MODAL contract).
    predictors : DataFrame
        Block predictors (PREDICTORS contract) on the modal table's blocks.
    cases : None, "derive", CaseRule, column name, path or DataFrame
        Operating cases (:func:`workbench.stats.cases.case_labels`): models per case
        beside the stitched model of all the cases' blocks.
    options : FitOptions, optional

    Raises
    ------
    ValueError
        When no mode could be fitted.
    """
    options = options or FitOptions()
    modal = read_any_table(modal, MODAL, name="modal")
    predictors = read_any_table(predictors, PREDICTORS, name="predictors")
    modal, lines = persistent_modes(modal, options.min_presence)
    common = dict(
        quantity=options.quantity,
        predictors_used=options.predictors_used,
        modes=options.modes,
        errors=options.errors,
        **options.stepwise_options(),
    )
    by_case = None
    if isinstance(cases, str | os.PathLike) and not (isinstance(cases, str) and cases == "derive"):
        from .correlation import _cases

        cases = _cases(cases)  # a file: read and checked as correlate reads it
    if cases is not None:
        by_case = fit_cases(modal, predictors, cases, min_blocks=options.min_case_blocks, **common)
        fits = by_case.fits[STITCHED]
    else:
        fits = fit_modes(modal, predictors, **common)
    if not fits:
        raise ValueError(f"no mode could be fitted ({options.quantity}); see the warnings")
    exog = _model_inputs(predictors).set_index("block")  # the inputs as the fits saw them
    models = {int(m): ModeResults(int(m), item.fit, item, exog) for m, item in fits.items()}
    result = FitResult(models=models, options=options, by_case=by_case, lines=list(lines))
    names = ", ".join(next(iter(fits.values())).fit.predictor_names)
    result.lines.append(f"{len(fits)} modes fitted ({options.quantity} on {names})")
    return result


def read_fit(path: str | os.PathLike) -> FitResult:
    """The models of a ``fit.json`` written by :meth:`FitResult.save`, ready to predict.

    The fitted data (residuals, diagnostics) are not part of the JSON: ``resid``,
    ``fittedvalues``, ``diagnostics``, ``get_influence()`` and ``plot()`` raise
    :class:`FitDataMissing` (a ValueError naming what is missing) and need the original fit.
    """
    path = Path(path)
    if path.is_dir():
        path = path / "fit.json"
    data = json.loads(path.read_text(encoding="utf-8"))
    options = _options_from(data)
    models = {}
    for item in data["modes"]:
        try:
            model = model_from_dict(item["model"])
        except (KeyError, ValueError) as error:
            raise ValueError(f"{path}: mode {item.get('mode')}: {error}") from None
        models[int(item["mode"])] = ModeResults(int(item["mode"]), model, source=path)
    return FitResult(
        models=models, options=options, lines=[f"{len(models)} models read from {path}"]
    )


class FitDataMissing(ValueError):
    """A model read back from fit.json asked for the fitted blocks' data it does not keep."""


def _as_given(values, exog, name: str | None) -> pd.Series | np.ndarray:
    """*values* as a Series on *exog*'s index when *exog* is a DataFrame, else an array."""
    values = np.asarray(values, dtype=float)
    if isinstance(exog, pd.DataFrame):
        return pd.Series(values, index=exog.index, name=name)
    return values


def _options_from(data: Mapping[str, Any]) -> FitOptions:
    stepwise = dict(data.get("options") or {})
    known = {k: stepwise[k] for k in ("p_enter", "p_remove", "upper", "criterion") if k in stepwise}
    return FitOptions(quantity=data.get("quantity", "frequency_hz"), **known)
