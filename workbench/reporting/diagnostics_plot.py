"""Residual diagnostics figures and the per-mode regression report.

:func:`plot_residual_diagnostics` draws the four classic panels (histogram with the fitted
normal density, normal probability plot, residual against the previous residual, residual
against fitted value). :func:`write_fit_report` writes the result of
:func:`workbench.stages.fit` (one stepwise model per mode): the summary text, JSON, the
coefficient and statistics tables and one diagnostics figure per mode.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from scipy import stats as _scipy_stats

from data_contracts import atomic_path
from workbench.stats.cases import STITCHED
from workbench.stats.diagnostics import ResidualDiagnostics, residual_diagnostics
from workbench.stats.mode_fits import ModeFit

from ..results import save_figure

__all__ = ["plot_residual_diagnostics", "write_diagnostics_figures", "write_fit_report"]


def plot_residual_diagnostics(
    residuals,
    fitted,
    *,
    diagnostics: ResidualDiagnostics | None = None,
    title: str | None = None,
    unit: str = "",
):
    """Four-panel residual diagnostics figure.

    Parameters
    ----------
    residuals, fitted : array_like
        Residuals and fitted values in time (block) order. [response unit]
    diagnostics : ResidualDiagnostics, optional
        Shown in the panel titles; computed when not given.
    title : str, optional
        Figure title.
    unit : str
        Unit of the response for the axis labels, e.g. ``"Hz"``.

    Returns
    -------
    matplotlib.figure.Figure
        Panels: histogram with the normal density of the same mean and sd; normal
        probability plot with the least-squares line; e_t against e_{t-1} with the
        Durbin-Watson statistic; residual against fitted value.
    """
    e = np.asarray(residuals, dtype=float).ravel()
    f = np.asarray(fitted, dtype=float).ravel()
    if e.shape != f.shape:
        raise ValueError(f"residuals {e.shape} and fitted {f.shape} differ in shape")
    if diagnostics is None:
        diagnostics = residual_diagnostics(e)
    finite = np.isfinite(e)
    label = f"residual [{unit}]" if unit else "residual"
    fig, axes = plt.subplots(2, 2, figsize=(9, 7), layout="constrained")
    ax = axes[0, 0]
    if finite.any():
        ax.hist(
            e[finite],
            bins=max(5, min(30, int(finite.sum() // 4))),
            density=True,
            color="0.65",
            lw=0,
        )
        if np.isfinite(diagnostics.std) and diagnostics.std > 0:
            grid = np.linspace(e[finite].min(), e[finite].max(), 200)
            ax.plot(
                grid,
                _scipy_stats.norm.pdf(grid, diagnostics.mean, diagnostics.std),
                color="tab:blue",
                lw=1.2,
                label="normal",
            )
    ax.set_xlabel(label)
    ax.set_ylabel("density")
    ax.set_title(f"Histogram (n = {diagnostics.n})", fontsize=10)

    ax = axes[0, 1]
    if finite.sum() >= 3:
        (theoretical, ordered), (slope, intercept, _) = _scipy_stats.probplot(e[finite])
        ax.plot(theoretical, ordered, ".", color="0.3", ms=4)
        ax.plot(theoretical, intercept + slope * theoretical, "-", color="tab:red", lw=1)
    ax.set_xlabel("standard normal quantile")
    ax.set_ylabel(label)
    test = "Shapiro-Wilk" if np.isfinite(diagnostics.shapiro_p_value) else "Jarque-Bera"
    ax.set_title(
        f"Normal probability plot ({test} p = {diagnostics.normality_p_value:.3g})", fontsize=10
    )

    ax = axes[1, 0]
    pairs = finite[1:] & finite[:-1]
    ax.plot(e[:-1][pairs], e[1:][pairs], ".", color="0.3", ms=4)
    ax.axhline(0, color="0.7", lw=0.8)
    ax.axvline(0, color="0.7", lw=0.8)
    ax.set_xlabel(f"previous {label}")
    ax.set_ylabel(label)
    ax.set_title(
        f"Lagged residuals (Durbin-Watson {diagnostics.durbin_watson:.2f}, "
        f"r₁ = {diagnostics.lag1_autocorrelation:.2f})",
        fontsize=10,
    )

    ax = axes[1, 1]
    both = finite & np.isfinite(f)
    ax.plot(f[both], e[both], ".", color="0.3", ms=4)
    ax.axhline(0, color="tab:red", lw=0.8)
    ax.set_xlabel(f"fitted value [{unit}]" if unit else "fitted value")
    ax.set_ylabel(label)
    ax.set_title("Residual against fitted value", fontsize=10)
    if title:
        fig.suptitle(title, fontsize=11)
    return fig


def _unit(quantity: str) -> str:
    return "Hz" if quantity.endswith("_hz") else ""


def write_diagnostics_figures(
    fits: Mapping[int, ModeFit],
    out_dir: str | os.PathLike,
    *,
    prefix: str = "diagnostics_mode",
    dpi: int = 100,
) -> list[Path]:
    """One residual diagnostics PNG per mode (``<prefix><mode>.png``); returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for mode, item in sorted(fits.items()):
        fig = plot_residual_diagnostics(
            item.residuals,
            item.fitted,
            diagnostics=item.diagnostics,
            title=f"Mode {mode}: {item.fit.formula}",
            unit=_unit(item.quantity),
        )
        paths.append(save_figure(fig, out / f"{prefix}{mode}.png", dpi=dpi))
    return paths


