"""Viewpoint entropy: hand-computed values on id images and on a cube, and the baseline."""

from __future__ import annotations

import math
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from snapcore import load_scene
from snapcore.render.viewpoint_entropy import (
    VE_RESOLUTION,
    EntropyError,
    select_view_entropy,
    viewpoint_entropy,
)


def h(*p):
    """-Σ p log2 p, by hand."""
    return -sum(x * math.log2(x) for x in p if x > 0)


def test_entropy_of_small_id_images():
    """Half background, two faces a quarter each: 1.5 bits; all distinct: log2(pixels)."""
    ids = np.zeros((4, 4), np.int32)
    ids[0, :] = 1
    ids[1, :] = 2
    assert viewpoint_entropy(ids, 2) == pytest.approx(0.5 + 2 * 0.25 * 2)  # = h(.5, .25, .25)
    distinct = np.arange(1, 17, dtype=np.int32).reshape(4, 4)
    assert viewpoint_entropy(distinct) == pytest.approx(4.0)
    assert viewpoint_entropy(np.zeros((3, 3), np.int64)) == 0.0  # empty view
    # several views at once give the same values as one at a time
    stack = np.stack([ids, distinct, np.zeros((4, 4), np.int32)])
    np.testing.assert_allclose(viewpoint_entropy(stack, 16), [1.5, 4.0, 0.0])


def test_entropy_rejects_bad_ids():
    with pytest.raises(EntropyError, match="integer"):
        viewpoint_entropy(np.zeros((2, 2)))
    with pytest.raises(EntropyError, match=">= 0"):
        viewpoint_entropy(-np.ones((2, 2), np.int32))
    with pytest.raises(EntropyError, match="n_faces"):
        viewpoint_entropy(np.full((2, 2), 5, np.int32), 3)


def unit_cube():
    """Unit cube centred at the origin, 12 triangles wound counter-clockwise outside."""
    v = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = []
    for a, b, c, d in quads:
        f += [(a, b, c), (a, c, d)]
    f = np.array(f)
    # orient outward: the normal must point away from the centre
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    flip = np.einsum("ij,ij->i", n, v[f].mean(axis=1)) < 0
    f[flip] = f[flip][:, ::-1]
    return v, f


# Orthographic framing of the bounding sphere (radius r = √3/2 for the unit cube): the
# image is (2r)² = 3 square units. Along an axis one face (1 unit², two equal
# triangles) shows; along a diagonal three faces of 1/√3 unit² each (six triangles).
AXIS = h(2 / 3, 1 / 6, 1 / 6)
DIAG_FACE = (1 / math.sqrt(3)) / 3
DIAG = h(1 - 3 * DIAG_FACE, *[DIAG_FACE / 2] * 6)


def test_cube_entropy_along_an_axis_and_a_diagonal():
    """Face-id renders of a cube match the hand-computed entropies (1.25 and 2.48 bits)."""
    render = pytest.importorskip("snapcore.render.buffers")
    v, f = unit_cube()
    views = np.array(
        [[0, 0, 1.0], [1.0, 0, 0], [1, 1, 1.0] / np.sqrt(3), [-1, 1, -1.0] / np.sqrt(3)]
    )
    ids = render.render_face_ids(v, f, views, resolution=512)
    got = viewpoint_entropy(ids, len(f))
    # pixel edges cost ~1 % of a face's pixels at 512²: a few hundredths of a bit
    np.testing.assert_allclose(got, [AXIS, AXIS, DIAG, DIAG], atol=0.02)
    assert AXIS == pytest.approx(1.2516, abs=1e-4) and DIAG == pytest.approx(2.4751, abs=1e-4)


def test_cube_baseline_picks_a_corner_view():
    """Over 162 views the cube's entropy peaks where three faces show (near a diagonal)."""
    pytest.importorskip("snapcore.render.renderer")
    v, f = unit_cube()
    sel = select_view_entropy(None, 0, mesh=SimpleNamespace(vertices=v, faces=f))
    assert np.all(np.abs(sel.view) > 0.35)  # all three face normals are seen
    assert sel.score > AXIS + 0.9
    assert sel.resolution == VE_RESOLUTION and sel.n_faces == 12
    assert sel.visible_faces.max() == 6
    # views more than 10° below the horizon were not rendered
    low = sel.views[:, 1] < -math.sin(math.radians(10)) - 1e-9
    assert np.all(np.isnan(sel.scores[low])) and np.all(np.isfinite(sel.scores[~low]))
    full = select_view_entropy(
        None, 0, mesh=SimpleNamespace(vertices=v, faces=f), min_elevation_deg=None
    )
    assert np.all(np.isfinite(full.scores)) and full.score >= sel.score


def test_body_baseline_on_a_real_clip(motions_dir):
    """The posed body of a walk: a finite best view, more faces seen than a face-on view of
    a cube, entropy within [0, log2(pixels)]."""
    pytest.importorskip("snapcore.render.mannequin")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(motions_dir / "walk_run/02_01.bvh")
    sel = select_view_entropy(scene, 100)
    ok = np.isfinite(sel.scores)
    assert 0 < sel.score <= 2 * math.log2(VE_RESOLUTION)
    assert sel.score == np.nanmax(sel.scores) and np.linalg.norm(sel.view) == pytest.approx(1.0)
    assert sel.visible_faces[ok].min() > 50 and sel.n_faces > 1000
    with pytest.raises(EntropyError, match="outside"):
        select_view_entropy(scene, scene.n_frames)
