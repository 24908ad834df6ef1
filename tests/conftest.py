"""Shared fixtures: where the real motion data is, and headless rendering setup.

Tests that need ``../shared/motions`` skip with a reason when it is absent, and fail
in CI (``CI=true``), where the data is always beside the checkout.
"""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")  # before anything imports OpenGL

import pytest  # noqa: E402

# PostgreSQL for the store tests: one throw-away server per test worker, shared by every
# module that asks for it (imported into each module, it was one server per module)
from pg import pg_server, pg_url  # noqa: E402, F401 - fixtures, requested by name

from snapcore.motion.load import data_dir  # noqa: E402

IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


class lazy_module:  # noqa: N801 - stands for a module
    """The module ``name``, imported on its first attribute access instead of here.

    A test file names the modules it tests at its top (``fr = lazy_module("analysis.frames")``
    for ``from analysis import frames as fr``); collecting it, which every xdist worker
    does for every file, then costs nothing, where pandas, scipy.stats and the study store
    cost seconds.
    """

    def __init__(self, name: str):
        self.__name = name

    def __getattr__(self, attr: str):
        import importlib

        if attr.startswith("_mock") or (attr.startswith("__") and attr.endswith("__")):
            # what collection asks of every attribute of a test file (__test__, _mock_name,
            # ...): not about the module, so no reason to import it
            raise AttributeError(attr)
        return getattr(importlib.import_module(self.__name), attr)


def need(condition: bool, reason: str) -> None:
    """Skip (locally) or fail (in CI) when a test's precondition is missing."""
    if not condition:
        if IN_CI:
            pytest.fail(f"required in CI: {reason}")
        pytest.skip(reason)


def shared_scene(motions_dir, files, fps: float = 60):
    """The scene of ``files`` (one clip, or the clips of one scene) under
    ``motions_dir``, at ``fps``; skipped when the shared data lacks them. Unit fitting
    and header warnings are silenced: the tests that use it are not about them."""
    import warnings

    from snapcore.motion.load import load_scene

    paths = [motions_dir / f for f in files]
    if not all(p.exists() for p in paths):
        pytest.skip(f"{files} not in the shared data")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_scene(paths if len(paths) > 1 else paths[0], fps=fps)


@pytest.fixture(scope="session")
def motions_dir():
    """The real motion-capture folder (``SNAPSHOT_DATA`` or ``../shared/motions``)."""
    d = data_dir()
    need(
        d is not None, "no motion data: set SNAPSHOT_DATA or put ../shared/motions beside the repo"
    )
    return d


@pytest.fixture(scope="session")
def all_bvh(motions_dir):
    """Every BVH file under the data folder, sorted."""
    files = sorted(motions_dir.rglob("*.bvh"))
    need(len(files) > 0, f"no BVH files under {motions_dir}")
    return files


#: The fixtures that start PostgreSQL (tests/pg.py): a test that asks for one by name
#: carries the ``postgres`` mark, so ``-m "not postgres"`` never starts the server. (A
#: fixture that asks for one inside, with ``request.getfixturevalue``, marks its
#: PostgreSQL parameter itself: ``pytest.param("postgresql", marks=pytest.mark.postgres)``.)
PG_FIXTURES = ("pg_server", "pg_url")


@pytest.hookimpl(tryfirst=True)  # before -m deselects
def pytest_collection_modifyitems(config, items):
    for item in items:
        if any(f in getattr(item, "fixturenames", ()) for f in PG_FIXTURES):
            item.add_marker(pytest.mark.postgres)


#: Tests slower than this (seconds, setup + call + teardown) carry the ``slow`` mark;
#: the end of every run lists those that do not, so the mark keeps up with the suite.
SLOW_S = 10.0
_unmarked_slow: dict[str, float] = {}


def pytest_runtest_logreport(report):
    # with xdist this runs in the controller too, for the workers' reports
    if "slow" in report.keywords:
        return
    _unmarked_slow[report.nodeid] = _unmarked_slow.get(report.nodeid, 0.0) + report.duration


def pytest_terminal_summary(terminalreporter):
    slow = sorted(((d, n) for n, d in _unmarked_slow.items() if d > SLOW_S), reverse=True)
    if slow:
        terminalreporter.section(f"tests over {SLOW_S:g} s without the slow mark")
        for d, n in slow:
            terminalreporter.write_line(f"{d:6.1f} s  {n}")
