"""Selection: which frame and which view tell the story (pure array code, no rendering).

- :mod:`~snapcore.select.capsules` and :mod:`~snapcore.select.contacts` find interaction
  events (ground, other bodies, props);
- :mod:`~snapcore.select.pose_methods` runs a named pose selector, each returning a
  :class:`~snapcore.select.pose_selection.PoseSelection`: the default
  :mod:`~snapcore.select.story` (departure from the neutral stance of
  :mod:`~snapcore.select.stance`, novelty and debounced events, in bits), the paper's
  pose entropy (:mod:`~snapcore.select.paper`, §3.1) or a baseline
  (:mod:`~snapcore.select.pose_baselines`); every one reports a
  :class:`~snapcore.select.pose_selection.PoseScores`;
- :mod:`~snapcore.select.view` scores views (Projected Motion Area, paper §3.2, and the
  motion-area baseline) over the sample sphere of :mod:`~snapcore.select.sphere`;
- :mod:`~snapcore.select.view_methods` names the view methods the study compares.
"""

from importlib import import_module
from typing import TYPE_CHECKING

# Imported on first use (PEP 562): `snapcore.select.pose_selection` is needed by every command's
# option parsing, the view search's trimesh only by the commands that search views.
_WHERE = {
    "PoseSelection": "pose_selection",
    "select_pose": "pose_methods",
    "POSE_METHODS": "pose_methods",
    "VIEW_METHODS": "view_methods",
    "ViewMethod": "view_methods",
    "ViewSelection": "view",
    "select_view": "view",
}

# The type checker reads the same names from their modules (a PEP 562 `__getattr__`
# alone would make every public name `Any` to it); these lines never run.
if TYPE_CHECKING:
    from snapcore.select.pose_methods import POSE_METHODS, select_pose
    from snapcore.select.pose_selection import PoseSelection
    from snapcore.select.view import ViewSelection, select_view
    from snapcore.select.view_methods import VIEW_METHODS, ViewMethod

__all__ = [
    "POSE_METHODS",
    "PoseSelection",
    "VIEW_METHODS",
    "ViewMethod",
    "ViewSelection",
    "select_pose",
    "select_view",
]


def __getattr__(name: str) -> object:
    if name not in _WHERE:
        raise AttributeError(f"module 'snapcore.select' has no attribute {name!r}")
    value = getattr(import_module(f"snapcore.select.{_WHERE[name]}"), name)
    globals()[name] = value
    return value
