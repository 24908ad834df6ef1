"""The public entry points of snapcore document themselves, and their examples run.

Every function in ``snapcore.__all__`` has numpydoc ``Parameters``, ``Returns`` and
``Examples`` sections, and the examples pass as doctests. They use the synthetic scenes
of :mod:`snapcore.motion.synth`, so they need no motion data.
"""

from __future__ import annotations

import doctest
import inspect

import pytest

import snapcore

# Names only (no import of the stages at collection): functions are lower-case.
ENTRY_POINTS = [n for n in snapcore.__all__ if n[0].islower() and not n.startswith("__")]
#: Entry points whose examples render with OpenGL (an EGL context each) or encode video.
RENDERING = {"render_still", "render_video", "contact_sheet", "compare_views"}


def test_the_public_api_is_stages_and_results():
    """Entry points and result types only; internals stay in their modules."""
    assert {
        "load_scene",
        "select_pose",
        "select_view",
        "take_snapshot",
        "relief_from_scene",
        "Relief",
        "Snapshot",
    } <= set(snapcore.__all__)
    for internal in ("render_face_ids", "PosedMesh", "SceneBody", "pma_scores"):
        assert internal not in snapcore.__all__
        with pytest.raises(AttributeError):
            getattr(snapcore, internal)
    for name in snapcore.__all__:
        assert getattr(snapcore, name) is not None


@pytest.mark.parametrize("name", ENTRY_POINTS)
def test_entry_point_docstring_and_examples(name):
    func = getattr(snapcore, name)
    doc = inspect.getdoc(func) or ""
    for section in ("Parameters", "Returns", "Examples"):
        assert f"\n{section}\n{'-' * len(section)}\n" in doc, f"{name}: no {section} section"
    module = inspect.getmodule(func)
    found = doctest.DocTestFinder(recurse=False).find(
        func, name, module=module, globs={"__name__": module.__name__}
    )
    assert sum(len(t.examples) for t in found) > 0, f"{name}: no examples"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report: list[str] = []
    for test in found:
        runner.run(test, out=report.append)
    assert runner.failures == 0, "".join(report)


#: Examples beyond the entry points: the parameter objects and the options table.
MORE_EXAMPLES = {
    "snapcore.select.pose_methods": ["PoseParams"],
    "snapcore.pipeline": ["snapshot_params"],
    "snapcore.select.view_methods": ["view_label"],
}


@pytest.mark.parametrize(
    "module,name", [(m, n) for m, names in MORE_EXAMPLES.items() for n in names]
)
def test_parameter_object_examples(module, name):
    """The parameter objects' examples (a wrong option combination failing at
    construction, a table split by field name) run as doctests too."""
    import importlib

    mod = importlib.import_module(module)
    found = doctest.DocTestFinder(recurse=False).find(
        getattr(mod, name), name, module=mod, globs={"__name__": module}
    )
    assert sum(len(t.examples) for t in found) > 0, f"{name}: no examples"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report: list[str] = []
    for test in found:
        runner.run(test, out=report.append)
    assert runner.failures == 0, "".join(report)
