"""Constants in one home each, and the pose method checked and dispatched in one place."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _number_literals(path: Path, value: float) -> list[int]:
    """Lines of ``path`` where the number ``value`` is written out."""
    tree = ast.parse(path.read_text())
    return [
        n.lineno
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant)
        and isinstance(n.value, float)
        and abs(n.value - value) < 1e-12
    ]


def test_the_reference_stature_is_written_once():
    """1.70 m lives in snapcore.motion.anatomy (REFERENCE_STATURE_M); no other module of
    snapcore types it out (pose_baselines once did, beside the named constant)."""
    from snapcore.motion.anatomy import REFERENCE_STATURE_M

    assert REFERENCE_STATURE_M == 1.70
    found = {
        str(p.relative_to(ROOT)): lines
        for p in sorted((ROOT / "snapcore").rglob("*.py"))
        if (lines := _number_literals(p, 1.70))
    }
    assert found == {"snapcore/motion/anatomy.py": found.get("snapcore/motion/anatomy.py")}
    assert len(found["snapcore/motion/anatomy.py"]) == 1


def test_a_character_without_height_is_measured_at_the_reference_stature():
    from types import SimpleNamespace

    from snapcore.motion.anatomy import REFERENCE_STATURE_M, stature_of

    assert stature_of(SimpleNamespace(height=1.62)) == 1.62
    for h in (0.0, -1.0, float("nan"), float("inf")):
        assert stature_of(SimpleNamespace(height=h)) == REFERENCE_STATURE_M


def test_the_watched_enough_bar_is_the_study_s_own():
    """The analysis counts a pose answer as watched by the bar the study enforced."""
    import analysis.load
    import study_app.session
    import study_app.session.events

    assert analysis.load.WATCHED_ENOUGH is study_app.session.events.WATCHED_ENOUGH
    assert study_app.session.WATCHED_ENOUGH is study_app.session.events.WATCHED_ENOUGH
    assert _number_literals(ROOT / "analysis" / "load.py", 0.9) == []


def test_the_minimum_separation_has_one_default():
    from snapcore.select.pose_methods import PoseParams, run_pose_method, select_pose
    from snapcore.select.pose_selection import MIN_SEPARATION_S

    for f in (select_pose, run_pose_method):
        assert f.__kwdefaults__["min_separation_s"] == MIN_SEPARATION_S
    assert PoseParams().min_separation_s == MIN_SEPARATION_S


@pytest.fixture(scope="module")
def kick():
    from snapcore.motion.synth import synth_scene

    return synth_scene("kick")


def test_one_table_of_pose_methods(kick):
    """Every method in the table runs through select_pose with the options PoseParams
    gives it, and reports itself; an unknown method is one SelectionError."""
    from snapcore.errors import SelectionError
    from snapcore.select.pose_methods import METHOD_OPTIONS, POSE_METHODS, PoseParams, select_pose

    assert tuple(METHOD_OPTIONS) == POSE_METHODS and POSE_METHODS[0] == "story"
    for m in POSE_METHODS:
        kwargs = PoseParams(pose_method=m, k=2).kwargs()
        assert set(kwargs) - {"method", "k", "min_separation_s"} <= set(METHOD_OPTIONS[m])
        sel = select_pose(kick, **kwargs)
        assert sel.method == m and len(sel.indices) == 2
    with pytest.raises(SelectionError, match="method must be one of story, paper"):
        select_pose(kick, method="nope")
    with pytest.raises(SelectionError, match="must be one of story, stretch"):
        from snapcore.select.pose_methods import run_pose_method

        run_pose_method(kick, "paper")
