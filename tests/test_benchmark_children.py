"""Benchmarks' child processes import the library the benchmark imported.

``python -m workbench.cli`` puts the current folder first on the module path: a benchmark
run from a folder holding another ``workbench`` (another checkout, while two trees are
compared with PYTHONPATH) would run that one in its children. ``benchmarks/child_library``
pins the children to the parent's library.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import workbench

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "child_library.py"


def _child_library():
    spec = importlib.util.spec_from_file_location("child_library_under_test", _PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _decoy(folder: Path) -> Path:
    """A folder holding another ``workbench`` whose command line says so."""
    package = folder / "workbench"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "cli.py").write_text("print('decoy workbench')\n")
    return folder


def _version(cwd: Path, env: dict[str, str]) -> str:
    done = subprocess.run(
        [sys.executable, "-m", "workbench.cli", "--version"],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    return done.stdout.strip()


def test_a_child_run_from_another_checkout_imports_the_parents_library(tmp_path):
    folder = _decoy(tmp_path)
    plain = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONSAFEPATH")}
    # the hazard: from that folder a child runs the decoy
    assert _version(folder, dict(plain)) == "decoy workbench"
    pinned = dict(plain, PYTHONPATH=os.pathsep.join(["/nonexistent", str(tmp_path / "x")]))
    root = _child_library().pin_library(pinned)
    assert root == Path(workbench.__file__).resolve().parents[1]
    # the library's root first, the earlier entries kept after it, the current folder off the path
    assert pinned["PYTHONPATH"].split(os.pathsep) == [
        str(root),
        "/nonexistent",
        str(tmp_path / "x"),
    ]
    assert pinned["PYTHONSAFEPATH"] == "1"
    assert _version(folder, pinned) == f"workbench {workbench.__version__}"


def test_pinning_twice_changes_nothing():
    env = {"PYTHONPATH": "/a"}
    library = _child_library()
    library.pin_library(env)
    once = dict(env)
    library.pin_library(env)
    assert env == once
