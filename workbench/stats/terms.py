"""Model terms of a linear model: names, canonical order and a small formula parser.

A term is a tuple of predictor column indices: ``()`` is the intercept, ``(i,)`` the main
effect of column *i* and ``(i, j)`` with ``i < j`` the two-way interaction ``a:b``. Terms
are kept in MATLAB's order: intercept, main effects in column order, then interactions in
lexicographic order of their column pairs (``x1:x2, x1:x3, ..., x2:x3, ...``).

Formula text (Wilkinson notation, as in MATLAB ``fitlm``/``stepwiselm``) is tokenised and
parsed here; it is never evaluated. Supported: ``y ~ x1 + x2 + x1:x2``, ``x1*x2`` (expands
to ``x1 + x2 + x1:x2``), ``- term`` (removes a term) and ``1`` (the intercept, which is
always in the model).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Sequence
from itertools import combinations

__all__ = ["Term", "canonical_order", "parse_terms", "term_name"]

Term = tuple[int, ...]

#: Model names accepted for ``start`` and ``upper``.
NAMED_MODELS = ("constant", "linear", "interactions")

_TOKEN = re.compile(r"\s*(?:(?P<name>[A-Za-z_][A-Za-z0-9_.]*)|(?P<number>\d+)|(?P<op>[~+\-:*]))")


def term_name(term: Term, names: Sequence[str]) -> str:
    """Display name of *term*: ``"(Intercept)"``, ``"x1"`` or ``"x1:x2"``."""
    if not term:
        return "(Intercept)"
    return ":".join(names[i] for i in term)


def canonical_order(terms) -> list[Term]:
    """Sort terms: intercept, main effects by column, interactions by column pair."""
    return sorted(set(terms), key=lambda t: (len(t), t))


def _named_model(spec: str, n_columns: int) -> list[Term]:
    terms: list[Term] = [()]
    if spec in ("linear", "interactions"):
        terms += [(i,) for i in range(n_columns)]
    if spec == "interactions":
        terms += list(combinations(range(n_columns), 2))
    return terms


def _tokenize(text: str, parameter: str) -> list[tuple[str, str, int]]:
    tokens = []
    position = 0
    stripped_end = len(text.rstrip())
    while position < stripped_end:
        match = _TOKEN.match(text, position)
        if match is None or match.end() == position:
            bad = text[position:].lstrip()[:1]
            where = len(text) - len(text[position:].lstrip())
            raise ValueError(
                f"{parameter}={text!r}: unexpected character {bad!r} at position {where}; "
                "formulas use names, numbers and ~ + - : * only"
            )
        kind = match.lastgroup
        tokens.append((kind, match.group(kind), match.start(kind)))
        position = match.end()
    return tokens


def _parse_formula(text: str, names: Sequence[str], parameter: str) -> list[Term]:
    """Parse Wilkinson formula *text* into terms (intercept always included)."""
    tokens = _tokenize(text, parameter)
    ops = [value for kind, value, _ in tokens if kind == "op"]
    if ops.count("~") > 1:
        raise ValueError(f"{parameter}={text!r}: more than one '~'")
    if "~" in ops:
        split = next(i for i, (_, value, _) in enumerate(tokens) if value == "~")
        lhs, tokens = tokens[:split], tokens[split + 1 :]
        if len(lhs) > 1 or (lhs and lhs[0][0] != "name"):
            raise ValueError(f"{parameter}={text!r}: the left of '~' must be one response name")
    if not tokens:
        raise ValueError(f"{parameter}={text!r}: no terms after '~'")
    index = {name: i for i, name in enumerate(names)}
    included: set[Term] = {()}
    removed: set[Term] = set()
    position = 0

    def expect_factor() -> str | None:
        nonlocal position
        if position >= len(tokens):
            raise ValueError(f"{parameter}={text!r}: formula ends after an operator")
        kind, value, where = tokens[position]
        position += 1
        if kind == "number":
            if value not in ("0", "1"):
                raise ValueError(
                    f"{parameter}={text!r}: number {value!r} at position {where}; "
                    "only 1 (intercept) is allowed"
                )
            return None if value == "1" else "0"
        if kind != "name":
            raise ValueError(f"{parameter}={text!r}: expected a name at position {where}")
        if value not in index:
            raise ValueError(
                f"{parameter}={text!r}: unknown predictor {value!r}; available: "
                + ", ".join(map(repr, names))
            )
        return value

    sign = "+"
    if tokens[0][0] == "op" and tokens[0][1] in ("+", "-"):
        sign = tokens[0][1]
        position = 1
    while True:
        first = expect_factor()
        products: list[frozenset[str]] = [frozenset() if first is None else frozenset([first])]
        constant_only = first is None or first == "0"
        while position < len(tokens) and tokens[position][1] in (":", "*"):
            op = tokens[position][1]
            position += 1
            factor = expect_factor()
            if factor is None or factor == "0" or constant_only:
                raise ValueError(f"{parameter}={text!r}: 1 and 0 cannot be multiplied")
            if op == ":":
                products = [p | {factor} for p in products]
            else:
                products = products + [frozenset([factor])] + [p | {factor} for p in products]
        if first == "0":
            raise ValueError(
                f"{parameter}={text!r}: the intercept is always in the model ('0' not allowed)"
            )
        for product in products:
            if len(product) > 2:
                raise ValueError(
                    f"{parameter}={text!r}: term {':'.join(sorted(product))!r} has more than two "
                    "factors; only main effects and two-way interactions are supported"
                )
            term = tuple(sorted(index[name] for name in product))
            (included if sign == "+" else removed).add(term)
        if position >= len(tokens):
            break
        kind, value, where = tokens[position]
        if kind != "op" or value not in "+-":
            raise ValueError(
                f"{parameter}={text!r}: expected '+' or '-' at position {where}, got {value!r}"
            )
        sign = value
        position += 1
    if () in removed:
        raise ValueError(f"{parameter}={text!r}: the intercept is always in the model")
    return canonical_order(included - removed)


def _parse_term_list(items: Sequence[str], names: Sequence[str], parameter: str) -> list[Term]:
    index = {name: i for i, name in enumerate(names)}
    terms: set[Term] = {()}
    for item in items:
        if not isinstance(item, str):
            raise TypeError(f"{parameter}: term {item!r} is not a string")
        if item.strip() in ("1", "(Intercept)", ""):
            continue
        parts = [part.strip() for part in item.split(":")]
        unknown = [part for part in parts if part not in index]
        if unknown:
            raise ValueError(
                f"{parameter}: term {item!r} names unknown predictor {unknown[0]!r}; available: "
                + ", ".join(map(repr, names))
            )
        if len(parts) > 2 or len(set(parts)) != len(parts):
            raise ValueError(
                f"{parameter}: term {item!r} is not a main effect or a two-way interaction "
                "of two different predictors"
            )
        terms.add(tuple(sorted(index[part] for part in parts)))
    return canonical_order(terms)


@functools.lru_cache(maxsize=256)
def _parse_cached(spec: str | tuple[str, ...], names: tuple[str, ...], parameter: str):
    if isinstance(spec, tuple):
        return tuple(_parse_term_list(spec, names, parameter))
    if spec in NAMED_MODELS:
        return tuple(_named_model(spec, len(names)))
    return tuple(_parse_formula(spec, names, parameter))


def parse_terms(spec, names: Sequence[str], *, parameter: str = "terms") -> list[Term]:
    """Terms of a model given by name, formula text or a list of term strings.

    Parameters
    ----------
    spec : {"constant", "linear", "interactions"}, str or sequence of str
        A named model; a Wilkinson formula such as ``"y ~ x1 + x2 + x1:x2"`` or
        ``"x1*x2"``; or term strings such as ``["x1", "x1:x2"]``. The text is tokenised
        and parsed, never evaluated.
    names : sequence of str
        Predictor column names (``x1..xn`` for arrays).
    parameter : str
        Parameter name used in error messages.

    Returns
    -------
    list of tuple of int
        Terms in canonical order, the intercept ``()`` first.
    """
    if isinstance(spec, str):
        key: str | tuple[str, ...] = spec
    elif isinstance(spec, Sequence):
        key = tuple(spec)
        if not all(isinstance(item, str) for item in key):
            raise TypeError(f"{parameter}: every term must be a string, got {spec!r}")
    else:
        raise TypeError(
            f"{parameter}={spec!r}: expected a model name, a formula or a list of term strings"
        )
    return list(_parse_cached(key, tuple(names), parameter))
