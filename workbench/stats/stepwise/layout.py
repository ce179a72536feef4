"""Design columns, display names and hierarchy of the terms of an upper model, cached per
model (the sliding forecast searches the same upper model for every mode and window)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..design import Encoding, column_names, term_width
from ..terms import Term, parents, term_name


@dataclass(frozen=True, eq=False)
class _Layout:
    """Columns, names and hierarchy of an upper model's terms (cached per model; compared
    and hashed by identity, so that the per-model caches below can key on it)."""

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


@functools.lru_cache(maxsize=4096)
def _eligible_terms(layout: _Layout, model: tuple[int, ...], just_removed: int) -> np.ndarray:
    """Terms that may enter *model*: not in it, both parents in it (hierarchy), not the
    term removed in the step before (-1: none). Cached: windows of a sliding fit visit the
    same few models."""
    n_terms = len(layout.terms)
    in_extended = np.zeros(n_terms + 1, dtype=bool)  # slot n_terms: no such parent
    in_extended[list(model)] = True
    in_model = in_extended[:n_terms]
    eligible = ~in_model & (
        ~layout.has_parents | (in_extended[layout.parent_a] & in_extended[layout.parent_b])
    )
    if just_removed >= 0:
        eligible[just_removed] = False
    out = np.flatnonzero(eligible)
    out.setflags(write=False)
    return out


@functools.lru_cache(maxsize=4096)
def _removable_terms(
    layout: _Layout, model: tuple[int, ...], protected: frozenset[int], just_added: int
) -> tuple[np.ndarray, np.ndarray]:
    """(model terms as an array, which of them may leave): not *protected* (the lower
    model), not the intercept, no child in the model (hierarchy), not the term added in the
    step before (-1: none). Cached like :func:`_eligible_terms`."""
    terms = np.array(model, dtype=int)
    in_model = np.zeros(len(layout.terms), dtype=bool)
    in_model[terms] = True
    has_child = (layout.parents[:, terms] & in_model[:, None]).any(axis=0)
    removable = ~layout.is_intercept[terms] & ~has_child
    if protected:
        removable &= ~np.isin(terms, list(protected))
    if just_added >= 0:
        removable &= terms != just_added
    terms.setflags(write=False)
    removable.setflags(write=False)
    return terms, removable


@dataclass(frozen=True)
class _ModelLabels:
    """Columns and names of a model's terms (cached per layout and model)."""

    columns: tuple[int, ...]  # design columns, the intercept's first
    slope_columns: list[int]  # columns[1:]
    slope_index: np.ndarray  # columns[1:] as an index array
    slope_rows: np.ndarray  # columns[1:] as a column of indices (rows of a sub-matrix)
    display: tuple[str, ...]  # non-constant terms
    terms: tuple[Term, ...]
    column_names: tuple[str, ...]
    column_terms: tuple[Term, ...]  # the term of each design column


@functools.lru_cache(maxsize=4096)
def _model_labels(layout: _Layout, model: tuple[int, ...]) -> _ModelLabels:
    columns = tuple(int(c) for t in model for c in layout.columns[t])
    slope_index = np.array(columns[1:], dtype=int)
    slope_index.setflags(write=False)
    return _ModelLabels(
        columns=columns,
        slope_columns=list(columns[1:]),
        slope_index=slope_index,
        slope_rows=slope_index[:, None],
        display=tuple(layout.display[t] for t in model[1:]),
        terms=tuple(layout.terms[t] for t in model),
        column_names=tuple(layout.column_names[c] for t in model for c in layout.columns[t]),
        column_terms=tuple(layout.terms[t] for t in model for _ in layout.columns[t]),
    )
