"""Posing skinned bodies frame after frame: vertices and normals in blocks of frames.

A video asks for frame 0, then 1, 2...; skinning is a matrix product that costs less
per frame for 16 frames than for one (the weights are read once per block, the
product is larger), so a skinned body poses :data:`BLOCK` frames at once and serves the
following requests from that block. A frame asked for out of sequence (a still, a
thumbnail, the panels of a preview strip) is posed alone: a block there skinned 15
frames nobody drew (a batch scene's 13 pictures skinned 208 frames per body). Normals
are computed for the block the first time one of its frames needs them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from snapcore.motion.skinning import face_incidence, vertex_normals

if TYPE_CHECKING:
    from snapcore.motion.scene import Character

__all__ = ["FrameBlocks", "BLOCK"]

#: Frames posed together when one frame is asked for.
BLOCK = 16


class FrameBlocks:
    """Mixin for skinned bodies: ``vertices(frame)`` and ``normals(frame)`` from
    ``_pose(frames)`` (K, V, 3) of the subclass, which also sets ``faces``, ``character``
    and ``n_vertices``."""

    faces: np.ndarray  # (M, 3) vertex indices, set by the subclass
    character: Character  # set by the subclass
    _blk: tuple | None = None  # (first frame, vertices (K, V, 3), normals or None)
    _inc = None

    def _pose(self, frames: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def _incidence(self):
        if self._inc is None:
            self._inc = face_incidence(self.faces, self.n_vertices).astype(np.float32)
        return self._inc

    def _block(self, f: int):
        b = self._blk
        if b is None or not b[0] <= f < b[0] + len(b[1]):
            # a block only when the frames come in sequence: at most a block past the
            # end of the last one (a video, every frame or every few)
            end = b[0] + len(b[1]) if b is not None else None
            ahead = BLOCK if end is not None and end <= f < end + BLOCK else 1
            stop = min(f + ahead, self.character.n_frames)
            b = self._blk = (f, self._pose(np.arange(f, max(stop, f + 1))), None)
        return b

    def vertices(self, frame) -> np.ndarray:
        """World vertices (metres) at internal frame(s): (V, 3) or (K, V, 3)."""
        key = np.asarray(frame)
        if key.ndim == 0:
            b = self._block(int(key))
            return b[1][int(key) - b[0]]
        return self._pose(key)

    def normals(self, frame) -> np.ndarray:
        """World unit vertex normals at internal frame(s): (V, 3) or (K, V, 3)."""
        key = np.asarray(frame)
        if key.ndim == 0:
            b = self._block(int(key))
            if b[2] is None:
                b = self._blk = (b[0], b[1], vertex_normals(b[1], self.faces, self._incidence()))
            return b[2][int(key) - b[0]]
        return vertex_normals(self._pose(key), self.faces, self._incidence())
