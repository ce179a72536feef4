"""A package's names loaded on first use (PEP 562), the pattern of Scientific Python's SPEC 1.

The command line imports a package for its options alone (``workbench.forecasting``'s
defaults, say) and should not pay for the machinery behind its other names; a package
lists them in a table of name -> submodule and takes its module ``__getattr__`` and
``__dir__`` from :func:`attach`. Type checkers and readers see the names through an
``if TYPE_CHECKING:`` block of ordinary imports beside the table.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import import_module
from typing import Any

__all__ = ["attach"]


def attach(
    package: str, exports: Mapping[str, str], namespace: dict[str, Any]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` of *package* whose names *exports* maps to the
    (relative) submodules defining them; a name is imported on first use and then kept in
    the package's *namespace* (its ``globals()``)."""

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(import_module(module, package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *exports})

    return __getattr__, __dir__
