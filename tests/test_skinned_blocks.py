"""Skinned bodies pose frames in blocks only when the frames come in sequence (issue 41:
a batch scene's thumbnail and 12 preview panels skinned 16 frames each)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from snapcore.render.skinned import BLOCK, FrameBlocks


class _Counting(FrameBlocks):
    """A triangle in the XY plane moved to ``x = f`` at frame ``f`` (its normals +Z);
    counts the frames posed."""

    def __init__(self, n_frames=400, n_vertices=3):
        self.character = SimpleNamespace(n_frames=n_frames)
        self.n_vertices = n_vertices
        self.faces = np.array([[0, 1, 2]])
        self.posed = []

    def _pose(self, frames):
        self.posed.append(len(frames))
        tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
        return np.stack([tri + [f, 0, 0] for f in frames])


def test_frames_out_of_sequence_are_posed_alone():
    body = _Counting()
    for f in (120, 40, 300, 41 + 2 * BLOCK):  # a thumbnail and preview panels
        np.testing.assert_array_equal(body.vertices(f)[0, 0], f)
    assert body.posed == [1, 1, 1, 1]


def test_a_video_is_posed_in_blocks_every_frame_or_every_few():
    body = _Counting()
    for f in range(0, 100):
        np.testing.assert_array_equal(body.vertices(f)[0, 0], f)
    assert body.posed[0] == 1 and len(body.posed) <= 2 + 100 // BLOCK
    stepped = _Counting()
    for f in range(0, 200, 3):  # a 20 fps video of a 60 fps motion
        np.testing.assert_array_equal(stepped.vertices(f)[0, 0], f)
    assert len(stepped.posed) <= 2 + 200 // BLOCK
    np.testing.assert_array_equal(stepped.normals(198)[:, 2], 1.0)  # normals of the block
