"""Packages whose public names are imported on first use (PEP 562: workbench.forecasting,
.shm, .simulate, .stats): every name of ``__all__`` is the object its module defines, also
after every submodule has been imported (a submodule bound on the package under a public
name would shadow the lazy name), and unknown names raise AttributeError."""

from __future__ import annotations

import importlib
import pkgutil
import types

import pytest

PACKAGES = ["workbench.forecasting", "workbench.shm", "workbench.simulate", "workbench.stats"]


@pytest.mark.parametrize("name", PACKAGES)
def test_lazy_names_are_the_defined_objects(name):
    package = importlib.import_module(name)
    for info in pkgutil.walk_packages(package.__path__, name + "."):
        importlib.import_module(info.name)
    for public in package.__all__:
        value = getattr(package, public)
        assert not isinstance(value, types.ModuleType), public
        module = package._EXPORTS.get(public)
        if module is not None:
            assert value is getattr(importlib.import_module(module, name), public)
        assert public in dir(package)
    with pytest.raises(AttributeError, match="no attribute 'not_a_name'"):
        package.not_a_name  # noqa: B018 - the access is the test
