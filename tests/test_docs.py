"""The documents keep their promises: a README a newcomer reads in ten minutes, links
that lead somewhere, and ARCHITECTURE.md stating the bounds the tests enforce."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: The README's length bound (issue 39: what it is, the two commands, the formats, one
#: example per user; the long read is in docs/).
README_MAX_LINES = 250


def test_readme_is_short():
    n = len(README.read_text().splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines; move long sections to docs/"


def test_readme_has_the_two_commands_and_one_example_per_user():
    text = README.read_text()
    assert "make study" in text and "make test" in text
    for user in ("participant", "researcher", "animator"):
        assert re.search(rf"^## The {user}$", text, re.M), user


def _links(md: Path) -> list[str]:
    text = md.read_text()
    found = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text) + re.findall(r'src="([^"]+)"', text)
    return [t for t in found if not re.match(r"[a-z]+://", t)]


def test_relative_links_of_the_readme_and_docs_lead_somewhere():
    broken = [
        f"{md.relative_to(ROOT)} → {target}"
        for md in [README, ROOT / "ARCHITECTURE.md", *sorted((ROOT / "docs").glob("*.md"))]
        for target in _links(md)
        if not (md.parent / target).exists()
    ]
    assert not broken, broken


def test_readme_layout_names_the_real_packages():
    """Every top-level package and subpackage of snapcore and study_app is in the
    README's Layout, and every name there with a slash is a real folder."""
    layout = README.read_text().split("## Layout", 1)[1]
    block = layout.split("```", 2)[1]
    for pkg in ("snapcore", "study_app", "analysis", "data_schema", "examples", "docs"):
        assert f"{pkg}/" in block, pkg
    for parent in ("snapcore", "study_app"):
        for sub in sorted(
            p.name for p in (ROOT / parent).iterdir() if (p / "__init__.py").exists()
        ):
            assert re.search(rf"\b{sub}/", block), f"{parent}/{sub}"
    for name in re.findall(r"^[ ]+(\w+)/", block, re.M):
        assert any((ROOT / top / name).is_dir() for top in ("snapcore", "study_app")), name


def test_architecture_states_the_module_bound_the_test_enforces():
    from test_architecture import MAX_LINES

    text = (ROOT / "ARCHITECTURE.md").read_text()
    bounds = {
        int(n.replace(",", "")) for n in re.findall(r"over ([\d,]+) (?:formatted )?lines", text)
    }
    assert bounds == {MAX_LINES}, bounds
