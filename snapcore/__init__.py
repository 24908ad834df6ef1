"""snapcore: the algorithms of Action Snapshot.

Motion capture in, one informative pose and view out (plus renders and reliefs). The
public API is listed in ``__all__``; everything else is reachable through its module.
No Streamlit, no SQL here (DESIGN: data flows one way).
"""

from __future__ import annotations

from .bvh import BVHDocument, read_bvh, write_bvh
from .errors import BVHError, SceneError, SchemaError, SnapshotError
from .load import data_dir, load_scene
from .scene import Character, Scene, Skeleton

__version__ = "0.1.0"

__all__ = [
    "BVHDocument",
    "BVHError",
    "Character",
    "Scene",
    "SceneError",
    "SchemaError",
    "Skeleton",
    "SnapshotError",
    "data_dir",
    "load_scene",
    "read_bvh",
    "write_bvh",
    "__version__",
]
