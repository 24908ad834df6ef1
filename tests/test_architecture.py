"""The house rules: layers import only downwards, no import cycles, no oversized modules,
SQL only in the study's data layer, and ARCHITECTURE.md's layer table equal to the one here.

Every ``import`` in snapcore, study_app and analysis is read from the source (at module
level and inside functions alike), resolved to the project module it names, and checked
against the layer table below (see ARCHITECTURE.md): data flows motion → selection →
rendering → relief/pipeline → bench/CLI → the study's design → its data → the session →
analysis → the web UI → operations → the study's commands, and a module may import only
from its own layer or a lower one.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("snapcore", "study_app", "analysis", "data_schema")
# one concept per module: the longest are a selector's stages (contacts, story) and the
# synthetic motions, each one concept
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
    "study_app.design": 9,  # protocol, scenes, stimuli: what a study shows
    "study_app.data": 10,  # tables, store, export, withdrawal, pseudonyms, backup: all SQL
    "study_app.session": 11,  # one participant's walk through the protocol
    "analysis": 12,  # reads the store and the stimulus manifest
    "study_app.web": 13,  # the Streamlit UI: the researcher screen shows analysis results
    "study_app.ops": 14,  # replicas and the load test: run the web servers as processes
    "study_app.commands": 15,  # the study's `snapshot` commands
    "study_app": 16,  # the package itself: its public names, imported by nothing inside
}


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        # compiled modules (Cython .pyx, built at install time) are modules too: their
        # importers resolve to them, and they obey the same layers and size bound
        for path in sorted([*(ROOT / pkg).rglob("*.py"), *(ROOT / pkg).rglob("*.pyx")]):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()
#: A Python import statement on one line of a Cython module (``cimport`` lines name C
#: declarations, not project modules).
PYX_IMPORT = re.compile(r"^(?:import [\w.]+(?: as \w+)?|from [\w.]+ import [\w, ]+)$")


def layer(module: str) -> int:
    best = max((p for p in LAYERS if module == p or module.startswith(p + ".")), key=len)
    return LAYERS[best]


def _imports(module: str, path: Path) -> list[tuple[str, int]]:
    """(imported project module, line) for every import statement in ``path``."""
    if path.suffix == ".pyx":  # Cython is not Python syntax: its import lines, read as text
        source = "\n".join(
            line if PYX_IMPORT.match(line) else "" for line in path.read_text().splitlines()
        )
    else:
        source = path.read_text()
    tree = ast.parse(source, filename=str(path))
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
            names = [
                f"{base}.{a.name}" if f"{base}.{a.name}" in MODULES else base for a in node.names
            ]
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


def test_every_study_module_is_in_a_named_layer():
    """A new module directly under ``study_app/`` must be placed in one of its layers,
    not fall under the package's own entry (which is for ``study_app/__init__`` only)."""
    loose = [
        m
        for m in MODULES
        if m.startswith("study_app.")
        and max((p for p in LAYERS if m == p or m.startswith(p + ".")), key=len) == "study_app"
    ]
    assert not loose, loose


def test_no_import_climbs_to_a_higher_layer():
    """No module imports from a layer above its own, at module level or inside a function."""
    bad = [
        f"{MODULES[m].relative_to(ROOT)}:{line} imports {target} "
        f"(layer {layer(target)} > {layer(m)})"
        for m, edges in GRAPH.items()
        for target, line in edges
        if layer(target) > layer(m)
    ]
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
                cycles.append(" -> ".join(stack[stack.index(target) :] + [target]))
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
    """No module is longer than MAX_LINES (800) lines (split by concept, not by length,
    before then); ARCHITECTURE.md states the same bound (test_docs)."""
    n = len(MODULES[module].read_text().splitlines())
    assert n <= MAX_LINES, f"{module}: {n} lines"


def test_the_checker_sees_upward_and_cyclic_imports(tmp_path):
    """Known answer: a function-level import climbing a layer is found by the parser."""
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from snapcore.pipeline import take_snapshot\n")
    assert ("snapcore.pipeline", 2) in _imports("snapcore.motion.fake", src)
    assert layer("snapcore.pipeline") > layer("snapcore.motion.fake")


