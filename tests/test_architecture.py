"""The house rules: layers import only downwards, no import cycles, no oversized modules.

Every ``import`` in snapcore, study_app and analysis is read from the source (at module
level and inside functions alike), resolved to the project module it names, and checked
against the layer table below (see ARCHITECTURE.md): data flows motion → selection →
rendering → relief/pipeline → bench/CLI → study → analysis → the app's screens, and a
module may import only from its own layer or a lower one.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("snapcore", "study_app", "analysis", "data_schema")
MAX_LINES = 800

#: Module-name prefix → layer rank (the longest matching prefix wins).
LAYERS = {
    "data_schema": 0,
    "snapcore.errors": 0,
    "snapcore.schema": 0,
    "snapcore._memory": 0,
    "snapcore.motion": 1,
    "snapcore.select": 2,
    "snapcore.render": 3,
    "snapcore.relief": 4,
    "snapcore.pipeline": 5,
    "snapcore.bench": 6,
    "snapcore.batch": 6,  # a library of scenes: pipeline and renders per scene, under the CLI
    "snapcore.cli": 7,
    "snapcore": 8,  # the package itself: the public API, imported by nothing inside
    "study_app": 9,  # study logic: protocol, store, export, stimuli, session, commands
    "analysis": 10,  # reads the store and the stimulus manifest
    "study_app.app": 11,  # the Streamlit UI: the researcher screen shows analysis results
    "study_app.screens": 11,
    "study_app.picker": 11,
    "study_app.server": 11,  # the server process that runs the UI (and warms its imports)
}


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def layer(module: str) -> int:
    best = max((p for p in LAYERS if module == p or module.startswith(p + ".")), key=len)
    return LAYERS[best]


def _imports(module: str, path: Path) -> list[tuple[str, int]]:
    """(imported project module, line) for every import statement in ``path``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_pkg = path.name == "__init__.py"
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = module.split(".") if is_pkg else module.split(".")[:-1]
                parts = parts[: len(parts) - (node.level - 1)]
                base = ".".join(parts + ([node.module] if node.module else []))
            # "from pkg import sub" imports the submodule when there is one
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base
                     for a in node.names]
        else:
            continue
        for name in names:
            # the longest project module the dotted name starts with
            while name and name not in MODULES:
                name = name.rpartition(".")[0]
            if name and name != module:
                found.append((name, node.lineno))
    return found


GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


def test_the_layer_table_knows_every_module():
    """Every project module falls under a layer (a new top-level package must be placed)."""
    assert all(any(m == p or m.startswith(p + ".") for p in LAYERS) for m in MODULES)


def test_no_import_climbs_to_a_higher_layer():
    """No module imports from a layer above its own, at module level or inside a function."""
    bad = [f"{MODULES[m].relative_to(ROOT)}:{line} imports {target} "
           f"(layer {layer(target)} > {layer(m)})"
           for m, edges in GRAPH.items() for target, line in edges
           if layer(target) > layer(m)]
    assert not bad, "\n".join(bad)


def test_no_import_cycles():
    """The module import graph is acyclic (including imports inside functions)."""
    state: dict[str, int] = {}
    cycles = []

    def visit(m, stack):
        state[m] = 1
        stack.append(m)
        for target, _ in GRAPH[m]:
            if state.get(target) == 1:
                cycles.append(" -> ".join(stack[stack.index(target):] + [target]))
            elif target not in state:
                visit(target, stack)
        stack.pop()
        state[m] = 2

    for m in MODULES:
        if m not in state:
            visit(m, [])
    assert not cycles, "\n".join(cycles)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_modules_stay_readable(module):
    """No module is longer than 800 lines (split by concept, not by length, before then)."""
    n = len(MODULES[module].read_text().splitlines())
    assert n <= MAX_LINES, f"{module}: {n} lines"


def test_the_checker_sees_upward_and_cyclic_imports(tmp_path):
    """Known answer: a function-level import climbing a layer is found by the parser."""
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from snapcore.pipeline import take_snapshot\n")
    assert ("snapcore.pipeline", 2) in _imports("snapcore.motion.fake", src)
    assert layer("snapcore.pipeline") > layer("snapcore.motion.fake")
