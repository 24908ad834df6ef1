"""snapcore: the algorithms of Action Snapshot.

Motion capture in, one informative pose and view out (plus renders and reliefs). The
public API is listed in ``__all__``; everything else is reachable through its module.
No Streamlit, no SQL here (DESIGN: data flows one way).
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

# The public API: the stages of the pipeline (load, interactions, pose, view, the whole
# snapshot, renders, relief), their parameter objects and their result types. Everything
# else (BVH I/O, body meshes, buffers, scores) is imported from its module.
# The names are imported on first use (PEP 562), not here: `import snapcore.anything`
# runs this file, and importing every layer up front (trimesh, scipy, pyrender) cost
# seconds on every `snapshot` call, including a `snapshot batch` re-run that has
# nothing to do.
_WHERE = {
    "snapcore.errors": ("BVHError", "SceneError", "SnapshotError"),
    "snapcore.motion.load": ("load_scene",),
    "snapcore.motion.scene": ("Character", "Scene", "Skeleton"),
    "snapcore.select.contacts": ("ContactParams", "Interactions", "detect_interactions"),
    "snapcore.select.pose_selection": ("PoseScores", "PoseSelection"),
    "snapcore.select.pose_methods": ("PoseParams", "select_pose"),
    "snapcore.select.view": ("ViewSelection", "select_view"),
    "snapcore.pipeline": ("Snapshot", "ViewParams", "take_snapshot"),
    "snapcore.render.renderer": ("render_still",),
    "snapcore.render.video": ("render_video",),
    "snapcore.render.composites": ("compare_views", "contact_sheet"),
    "snapcore.relief.height_field": ("Relief", "ReliefParams"),
    "snapcore.relief.scene": ("relief_from_scene",),
}
_MODULE_OF = {name: module for module, names in _WHERE.items() for name in names}

# The type checker reads the same names from their modules (a PEP 562 `__getattr__`
# alone would make every public name `Any` to it); these lines never run.
if TYPE_CHECKING:
    from snapcore.errors import BVHError, SceneError, SnapshotError
    from snapcore.motion.load import load_scene
    from snapcore.motion.scene import Character, Scene, Skeleton
    from snapcore.pipeline import Snapshot, ViewParams, take_snapshot
    from snapcore.relief.height_field import Relief, ReliefParams
    from snapcore.relief.scene import relief_from_scene
    from snapcore.render.composites import compare_views, contact_sheet
    from snapcore.render.renderer import render_still
    from snapcore.render.video import render_video
    from snapcore.select.contacts import ContactParams, Interactions, detect_interactions
    from snapcore.select.pose_methods import PoseParams, select_pose
    from snapcore.select.pose_selection import PoseScores, PoseSelection
    from snapcore.select.view import ViewSelection, select_view


def __getattr__(name: str) -> object:
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module 'snapcore' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


__version__ = "0.1.0"

__all__ = [
    # stages, in pipeline order
    "load_scene",
    "detect_interactions",
    "select_pose",
    "select_view",
    "take_snapshot",
    "render_still",
    "render_video",
    "contact_sheet",
    "compare_views",
    "relief_from_scene",
    # their parameters
    "ContactParams",
    "PoseParams",
    "ViewParams",
    "ReliefParams",
    # their results
    "Scene",
    "Character",
    "Skeleton",
    "Interactions",
    "PoseSelection",
    "PoseScores",
    "ViewSelection",
    "Snapshot",
    "Relief",
    # errors (every one a SnapshotError)
    "SnapshotError",
    "SceneError",
    "BVHError",
    "__version__",
]
