"""snapcore: the algorithms of Action Snapshot.

Motion capture in, one informative pose and view out (plus renders and reliefs). The
public API is listed in ``__all__``; everything else is reachable through its module.
No Streamlit, no SQL here (DESIGN: data flows one way).
"""

from __future__ import annotations

from importlib import import_module

# The public names and the module each lives in. They are imported on first use
# (PEP 562), not here: `import snapcore.anything` runs this file, and importing every
# layer up front (trimesh, scipy, pyrender) cost seconds on every `snapshot` call,
# including a `snapshot batch` re-run that has nothing to do.
_WHERE = {
    "snapcore.errors": ("BVHError", "SceneError", "SchemaError", "SnapshotError"),
    "snapcore.motion.bvh": ("BVHDocument", "read_bvh", "write_bvh"),
    "snapcore.motion.load": ("data_dir", "load_scene"),
    "snapcore.motion.scene": ("Character", "Scene", "Skeleton"),
    "snapcore.pipeline": ("Snapshot", "ViewParams", "take_snapshot"),
    "snapcore.render.bodies": ("posed_mesh",),
    "snapcore.render.body": ("PosedMesh", "SceneBody"),
    "snapcore.render.composites": ("compare_views", "contact_sheet"),
    "snapcore.render.buffers": ("render_depth", "render_face_ids"),
    "snapcore.render.renderer": ("render_still",),
    "snapcore.render.video": ("render_video",),
    "snapcore.select.contacts": ("ContactTolerances", "Interactions", "detect_interactions"),
    "snapcore.select.methods": ("VIEW_METHODS", "ViewMethod"),
    "snapcore.select.pose": ("PoseEntropy", "PoseScores", "PoseSelection", "pose_entropy"),
    "snapcore.select.pose_methods": ("POSE_METHODS", "PoseParams", "select_pose"),
    "snapcore.select.view": ("ViewSelection", "pma_scores", "select_view"),
}
_MODULE_OF = {name: module for module, names in _WHERE.items() for name in names}


def __getattr__(name: str):
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module 'snapcore' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__():
    return sorted(__all__)


__version__ = "0.1.0"

__all__ = [
    "BVHDocument",
    "BVHError",
    "Character",
    "ContactTolerances",
    "Interactions",
    "PoseEntropy",
    "PoseScores",
    "PosedMesh",
    "POSE_METHODS",
    "PoseSelection",
    "Scene",
    "SceneBody",
    "SceneError",
    "SchemaError",
    "Skeleton",
    "Snapshot",
    "SnapshotError",
    "ViewMethod",
    "VIEW_METHODS",
    "PoseParams",
    "ViewParams",
    "ViewSelection",
    "compare_views",
    "contact_sheet",
    "data_dir",
    "detect_interactions",
    "load_scene",
    "pma_scores",
    "pose_entropy",
    "posed_mesh",
    "read_bvh",
    "render_depth",
    "render_face_ids",
    "render_still",
    "render_video",
    "select_pose",
    "select_view",
    "take_snapshot",
    "write_bvh",
    "__version__",
]
