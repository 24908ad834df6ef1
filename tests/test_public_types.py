"""The public API keeps its types through the lazy ``__init__`` modules.

snapcore, snapcore.select, study_app and analysis import their public names on first use
(PEP 562 ``__getattr__``). A type checker cannot see through that, so without the
``if TYPE_CHECKING:`` imports beside it every public name would be ``Any`` and a caller's
mistakes (a wrong argument, a misspelt field of a result) would go unseen. This test asks
mypy itself (``reveal_type``) what it sees for every name in each package's ``__all__``.
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

mypy_api = pytest.importorskip("mypy.api")
# mypy reads the three packages: 10-15 s with a cold cache (under a second warm)
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("snapcore", "snapcore.select", "study_app", "analysis")

# The entry points a user calls first, and what each must return (mypy's full name of the
# return type). Independent of the code: these are the documented results of the stages.
ENTRY_POINTS = {
    "snapcore.load_scene": "snapcore.motion.scene.Scene",
    "snapcore.take_snapshot": "snapcore.pipeline.Snapshot",
    "snapcore.select_view": "snapcore.select.view.ViewSelection",
    "snapcore.select.select_view": "snapcore.select.view.ViewSelection",
    "snapcore.select_pose": "snapcore.select.pose_selection.PoseSelection",
    "snapcore.select.select_pose": "snapcore.select.pose_selection.PoseSelection",
    "snapcore.detect_interactions": "snapcore.select.contacts.Interactions",
    "snapcore.relief_from_scene": "snapcore.relief.height_field.Relief",
    # the answer record, not a bare dict (the participants schema's overload aside)
    "study_app.read_export": "list[TypedDict(study_app.data.answer.ResponseRow,",
}
# A parameter whose whole type is Any (``name: Any,`` or ``name: Any =``): an untyped one.
UNTYPED_PARAMETER = re.compile(r"\b(\w+): Any(?: =)?[,)]")


def _public_names() -> list[str]:
    names = []
    for package in PACKAGES:
        module = importlib.import_module(package)
        names += [f"{package}.{n}" for n in module.__all__ if not n.startswith("__")]
    return names


@pytest.fixture(scope="module")
def revealed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """Dotted public name → the type mypy reveals for it."""
    names = _public_names()
    snippet = tmp_path_factory.mktemp("types") / "snippet.py"
    lines = ["import snapcore", "import snapcore.select", "import study_app", "import analysis"]
    first = len(lines) + 1
    lines += [f"reveal_type({name})" for name in names]
    snippet.write_text("\n".join(lines) + "\n")
    # the project's own settings (pyproject.toml) and its cache, so a warm `make check`
    # makes this quick; errors inside the packages are `make check`'s business, not this
    # test's (silent), only the notes about the snippet are read
    stdout, stderr, _ = mypy_api.run(
        [
            "--config-file",
            str(ROOT / "pyproject.toml"),
            "--cache-dir",
            str(ROOT / ".mypy_cache"),
            "--follow-imports",
            "silent",
            str(snippet),
        ]
    )
    found = {}
    for match in re.finditer(r"snippet\.py:(\d+): note: Revealed type is \"(.*)\"", stdout):
        found[names[int(match.group(1)) - first]] = match.group(2)
    assert len(found) == len(names), stdout + stderr
    return found


@pytest.mark.parametrize("name", _public_names())
def test_public_name_is_typed(revealed: dict[str, str], name: str) -> None:
    """Every public name has its own type: not ``Any``, not the ``object`` of ``__getattr__``."""
    kind = revealed[name]
    assert kind != "Any", f"{name} is Any to a type checker"
    assert kind not in ("object", "builtins.object"), f"{name} falls through to __getattr__"


@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
def test_entry_point_returns_its_result_type(revealed: dict[str, str], name: str) -> None:
    """Calling an entry point gives its result type, so the result's fields are checked too."""
    assert f" -> {ENTRY_POINTS[name]}" in revealed[name], f"{name}: {revealed[name]}"


@pytest.mark.parametrize(
    "name",
    ["analysis.analyze", "analysis.load_responses", "study_app.Store", "study_app.write_export"],
)
def test_entry_point_parameters_are_typed(revealed: dict[str, str], name: str) -> None:
    """What a user passes to the analysis and the study's store and codec is typed: no
    parameter is plain ``Any`` (an untyped one), so a wrong argument is caught."""
    untyped = UNTYPED_PARAMETER.findall(revealed[name])
    assert not untyped, f"{name}: untyped {untyped} in {revealed[name]}"


def test_the_packages_still_import_their_names_on_first_use():
    """The types come from ``if TYPE_CHECKING:`` imports that never run: importing the
    packages still loads none of the modules behind their names (nor pandas)."""
    import subprocess
    import sys

    heavy = ["snapcore.pipeline", "snapcore.select.view", "study_app.data.store", "pandas"]
    code = (
        "import sys, snapcore, snapcore.select, study_app, analysis; "
        f"print([m for m in {heavy!r} if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
