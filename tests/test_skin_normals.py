"""Vertex normals of a block of frames (:func:`snapcore.motion.skinning.vertex_normals`):
each frame's normals are its own, whatever the others in the block."""

from __future__ import annotations

import numpy as np


def _rotation(axis, angle):
    """Rotation matrix (3, 3) about a unit ``axis`` by ``angle`` radians (Rodrigues)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def test_a_rotated_cube_in_a_block_has_its_corners_normals_rotated():
    """In a block of differently rotated and moved cubes, frame k's normals are the
    unmoved cube's normals (summed face by face here: each face's edge cross product,
    twice its area along its normal, added to its three corners) rotated by frame k's
    rotation, in float32 and float64; each frame's alone are those of the block."""
    import trimesh

    from snapcore.motion.skinning import face_incidence, vertex_normals

    box = trimesh.creation.box((2.0, 2.0, 2.0))
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    rots = [_rotation(ax, a) for ax, a in (((0, 0, 1), 0.0), ((1, 2, 3), 0.7), ((3, -1, 0), 2.1))]
    block = np.stack([v @ r.T + [0.5, -1.0, 2.0] for r in rots])
    rest = np.zeros_like(v)
    for tri in f:
        a, b, c = v[tri]
        rest[tri] += np.cross(b - a, c - a)
    rest /= np.linalg.norm(rest, axis=1, keepdims=True)
    assert np.all(np.sum(rest * v, axis=1) > 0.5)  # outward, not on a face's plane
    want = np.stack([rest @ r.T for r in rots])
    for dtype, tol in ((np.float64, 1e-12), (np.float32, 1e-6)):
        inc = face_incidence(f, len(v)).astype(dtype)  # as posed bodies pass it
        got = vertex_normals(block.astype(dtype), f, inc)
        assert got.shape == block.shape and got.dtype == dtype
        np.testing.assert_allclose(got, want, atol=tol)
        for k in range(len(rots)):  # the same alone as in the block
            np.testing.assert_array_equal(vertex_normals(block[k].astype(dtype), f, inc), got[k])
