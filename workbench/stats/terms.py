"""Model terms of a linear model: names, canonical order and a small formula parser.

A term is a tuple of predictor column indices: ``()`` is the intercept, ``(i,)`` the main
effect of column *i*, ``(i, j)`` with ``i < j`` the two-way interaction ``a:b`` and
``(i, i)`` the squared term ``a^2``. Terms are kept in MATLAB's order: intercept, main
effects in column order, interactions in lexicographic order of their column pairs
(``x1:x2, x1:x3, ..., x2:x3, ...``), then squares (``x1^2, x2^2, ...``).

Formula text (Wilkinson notation, as in MATLAB ``fitlm``/``stepwiselm``) is tokenised and
parsed here; it is never evaluated. Supported: ``y ~ x1 + x2 + x1:x2``, ``x1*x2`` (expands
to ``x1 + x2 + x1:x2``), ``x1^2`` (squared term), ``- term`` (removes a term) and ``1``
(the intercept, which is always in the model).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Sequence
from itertools import combinations

__all__ = [
    "Term",
    "canonical_order",
    "is_square",
    "parents",
    "parse_terms",
    "term_key",
    "term_name",
]

Term = tuple[int, ...]

#: Model names accepted for ``start``, ``upper`` and ``lower`` (MATLAB's model names).
NAMED_MODELS = ("constant", "linear", "interactions", "purequadratic", "quadratic")

_TOKEN = re.compile(r"\s*(?:(?P<name>[A-Za-z_][A-Za-z0-9_.]*)|(?P<number>\d+)|(?P<op>[~+\-:*^]))")


def term_name(term: Term, names: Sequence[str]) -> str:
    """Display name of *term*: ``"(Intercept)"``, ``"x1"``, ``"x1:x2"`` or ``"x1^2"``."""
    if not term:
        return "(Intercept)"
    if len(term) == 2 and term[0] == term[1]:
        return f"{names[term[0]]}^2"
    return ":".join(names[i] for i in term)


def is_square(term: Term) -> bool:
    """Whether *term* is a squared term ``(i, i)``."""
    return len(term) == 2 and term[0] == term[1]


def term_key(term: Term) -> tuple:
    """Sort key of MATLAB's term order: degree, then interactions before squares."""
    return (len(term), 2 if is_square(term) else 1, term)


def canonical_order(terms) -> list[Term]:
    """Sort terms: intercept, main effects by column, interactions by column pair, squares."""
    return sorted(set(terms), key=term_key)


def parents(term: Term) -> tuple[Term, ...]:
    """Terms one order lower that *term* needs in the model (hierarchy): the main effects
    of an interaction or of a squared term; none for main effects and the intercept."""
    if len(term) < 2:
        return ()
    return tuple(sorted({(term[0],), (term[1],)}))


def _named_model(spec: str, n_columns: int, squarable: Sequence[bool] | None = None) -> list[Term]:
    terms: list[Term] = [()]
    if spec != "constant":
        terms += [(i,) for i in range(n_columns)]
    if spec in ("interactions", "quadratic"):
        terms += list(combinations(range(n_columns), 2))
    if spec in ("purequadratic", "quadratic"):
        terms += [(i, i) for i in range(n_columns) if squarable is None or squarable[i]]
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
        if kind == "name" and position < len(tokens) and tokens[position][1] == "^":
            power = tokens[position + 1] if position + 1 < len(tokens) else None
            if power is None or power[0] != "number" or power[1] not in ("1", "2"):
                raise ValueError(
                    f"{parameter}={text!r}: only the powers 1 and 2 are supported "
                    f"(after {value!r} at position {where})"
                )
            position += 2
            if power[1] == "2":
                if value not in index:
                    raise ValueError(
                        f"{parameter}={text!r}: unknown predictor {value!r}; available: "
                        + ", ".join(map(repr, names))
                    )
                return value + "^2"
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
            if factor.endswith("^2") or (first or "").endswith("^2"):
                raise ValueError(
                    f"{parameter}={text!r}: a squared term cannot be multiplied; only main "
                    "effects, two-way interactions and squares are supported"
                )
            if op == ":":
                products = [p | {factor} for p in products]
            else:
                products = products + [frozenset([factor])] + [p | {factor} for p in products]
        if first == "0":
            raise ValueError(
                f"{parameter}={text!r}: the intercept is always in the model ('0' not allowed)"
            )
        for product in products:
            squared = [name for name in product if name.endswith("^2")]
            if squared:
                term = (index[squared[0][:-2]],) * 2
                (included if sign == "+" else removed).add(term)
                continue
            if len(product) > 2:
                raise ValueError(
                    f"{parameter}={text!r}: term {':'.join(sorted(product))!r} has more than two "
                    "factors; only main effects, two-way interactions and squares are supported"
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
        squared = re.fullmatch(r"\s*(.+?)\s*\^\s*2\s*", item)
        if squared and squared.group(1) in index:
            terms.add((index[squared.group(1)],) * 2)
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
                "of two different predictors (write a square as 'x^2')"
            )
        terms.add(tuple(sorted(index[part] for part in parts)))
    return canonical_order(terms)


@functools.lru_cache(maxsize=256)
def _parse_cached(
    spec: str | tuple[str, ...],
    names: tuple[str, ...],
    parameter: str,
    squarable: tuple[bool, ...] | None,
):
    if isinstance(spec, tuple):
        return tuple(_parse_term_list(spec, names, parameter))
    if spec in NAMED_MODELS:
        return tuple(_named_model(spec, len(names), squarable))
    return tuple(_parse_formula(spec, names, parameter))


def parse_terms(
    spec,
    names: Sequence[str],
    *,
    parameter: str = "terms",
    squarable: Sequence[bool] | None = None,
) -> list[Term]:
    """Terms of a model given by name, formula text or a list of term strings.

    Parameters
    ----------
    spec : {"constant", "linear", "interactions", "purequadratic", "quadratic"}, str or \
sequence of str
        A named model (MATLAB's: ``"purequadratic"`` is the linear model plus squares,
        ``"quadratic"`` the interactions model plus squares); a Wilkinson formula such as
        ``"y ~ x1 + x2 + x1:x2 + x1^2"`` or ``"x1*x2"``; or term strings such as
        ``["x1", "x1:x2", "x1^2"]``. The text is tokenised and parsed, never evaluated.
    names : sequence of str
        Predictor column names (``x1..xn`` for arrays).
    parameter : str
        Parameter name used in error messages.
    squarable : sequence of bool, optional
        Per column, whether the named quadratic models square it (``False`` for a
        categorical predictor, whose square is itself); default all.

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
    flags = None if squarable is None else tuple(bool(b) for b in squarable)
    return list(_parse_cached(key, tuple(names), parameter, flags))
