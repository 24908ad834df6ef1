"""The marks keep their promise: ``pytest -m "not postgres"`` runs no test that starts
PostgreSQL (the fixtures of ``tests/pg.py``)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent


@pytest.mark.slow
def test_not_postgres_selects_no_test_that_starts_the_server():
    """Every test file that asks for the server is collected with ``-m "not postgres"``:
    what is left asks for no PostgreSQL fixture and has no PostgreSQL parameter."""
    users = sorted(
        f"tests/{p.name}"
        for p in TESTS.glob("test_*.py")
        if p.name != Path(__file__).name and re.search(r"\bpg_(server|url)\b", p.read_text())
    )
    assert {"tests/test_researcher_data.py", "tests/test_e2e_researcher.py"} <= set(users)
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "--collect-only",
            "-q",
            "-p",
            "no:xdist",
            "-m",
            "not postgres",
            *users,
        ],
        cwd=TESTS.parent,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    selected = [ln for ln in r.stdout.splitlines() if "::" in ln]
    assert selected  # the files' other tests are still there
    starts = [t for t in selected if re.search(r"[\[-]postgresql[\]-]|pg_url|pg_server", t)]
    assert not starts, starts
    # and the tests that ask for a server by name are the ones deselected
    named = [t for t in selected if "empty_postgresql_database" in t]
    assert not named, named
