"""No module imports a layer above its own (every import statement, also inside functions).

Layers, bottom up: data contracts; infrastructure (errors, blocks, the per-block store,
parallel runs, joins, configuration) with signals and predictors; sid; stats and the
simulator (which imitates identification with sid's functions); forecast and health; the figure modules of reporting (they draw from tables and
stage results and import nothing above stats); the stages (``workbench.stages`` and the
identify engine ``workbench.identify``); at the top the run report builder, the demo, the
CLI and its argument helpers, the monitor and the dashboard.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: Layer of each module prefix; the longest matching prefix wins.
LAYERS = {
    "data_contracts": 0,
    "workbench": 0,  # the package itself: lazy names only
    "workbench.errors": 0,
    "workbench.dynamics": 0,
    "workbench.progress": 0,
    "workbench.blocks": 1,
    "workbench.store": 1,
    "workbench.parallel": 1,
    "workbench.processes": 1,
    "workbench.local_workers": 1,
    "workbench.joins": 1,
    "workbench.config": 1,
    "workbench.signals": 1,
    "workbench.predictors": 1,
    "workbench.simulate": 3,  # the simulator imitates identification with sid's own functions
    "workbench.sid": 2,
    "workbench.stats": 3,
    "workbench.forecast": 4,
    "workbench.health": 4,
    "workbench.reporting": 5,
    "workbench.identify": 6,
    "workbench.identification": 6,  # the identify engine, one module per responsibility
    "workbench.stages": 6,
    "workbench.reporting.report": 7,
    "workbench.demo": 7,
    "workbench.inputs": 7,
    "workbench.cli": 7,
    "workbench.launch": 7,  # the command's entry point, importing the CLI on call
    "workbench.__main__": 7,
    "workbench.defaults": 7,  # the command line's defaults, read from the library
    "workbench.arguments": 7,
    "workbench.dashboard": 7,
    "workbench.monitor": 7,
}


def layer(module: str) -> int:
    parts = module.split(".")
    for n in range(len(parts), 0, -1):
        prefix = ".".join(parts[:n])
        if prefix in LAYERS:
            return LAYERS[prefix]
    raise KeyError(f"{module}: no layer; add its package to LAYERS")


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
                names = [f"{name}.{a.name}" for a in node.names] if not node.module else [name]
            else:
                names = [node.module]
            found += [(node.lineno, n) for n in names]
    return [(line, n) for line, n in found if n.split(".")[0] in ("workbench", "data_contracts")]


def modules():
    for top in ("workbench", "data_contracts"):
        for path in sorted((ROOT / top).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            yield path, name


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
    path.write_text("def f():\n    from ..reporting import x\n    from . import modes\n")
    found = dict((n, line) for line, n in imports(path, "workbench.stats.diagnostics"))
    assert found == {"workbench.reporting": 2, "workbench.stats.modes": 3}
    assert layer("workbench.reporting") > layer("workbench.stats.diagnostics")
