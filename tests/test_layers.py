"""No module imports a layer above its own (every import statement, also inside functions).

The layers and their rules are written in ``docs/architecture.md`` ("Layers"); this test
reads the table there, so the page and the check cannot drift apart. Every module of
``workbench`` and ``data_contracts`` must have a layer (a new package without a row fails),
and every entry of the table must name a module.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ARCHITECTURE = ROOT / "docs" / "architecture.md"

#: Entries that name only themselves, not the modules below them (the package's lazy names).
ONLY_ITSELF = {"workbench"}


def read_layers(text: str) -> dict[str, int]:
    """Module -> layer from the table of the "Layers" section of *text*."""
    section = text.split("## Layers", 1)[1].split("\n## ", 1)[0]
    layers = {}
    for line in section.splitlines():
        row = re.match(r"\|\s*(\d+)\s*\|([^|]*)\|", line)
        if row:
            for name in re.findall(r"`([\w.]+)`", row.group(2)):
                assert name not in layers, f"{name} has two rows"
                layers[name] = int(row.group(1))
    return layers


LAYERS = read_layers(ARCHITECTURE.read_text(encoding="utf-8"))


def layer(module: str) -> int:
    """The layer of the longest entry *module* starts with (KeyError: none)."""
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        prefix = ".".join(parts[:n])
        if prefix in LAYERS and (prefix not in ONLY_ITSELF or prefix == module):
            return LAYERS[prefix]
    raise KeyError(f"{module}: no layer; add it to the table in docs/architecture.md")


def imports(path: Path, module: str) -> list[tuple[int, str]]:
    """(line, module) of every workbench/data_contracts import in *path*."""
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                name = ".".join(base + ([node.module] if node.module else []))
                # "from . import views": the names may be submodules
                names = (
                    [_module_or_package(name, a.name) for a in node.names]
                    if not node.module
                    else [name]
                )
            else:
                names = [node.module]
            found += [(node.lineno, n) for n in names]
    return [(line, n) for line, n in found if n.split(".")[0] in ("workbench", "data_contracts")]


def _module_or_package(package: str, name: str) -> str:
    """``package.name`` if it is a module, else *package* (a name defined in it)."""
    path = ROOT.joinpath(*package.split("."), name)
    return f"{package}.{name}" if path.with_suffix(".py").exists() or path.is_dir() else package


def modules():
    for top in ("workbench", "data_contracts"):
        for path in sorted((ROOT / top).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            yield path, name


def test_every_module_has_a_layer_and_every_entry_names_a_module():
    names = [name for _, name in modules()]
    without = []
    for name in names:
        try:
            layer(name)
        except KeyError as error:
            without.append(str(error))
    assert not without, "\n".join(without)
    stale = [e for e in LAYERS if not any(n == e or n.startswith(e + ".") for n in names)]
    assert not stale, f"entries naming no module: {stale}"
    assert len(LAYERS) >= 30 and max(LAYERS.values()) >= 12


def test_the_table_orders_the_top_packages():
    """cli <-> monitor was a cycle; the monitor, dashboard and demo have one direction."""
    order = ["workbench.dashboard", "workbench.monitor", "workbench.demo", "workbench.cli"]
    assert [layer(m) for m in order] == sorted({layer(m) for m in order})
    assert layer("workbench.cli.monitoring") > layer("workbench.monitor.core")
    assert layer("workbench.arguments") < layer("workbench.cli") < layer("workbench.launch")


def test_a_new_module_without_a_row_has_no_layer():
    """``workbench`` names only itself: a new top-level module does not fall under it."""
    assert layer("workbench") == 0
    for name in ("workbench.new_module", "workbench.new_package.part"):
        try:
            layer(name)
        except KeyError as error:
            assert "docs/architecture.md" in str(error)
        else:
            raise AssertionError(f"{name} got a layer")


def test_no_module_imports_a_layer_above_it():
    upward = []
    for path, module in modules():
        own = layer(module)
        for line, target in imports(path, module):
            if layer(target) > own:
                upward.append(
                    f"{path.relative_to(ROOT)}:{line}: {module} ({own}) imports {target} ({layer(target)})"
                )
    assert not upward, "\n".join(upward)


def test_the_check_sees_an_upward_import(tmp_path):
    """The parser finds relative and function-level imports (else the test above is void)."""
    path = tmp_path / "diagnostics.py"
    path.write_text(
        "def f():\n    from ..reporting import x\n    from . import stepwise, DEFAULT\n"
    )
    found = dict((n, line) for line, n in imports(path, "workbench.stats.diagnostics"))
    assert found == {"workbench.reporting": 2, "workbench.stats.stepwise": 3, "workbench.stats": 3}
    assert layer("workbench.reporting") > layer("workbench.stats.diagnostics")