def _write_text(path: Path, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def write_fit_report(
    result,
    out_dir: str | os.PathLike,
    *,
    figures: bool = True,
    dpi: int = 100,
) -> dict[str, Path]:
    """Write the models of a fit result: summary, JSON, tables and diagnostics figures.

    Parameters
    ----------
    result : FitResult
        Output of :func:`workbench.stages.fit`.
    out_dir : path-like
        Folder written into (created).
    figures : bool
        Also one residual diagnostics PNG per mode.
    dpi : int
        Resolution of the figures.

    Returns
    -------
    dict of str -> Path
        ``"summary"`` (fit_summary.txt), ``"json"`` (fit.json), ``"coefficients"``
        (coefficients.csv: one row per mode, one column per term, 0 where a term is not in
        the model), ``"statistics"`` (fit_statistics.csv), ``"influence"`` (influence.csv:
        leverage, Cook's distance, studentized residual per mode and block) and
        ``"diagnostics_mode<k>"``
        per mode (PNG); with cases also ``"case_models"`` and ``"case_coefficients"``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fits = result.fits
    by_case = result.by_case
    quantity = result.options.quantity
    paths: dict[str, Path] = {}
    with atomic_path(out / "coefficients.csv") as tmp:
        result.coefficients.to_csv(tmp, float_format="%.10g")
    paths["coefficients"] = out / "coefficients.csv"
    with atomic_path(out / "fit_statistics.csv") as tmp:
        result.table.to_csv(tmp, float_format="%.10g")
    paths["statistics"] = out / "fit_statistics.csv"
    if len(fits) == len(result.models):  # fitted here, not read from JSON
        with atomic_path(out / "influence.csv") as tmp:
            result.influence_table().to_csv(tmp, index=False, float_format="%.10g")
        paths["influence"] = out / "influence.csv"
    sections = []
    for mode, item in fits.items():
        sections.append(
            f"=== Mode {mode} ({quantity}) ===\n{item.fit.summary()}\n\n"
            f"Residual diagnostics\n{item.diagnostics.summary()}\n"
        )
    header = (
        f"Stepwise regression of {quantity} per mode on {', '.join(fits[next(iter(fits))].fit.predictor_names)}\n"
        f"{len(fits)} modes fitted\n\n"
    )
    if by_case is not None:
        header += by_case.summary() + "\n\n"
        for case, case_fits in by_case.fits.items():
            if case == STITCHED:
                continue
            for mode, item in case_fits.items():
                sections.append(
                    f"=== Case {case}, mode {mode} ({quantity}) ===\n{item.fit.summary()}\n\n"
                    f"Residual diagnostics\n{item.diagnostics.summary()}\n"
                )
        with atomic_path(out / "case_models.csv") as tmp:
            by_case.table().to_csv(tmp, float_format="%.10g")
        paths["case_models"] = out / "case_models.csv"
        with atomic_path(out / "case_coefficients.csv") as tmp:
            by_case.coefficients().to_csv(tmp, float_format="%.10g")
        paths["case_coefficients"] = out / "case_coefficients.csv"
    paths["summary"] = _write_text(out / "fit_summary.txt", header + "\n".join(sections))
    paths["json"] = _write_text(
        out / "fit.json", json.dumps(result.to_dict(), indent=1, allow_nan=False, default=str)
    )
    if figures:
        for mode, path in zip(fits, write_diagnostics_figures(fits, out, dpi=dpi), strict=True):
            paths[f"diagnostics_mode{mode}"] = path
    return paths
