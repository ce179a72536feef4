"""Renamed parameters and fields: the old spelling keeps working, with a DeprecationWarning.

The project's vocabulary (README, "Glossary") gives every concept one name. Where a name
changed, code written against the old one still runs: the old keyword is accepted, mapped
onto the new one and a :class:`DeprecationWarning` says which name to use (scikit-learn
style). Giving both spellings is a ``TypeError``.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

__all__ = ["DEPRECATED", "renamed_argument", "renamed_fields", "renamed_parameters"]

F = TypeVar("F", bound=Callable[..., Any])
C = TypeVar("C", bound=type)


def _warn(owner: str, old: str, new: str, stacklevel: int) -> None:
    warnings.warn(
        f"{owner}: '{old}' is deprecated and will be removed; use '{new}'",
        DeprecationWarning,
        stacklevel=stacklevel,
    )


def _target(rename) -> tuple[str, Callable[[Any], Any], Callable[[Any], Any]]:
    """(new name, old value -> new value, new value -> old value) of a rename given as the
    new name or as that triple (a parameter whose meaning was widened, e.g. a maximum that
    became a pair of limits)."""
    if isinstance(rename, str):
        return rename, _same, _same
    return rename


def _same(value):
    return value


def _translate(owner: str, renames: Mapping[str, Any], kwargs: dict, stacklevel: int) -> dict:
    """*kwargs* with every old keyword of *renames* replaced by its new name (and value)."""
    if not renames.keys() & kwargs.keys():
        return kwargs
    kwargs = dict(kwargs)
    for old, rename in renames.items():
        if old not in kwargs:
            continue
        new, to_new, _ = _target(rename)
        if new in kwargs:
            raise TypeError(f"{owner}: give '{new}' only ('{old}' is its deprecated name)")
        _warn(owner, old, new, stacklevel + 1)
        kwargs[new] = to_new(kwargs.pop(old))
    return kwargs


def renamed_parameters(**renames: Any) -> Callable[[F], F]:
    """Decorator: accept the old keyword names ``old=new`` of a function, with a warning.

    Examples
    --------
    >>> @renamed_parameters(like="onto")
    ... def load(*, onto=None):
    ...     return onto
    """

    def decorate(function: F) -> F:
        owner = f"{function.__qualname__}()"

        @functools.wraps(function)
        def wrapper(*args, **kwargs):
            return function(*args, **_translate(owner, renames, kwargs, 3))

        wrapper.__deprecated_parameters__ = {o: _target(r)[0] for o, r in renames.items()}  # type: ignore[attr-defined]
        return wrapper  # type: ignore[return-value]

    return decorate


def renamed_fields(**renames: Any) -> Callable[[C], C]:
    """Class decorator for (frozen) dataclasses: old field names ``old=new`` (or
    ``old=(new, to_new, to_old)``) are accepted by the constructor and readable as
    attributes, both with a DeprecationWarning."""

    def decorate(cls: C) -> C:
        init = cls.__init__
        owner = cls.__name__

        @functools.wraps(init)
        def __init__(self, *args, **kwargs):
            init(self, *args, **_translate(owner, renames, kwargs, 3))

        cls.__init__ = __init__  # type: ignore[misc]
        for old, rename in renames.items():
            new, _, to_old = _target(rename)

            def getter(self, _old=old, _new=new, _to_old=to_old):
                _warn(owner, _old, _new, 3)
                return _to_old(getattr(self, _new))

            setattr(cls, old, property(getter, doc=f"Deprecated name of ``{new}``."))
        cls.__deprecated_fields__ = {o: _target(r)[0] for o, r in renames.items()}  # type: ignore[attr-defined]
        return cls

    return decorate


class _Unset:
    def __repr__(self) -> str:
        return "<deprecated>"


#: Default of a deprecated keyword kept in a signature (see :func:`renamed_argument`).
DEPRECATED: Any = _Unset()


def renamed_argument(owner: str, old: str, old_value, new: str, new_value, default):
    """The value of parameter *new* when its deprecated name *old* may have been given.

    For functions whose warnings point at their caller (``stacklevel=2``), where the
    wrapper of :func:`renamed_parameters` would add a frame: the old keyword stays in the
    signature with the default :data:`DEPRECATED`, and the body calls this first.
    """
    if old_value is DEPRECATED:
        return new_value
    if new_value is not default and new_value != default:
        raise TypeError(f"{owner}: give '{new}' only ('{old}' is its deprecated name)")
    _warn(owner, old, new, 4)  # _warn <- renamed_argument <- the function <- its caller
    return old_value
