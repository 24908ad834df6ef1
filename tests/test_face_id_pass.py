"""The fast face-id pass gives the former pass's ids at every pixel (issue 41).

``snapcore.render.buffers.render_face_ids`` lays the mesh out differently (each face's
id on its provoking vertex, not ``gl_PrimitiveID``) and may skip faces it can prove
invisible; none of that may change a single id. The reference is the former pass
(``tests/face_id_reference.py``): one indexed draw per view of the mesh as given.
The meshes are chosen where a difference would show: two bodies pressed together
(surfaces crossing), exact depth ties (the first face drawn must win), and a soup of
random triangles of every size and slant, slivers and edge-on faces included.
"""

from __future__ import annotations

import threading
import warnings

import numpy as np
import pytest
import trimesh
from face_id_reference import reference_face_ids

from snapcore.render import buffers
from snapcore.render.buffers import render_face_ids
from snapcore.select.view import view_sphere

pytestmark = pytest.mark.slow


def _soup(n, seed):
    """``n`` random triangles in the unit box: sizes from 1e-4 to 0.5, a tenth of them
    nearly edge-on to a sample view, some degenerate (a repeated corner)."""
    rng = np.random.default_rng(seed)
    centre = rng.uniform(-1, 1, (n, 1, 3))
    size = 10 ** rng.uniform(-4, -0.3, (n, 1, 1))
    tri = centre + size * rng.normal(size=(n, 3, 3))
    views = view_sphere(42)
    slanted = rng.choice(n, n // 10, replace=False)
    for k in slanted:  # flatten the triangle along a view direction: edge-on there
        d = views[rng.integers(len(views))]
        tri[k] -= np.outer(tri[k] @ d - tri[k].mean(0) @ d, d) * (1 - 10 ** rng.uniform(-7, -2))
    tri[:5, 2] = tri[:5, 1]  # degenerate: zero area
    return tri.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3)


def test_random_triangles_of_every_size_and_slant():
    v, f = _soup(3000, seed=41)
    views = view_sphere(42)
    for res in (97, 256):
        got = render_face_ids(v, f, views, resolution=res)
        want = reference_face_ids(v, f, views, res)
        assert (want > 0).sum() > 0.2 * want.size
        np.testing.assert_array_equal(got, want)


def test_exact_depth_ties_go_to_the_face_drawn_first():
    """A sphere stored twice (same vertices, the copy's faces after the original's):
    every depth test is a tie, which GL_LESS gives to the face drawn first, the
    original. Any change of draw order shows as ids of the copy."""
    m = trimesh.creation.icosphere(subdivisions=3)
    n = len(m.faces)
    faces = np.vstack([m.faces, m.faces])
    views = view_sphere(42)
    got = render_face_ids(m.vertices, faces, views, resolution=64)
    assert got.max() <= n and got.max() > 0
    np.testing.assert_array_equal(got, reference_face_ids(m.vertices, faces, views, 64))


def test_two_human_bodies_in_a_hold_at_the_bench_frame(motions_dir):
    """The bench's mesh: the salsa pair's human bodies at frame 900 (2 x 26,756 faces,
    touching), all 162 views of the viewpoint-entropy baseline at 256²."""
    from snapcore.motion.load import load_scene
    from snapcore.render.bodies import posed_mesh

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(
            [
                motions_dir / "two_person/60_01_scaled.bvh",
                motions_dir / "two_person/61_01_scaled.bvh",
            ],
            fps=60,
        )
    m = posed_mesh(scene, 900, kind="human")
    views = view_sphere(162)
    got = render_face_ids(m.vertices, m.faces, views, resolution=256)
    if buffers._ID_THREADS > 1:  # a helper thread (its own GL context) drew some views
        assert any(t.name.startswith("snapcore-ids") for t in threading.enumerate())
    np.testing.assert_array_equal(got, reference_face_ids(m.vertices, m.faces, views, 256))


def test_blocks_hand_over_every_view_once_as_read_back():
    """face_id_blocks (the entropy's way, views split between threads) delivers each
    view's ids exactly once, rows bottom-up: render_face_ids flipped."""
    v, f = _soup(2000, seed=7)
    views = view_sphere(42)
    seen = np.zeros(len(views), int)
    got = np.full((len(views), 64, 64), -1, np.int32)

    def take(first, ids):
        seen[first : first + len(ids)] += 1
        got[first : first + len(ids)] = ids

    buffers.face_id_blocks(v, f, views, take, resolution=64)
    assert np.all(seen == 1)
    np.testing.assert_array_equal(got, render_face_ids(v, f, views, resolution=64)[:, ::-1])
