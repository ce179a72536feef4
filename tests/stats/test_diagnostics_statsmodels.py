"""Residual diagnostics from statsmodels equal the formulas they replaced.

Jarque-Bera JB = n/6 (S² + K²/4) (Jarque & Bera 1987) and Durbin-Watson
d = Σ (e_t - e_{t-1})² / Σ e_t² (Durbin & Watson 1950) written out by hand; the library
takes both from statsmodels (Durbin-Watson with gaps keeps its run-aware form).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from workbench.stats.diagnostics import durbin_watson, residual_diagnostics


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_jarque_bera_and_durbin_watson_match_the_formulas(seed):
    rng = np.random.default_rng(seed)
    e = rng.standard_t(5, 150) + 0.3 * np.cumsum(rng.normal(size=150)) / 10
    n = e.size
    centred = e - e.mean()
    m2 = centred @ centred / n
    skew = np.mean(centred**3) / m2**1.5
    excess = np.mean(centred**4) / m2**2 - 3.0
    jb = n / 6.0 * (skew**2 + excess**2 / 4.0)
    result = residual_diagnostics(e)
    assert result.jarque_bera_statistic == pytest.approx(jb, rel=1e-12)
    assert result.jarque_bera_p_value == pytest.approx(stats.chi2.sf(jb, 2), rel=1e-10)
    d = np.sum(np.diff(e) ** 2) / np.sum(e**2)
    assert result.durbin_watson == pytest.approx(d, rel=1e-12)
    # consecutive blocks: the same statistic; a gap: only pairs inside runs, rescaled
    assert durbin_watson(e, blocks=np.arange(n) + 10) == pytest.approx(d, rel=1e-12)
    blocks = np.r_[np.arange(75), np.arange(75) + 100]
    inside = np.diff(e)[np.diff(blocks) == 1]
    expected = (inside @ inside) / (e @ e) * (n - 1) / inside.size
    assert durbin_watson(e, blocks=blocks) == pytest.approx(expected, rel=1e-12)
