"""Rendering: bodies, cameras and pictures of a scene (headless OpenGL through pyrender).

- :mod:`~snapcore.render.camera` frames a scene; :mod:`~snapcore.render.gl` owns the
  per-thread EGL renderer; :mod:`~snapcore.render.renderer` draws stills, depth and
  face-id buffers;
- :mod:`~snapcore.render.bodies` picks each character's body: the human mesh
  (:mod:`~snapcore.render.human`, data in :mod:`~snapcore.render.human_asset`) by default,
  a glTF character's own skinned mesh, or the capsule mannequin of
  :mod:`~snapcore.render.mannequin` (``--body mannequin``);
- :mod:`~snapcore.render.video` writes videos, :mod:`~snapcore.render.composites` contact
  sheets and view comparisons;
- :mod:`~snapcore.render.viewpoint_entropy` is the rendered view baseline;
- :mod:`~snapcore.render.entropy_plot` and :mod:`~snapcore.render.view_plot` are the
  diagnostic plots of the selection.
"""

from snapcore.render.buffers import render_depth, render_face_ids
from snapcore.render.renderer import render_still

__all__ = ["render_depth", "render_face_ids", "render_still"]
