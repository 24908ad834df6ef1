"""snapcore: the algorithms of Action Snapshot.

Motion capture in, one informative pose and view out (plus renders and reliefs). The
public API is listed in ``__all__``; everything else is reachable through its module.
No Streamlit, no SQL here (DESIGN: data flows one way).
"""

from __future__ import annotations

from snapcore.errors import BVHError, SceneError, SchemaError, SnapshotError
from snapcore.motion.bvh import BVHDocument, read_bvh, write_bvh
from snapcore.motion.load import data_dir, load_scene
from snapcore.motion.scene import Character, Scene, Skeleton
from snapcore.pipeline import Snapshot, ViewParams, take_snapshot
from snapcore.render.bodies import posed_mesh
from snapcore.render.body import PosedMesh, SceneBody
from snapcore.render.composites import compare_views, contact_sheet
from snapcore.render.renderer import render_depth, render_face_ids, render_still
from snapcore.render.video import render_video
from snapcore.select.contacts import ContactTolerances, Interactions, detect_interactions
from snapcore.select.methods import VIEW_METHODS, ViewMethod
from snapcore.select.pose import PoseEntropy, PoseSelection, pose_entropy, select_pose
from snapcore.select.view import ViewSelection, pma_scores, select_view

__version__ = "0.1.0"

__all__ = [
    "BVHDocument",
    "BVHError",
    "Character",
    "ContactTolerances",
    "Interactions",
    "PoseEntropy",
    "PosedMesh",
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
