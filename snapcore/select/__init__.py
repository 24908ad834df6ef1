"""Selection: which frame and which view tell the story (pure array code, no rendering).

- :mod:`~snapcore.select.capsules` and :mod:`~snapcore.select.contacts` find interaction
  events (ground, other bodies, props);
- :mod:`~snapcore.select.pose` scores frames (pose entropy, paper §3.1);
- :mod:`~snapcore.select.view` scores views (Projected Motion Area, paper §3.2, and the
  motion-area baseline) over the sample sphere of :mod:`~snapcore.select.sphere`;
- :mod:`~snapcore.select.methods` names the view methods the study compares.
"""

from snapcore.select.methods import VIEW_METHODS, ViewMethod
from snapcore.select.pose import PoseSelection
from snapcore.select.pose_methods import POSE_METHODS, select_pose
from snapcore.select.view import ViewSelection, select_view

__all__ = ["POSE_METHODS", "PoseSelection", "VIEW_METHODS", "ViewMethod", "ViewSelection", "select_pose",
           "select_view"]
