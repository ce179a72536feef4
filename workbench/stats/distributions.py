"""Quantiles of the sampling distributions the models use, cached.

Every window of a sliding forecast and every prediction interval of a fitted model asks
for the same few Student-t quantiles; one cached function serves them all.
"""

from __future__ import annotations

import functools

from scipy import special

__all__ = ["t_quantile"]


@functools.lru_cache(maxsize=4096)
def t_quantile(probability: float, dof: int) -> float:
    """Student-t quantile: the *t* with ``P(T <= t) = probability`` for *dof* degrees of freedom.

    The two-sided interval of level ``1 - alpha`` uses ``t_quantile(1 - alpha / 2, dof)``.
    Equals ``scipy.stats.t.ppf(probability, dof)`` (the same ``stdtrit`` kernel).
    """
    return float(special.stdtrit(dof, probability))
