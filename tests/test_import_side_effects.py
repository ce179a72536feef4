"""Importing the library changes nothing in the caller's process (matplotlib backend)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap


def test_importing_every_module_keeps_the_users_matplotlib_backend():
    # a notebook or GUI user has chosen a backend; no workbench module may switch it (the
    # CLI selects Agg itself, in main). "pdf" stands for any choice other than Agg.
    script = textwrap.dedent(
        """
        import importlib, pkgutil
        import matplotlib
        before = matplotlib.get_backend()
        import data_contracts, workbench
        names = []
        for package in (data_contracts, workbench):
            names.append(package.__name__)
            for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
                if not info.name.rsplit(".", 1)[-1].startswith("__"):
                    names.append(info.name)
        for name in names:
            importlib.import_module(name)
        print(len(names), before, matplotlib.get_backend())
        """
    )
    env = {**os.environ, "MPLBACKEND": "pdf"}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    n_modules, before, after = done.stdout.split()
    assert int(n_modules) > 80  # every module was imported, not just the packages
    assert before.lower() == "pdf" and after.lower() == "pdf"


def test_the_cli_selects_agg_for_itself(tmp_path):
    script = textwrap.dedent(
        f"""
        import matplotlib
        from workbench.cli import main
        status = main(["validate", "modal", {str(tmp_path / "missing.csv")!r}])
        print(status, matplotlib.get_backend())
        """
    )
    env = {**os.environ, "MPLBACKEND": "pdf"}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300
    )
    assert done.stdout.lower().split() == ["1", "agg"], done.stderr


def test_the_cli_selects_agg_before_matplotlib_is_imported(tmp_path):
    # a command that draws nothing does not import matplotlib; one imported afterwards (by
    # a later command in the same process) still comes up with Agg, not the user's "pdf"
    script = textwrap.dedent(
        f"""
        import sys
        from workbench.cli import main
        status = main(["validate", "modal", {str(tmp_path / "missing.csv")!r}])
        imported = "matplotlib" in sys.modules
        import matplotlib
        print(status, imported, matplotlib.get_backend())
        """
    )
    env = {**os.environ, "MPLBACKEND": "pdf"}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300
    )
    status, imported, backend = done.stdout.split()
    assert (status, backend.lower()) == ("1", "agg"), done.stderr
    assert imported in ("True", "False")  # either way the backend is Agg
