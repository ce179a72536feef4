"""Design columns, display names and hierarchy of the terms of an upper model, cached per
model (the sliding forecast searches the same upper model for every mode and window)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..design import Encoding, column_names, term_width
from ..terms import Term, parents, term_name


@dataclass(frozen=True)
class _Layout:
    """Columns, names and hierarchy of an upper model's terms (cached per model)."""

    terms: tuple[Term, ...]
    widths: tuple[int, ...]
    columns: tuple[np.ndarray, ...]  # design columns of each term
    display: tuple[str, ...]
    column_names: tuple[str, ...]
    parent_count: np.ndarray  # parents each term needs (hierarchy)
    parents: np.ndarray  # parents[k, p]: term p is a parent of term k
    missing_parent: np.ndarray  # a parent is not in the upper model: never eligible
    is_intercept: np.ndarray
    predictors: tuple[tuple[int, ...], ...]  # predictor columns of each term
    used_columns: list[int]
    single: bool  # every term has one design column
    first_column: np.ndarray  # first design column of each term
    parent_a: np.ndarray  # the parents of a term; n_terms: none, or absent from upper
    parent_b: np.ndarray
    has_parents: np.ndarray


@functools.lru_cache(maxsize=256)
def _layout(upper_terms: tuple[Term, ...], names: tuple[str, ...], levels: tuple) -> _Layout:
    encoding = Encoding(names, levels, np.zeros(len(names)))
    n_terms = len(upper_terms)
    position = {term: k for k, term in enumerate(upper_terms)}
    widths = tuple(term_width(t, encoding) for t in upper_terms)
    starts = np.concatenate([[0], np.cumsum(widths)])
    columns = tuple(np.arange(starts[k], starts[k + 1]) for k in range(n_terms))
    parent_matrix = np.zeros((n_terms, n_terms), dtype=bool)
    missing_parent = np.zeros(n_terms, dtype=bool)
    parent_a = np.full(n_terms, n_terms)
    parent_b = np.full(n_terms, n_terms)
    for k, term in enumerate(upper_terms):
        term_parents = parents(term)
        for parent in term_parents:
            if parent in position:
                parent_matrix[k, position[parent]] = True
            else:
                missing_parent[k] = True
        if term_parents:
            parent_a[k] = position.get(term_parents[0], n_terms)
            parent_b[k] = position.get(term_parents[-1], n_terms)
    out = _Layout(
        terms=upper_terms,
        widths=widths,
        columns=columns,
        display=tuple(term_name(t, names) for t in upper_terms),
        column_names=tuple(column_names(upper_terms, encoding)),
        parent_count=parent_matrix.sum(axis=1),
        parents=parent_matrix,
        missing_parent=missing_parent,
        is_intercept=np.array([not t for t in upper_terms]),
        predictors=tuple(tuple(sorted(set(t))) for t in upper_terms),
        used_columns=sorted({i for t in upper_terms for i in t}),
        single=all(w == 1 for w in widths),
        first_column=starts[:-1].astype(int),
        parent_a=parent_a,
        parent_b=parent_b,
        has_parents=np.array([len(parents(t)) > 0 for t in upper_terms], dtype=bool),
    )
    for array in (
        out.parent_count,
        out.parents,
        out.missing_parent,
        out.is_intercept,
        out.first_column,
    ):
        array.setflags(write=False)
    return out
