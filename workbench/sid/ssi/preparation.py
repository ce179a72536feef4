"""Defaults of both SSI variants, the checks of their data and options, and the threading
policy (single-threaded BLAS, a fixed thread budget; see :mod:`workbench.sid.ssi`)."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Literal

import numpy as np

from ..threads import sid_threads

Weighting = Literal["pc", "upc", "cva"]
_WEIGHTINGS = ("pc", "upc", "cva")
DEFAULT_ORDERS = range(2, 81, 2)
DEFAULT_BLOCK_ROWS = 20
#: Singular values computed beyond the largest model order (kept on the result).
_EXTRA_SINGULAR_VALUES = 10


def _prepare(
    acceleration,
    sampling_rate_hz: float,
    block_rows: int,
    orders: Sequence[int],
    reference_channels: Sequence[int] | None,
) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """Checked, mean-free data, reference indices and orders."""
    data = np.asarray(acceleration)
    if data.ndim != 2:
        raise ValueError(
            f"acceleration must be 2-D (n_samples, n_channels), got shape {data.shape}"
        )
    if not np.issubdtype(data.dtype, np.number) or np.iscomplexobj(data):
        raise TypeError(f"acceleration must hold real numbers, got dtype {data.dtype}")
    data = np.asarray(data, dtype=float)  # no copy for float64: the centring below copies
    n_samples, n_channels = data.shape
    mean = data.mean(axis=0)  # NaN or inf in a channel make its mean non-finite
    bad = np.zeros(0, dtype=int)
    if not np.isfinite(mean).all():
        bad = np.flatnonzero(~np.isfinite(data).all(axis=0))
    if bad.size:
        raise ValueError(
            f"acceleration channel(s) {bad.tolist()} (column index) contain NaN or inf; "
            "drop faulty channels before identification"
        )
    if not (np.isfinite(sampling_rate_hz) and sampling_rate_hz > 0):
        raise ValueError(f"sampling_rate_hz={sampling_rate_hz} must be positive")
    if int(block_rows) != block_rows or block_rows < 2:
        raise ValueError(f"block_rows={block_rows} must be an integer >= 2")
    block_rows = int(block_rows)

    if reference_channels is None:
        references = np.arange(n_channels)
    else:
        references = np.asarray(reference_channels)
        if references.ndim != 1 or references.size == 0 or references.dtype.kind not in "iu":
            raise ValueError(
                f"reference_channels={reference_channels!r} must be a non-empty sequence of "
                "column indices"
            )
        if np.unique(references).size != references.size:
            raise ValueError(f"reference_channels={references.tolist()} has duplicates")
        if references.min() < 0 or references.max() >= n_channels:
            raise ValueError(
                f"reference_channels={references.tolist()} must lie in 0..{n_channels - 1}"
            )

    order_list = sorted({int(n) for n in orders})
    if not order_list or order_list[0] < 1:
        raise ValueError(f"orders={list(orders)!r} must be positive integers")
    n_refs = references.size
    capacity = min(n_refs * block_rows, n_channels * (block_rows - 1))
    if order_list[-1] > capacity:
        # r·i >= n and l·(i - 1) >= n
        needed = max(-(-order_list[-1] // n_refs), -(-order_list[-1] // n_channels) + 1)
        raise ValueError(
            f"orders up to {order_list[-1]} need block_rows >= {needed} with "
            f"{n_refs} reference and {n_channels} channels, got block_rows={block_rows}"
        )
    _check_length(n_samples, n_channels, n_refs, block_rows)
    data = data - mean
    return data, references, tuple(order_list)


def _check_length(n_samples: int, n_channels: int, n_refs: int, block_rows: int) -> None:
    """ValueError if *n_samples* are too few for *block_rows* block rows."""
    min_samples = (n_channels + n_refs + 2) * block_rows
    if n_samples < min_samples:
        raise ValueError(
            f"block_rows={block_rows} needs at least {min_samples} samples with "
            f"{n_channels} channels, got {n_samples}"
        )


def _order_limits(n_max: int, singular_values: np.ndarray) -> None:
    if singular_values.size < n_max or singular_values[n_max - 1] <= 0:
        raise ValueError(
            f"the data support at most {int(np.sum(singular_values > 0))} states, "
            f"orders go up to {n_max}"
        )


def _single_threaded(function):
    """Run *function* with single-threaded BLAS and a fixed thread budget (module docstring)."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with sid_threads():
            return function(*args, **kwargs)

    return wrapper