def test_compiled_modules_are_checked_too(tmp_path):
    """Known answer: the Cython kernel is a module of its layer, and a project import in a
    .pyx file is found (its ``cimport`` lines are not imports of project modules)."""
    assert "snapcore.select._pma_kernel" in MODULES
    src = tmp_path / "m.pyx"
    src.write_text(
        "# cython: language_level=3\nfrom libc.math cimport sqrt\ncdef double x = 1.0\n"
        "from snapcore.pipeline import take_snapshot\n"
    )
    assert _imports("snapcore.select.fake", src) == [("snapcore.pipeline", 4)]


# -- SQL lives in the data layer ---------------------------------------------------------
#: What counts as SQL in a line of source: a SQLAlchemy statement (``sa.text(...)``,
#: ``sa.select(...)``, ... or those names imported from sqlalchemy), a database driver
#: (``sqlite3``, ``psycopg``) imported, a raw script run, or a string literal that starts
#: with an SQL keyword in capitals.
SQL = re.compile(
    r"""
    \b(?:sa|sqlalchemy)\.(?:text|select|insert|update|delete)\(
  | ^\s*from\ sqlalchemy(?:\.\w+)*\ import\ .*\b(?:text|select|insert|update|delete)\b
  | ^\s*(?:import|from)\ (?:sqlite3|psycopg)\b
  | \.(?:exec_driver_sql|executescript)\(
  | ["'](?:SELECT|INSERT\ INTO|UPDATE\ \w+\ SET|DELETE\ FROM|CREATE|DROP|ALTER|PRAGMA|VACUUM|BEGIN|COMMIT)\b
""",
    re.X,
)
DATA_LAYER = "study_app.data"


def _sql_lines(path: Path) -> list[tuple[int, str]]:
    return [
        (i, line.strip())
        for i, line in enumerate(path.read_text().splitlines(), 1)
        if SQL.search(line)
    ]


def test_sql_appears_only_in_the_data_layer():
    """Every SQL statement, SQLAlchemy statement builder and database driver import is
    under ``study_app/data/``: the rest of the project asks the store."""
    bad = [
        f"{path.relative_to(ROOT)}:{i}: {line}"
        for m, path in MODULES.items()
        if layer(m) != LAYERS[DATA_LAYER]
        for i, line in _sql_lines(path)
    ]
    assert not bad, "\n".join(bad)


def test_the_sql_pattern_finds_sql():
    """Known answers: the store's own statements are found, and so are the kinds of SQL
    the pattern names (the replica supervisor's old database check among them)."""
    assert _sql_lines(ROOT / "study_app" / "data" / "participant_records.py")
    for line in (
        "rows = conn.execute(sa.select(participants.c.id))",
        "from sqlalchemy import delete, select",
        "import sqlite3",
        "    import psycopg",
        'conn.execute("SELECT 1 FROM pg_database WHERE datname = %s", (name,))',
        "conn.execute(f'CREATE DATABASE \"{name}\"')",
        "con.executescript(script)",
    ):
        assert SQL.search(line), line
    for line in (
        '"""Select the frames (no SQL here)."""',
        "select_pose(scene)",
        "parts.insert(0, x)",
        'ax.text(0.5, 0.5, "no events")',
    ):
        assert not SQL.search(line), line


# -- ARCHITECTURE.md follows this table ----------------------------------------------------
def _documented_layers() -> dict[str, int]:
    """ARCHITECTURE.md's layer table: every backquoted module name of the package column
    → the layer of its row."""
    text = (ROOT / "ARCHITECTURE.md").read_text()
    section = text.split("## The layers", 1)[1].split("\n## ", 1)[0]
    out = {}
    for row in section.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) >= 4 and cells[0].isdigit():
            for name in re.findall(r"`([\w.]+)`", cells[1]):
                out[name] = int(cells[0])
    return out


def test_architecture_md_lists_the_layer_table():
    """ARCHITECTURE.md's layer table names exactly the packages of ``LAYERS``, each in its
    layer, and says each layer may import the layers below it."""
    assert _documented_layers() == LAYERS
    text = (ROOT / "ARCHITECTURE.md").read_text().split("## The layers", 1)[1].split("\n## ", 1)[0]
    for row in text.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) >= 4 and cells[0].isdigit():
            n = int(cells[0])
            assert cells[3] == {0: "—", 1: "0"}.get(n, f"0–{n - 1}"), row
