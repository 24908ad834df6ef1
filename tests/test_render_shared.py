"""What the renderers of one scene share, and the per-picture costs a batch scene avoids
(issue 41: a library scene's thumbnail and 13 preview cameras)."""

from __future__ import annotations

import io
import os
import zlib

import numpy as np
import pytest

from snapcore.motion import synth
from snapcore.render.mannequin import TESSELLATION_COARSE, SceneBody
from snapcore.render.renderer import SceneRenderer

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def walk():
    return synth.synth_scene("walk", fps=30)


def test_renderers_of_one_scene_share_its_coarse_shadow_mannequins(walk):
    human = SceneRenderer(walk, size=(64, 72), body="human")
    mannequin = SceneRenderer(walk, size=(64, 72), body="mannequin")
    a, b = human._shadow_body, mannequin._shadow_body
    assert all(p is q for p, q in zip(a.characters, b.characters, strict=True))
    # the shared pieces cast the shadow a coarse mannequin built afresh casts
    fresh = SceneBody(walk, tessellation=TESSELLATION_COARSE)
    np.testing.assert_array_equal(a.vertices(7), fresh.vertices(7))
    np.testing.assert_array_equal(a.faces, fresh.faces)
    # another scene object gets its own
    other = synth.synth_scene("walk", fps=30)
    c = SceneRenderer(other, size=(64, 72), body="mannequin")._shadow_body
    assert c.characters[0] is not a.characters[0]
    assert c.characters[0].character is other.characters[0]


def test_mannequins_of_two_tessellations_measure_their_pieces_once(monkeypatch):
    """A batch scene draws the mannequin (strip) and casts shadows with a coarse one
    (thumbnail and strip): both are the same pieces, measured from the motion once per
    character; tessellated from them, each is the body built on a fresh scene."""
    import snapcore.render.mannequin as mannequin
    from snapcore.render.mannequin import TESSELLATION

    calls = []
    measure = mannequin.CharacterBody._measure_pieces
    monkeypatch.setattr(
        mannequin.CharacterBody,
        "_measure_pieces",
        lambda self, base: calls.append(1) or measure(self, base),
    )
    scene = synth.synth_scene("jump", fps=30)
    coarse = SceneBody(scene, tessellation=TESSELLATION_COARSE)
    fine = SceneBody(scene, tessellation=TESSELLATION)
    assert len(calls) == 1
    assert fine.n_faces > 2 * coarse.n_faces
    for tess, body in ((TESSELLATION, fine), (TESSELLATION_COARSE, coarse)):
        alone = SceneBody(synth.synth_scene("jump", fps=30), tessellation=tess)
        np.testing.assert_array_equal(body.vertices(9), alone.vertices(9))
        np.testing.assert_array_equal(body.normals(9), alone.normals(9))
        np.testing.assert_array_equal(body.faces, alone.faces)
        np.testing.assert_array_equal(body.face_colors, alone.face_colors)
        assert body.characters[0].pieces == alone.characters[0].pieces
    assert len(calls) == 3


def test_the_drawn_coarse_mannequin_is_the_shadows_one(walk):
    """A batch strip draws the coarse mannequin its shadows are cast with: one build."""
    from snapcore.render.bodies import scene_body
    from snapcore.render.mannequin import scene_body as mannequin_scene_body

    drawn = scene_body(walk, TESSELLATION_COARSE, kind="mannequin")
    shadows = mannequin_scene_body(walk, TESSELLATION_COARSE)
    assert all(p is q for p, q in zip(drawn.characters, shadows.characters, strict=True))
    np.testing.assert_array_equal(drawn.faces, shadows.faces)
    np.testing.assert_array_equal(drawn.face_colors, shadows.face_colors)


@pytest.mark.skipif(
    os.environ.get("PYOPENGL_PLATFORM") != "egl", reason="the bare context is EGL's"
)
def test_the_bare_context_is_made_current_only_when_it_is_not(walk, monkeypatch):
    import ctypes

    from OpenGL import EGL as egl

    from snapcore.render.gl import bare_gl_context
    from snapcore.render.renderer import render_still

    ctx = bare_gl_context()
    calls = []
    make_current = egl.eglMakeCurrent

    def counted(*args):
        calls.append(args)
        return make_current(*args)

    monkeypatch.setattr(egl, "eglMakeCurrent", counted)
    image = render_still(walk, 3, size=(64, 72), body="mannequin")
    assert image.std() > 0
    # every draw and read-back asks for the context: none of them re-binds it
    assert calls == []
    # another context current (here none): asking makes the bare one current again
    make_current(ctx._display, egl.EGL_NO_SURFACE, egl.EGL_NO_SURFACE, egl.EGL_NO_CONTEXT)
    assert bare_gl_context() is ctx
    assert len(calls) == 1
    current = ctypes.cast(egl.eglGetCurrentContext(), ctypes.c_void_p).value
    assert current == ctypes.cast(ctx._context, ctypes.c_void_p).value
    np.testing.assert_array_equal(render_still(walk, 3, size=(64, 72), body="mannequin"), image)


def test_batch_pictures_are_lossless_pngs_at_a_fast_zlib_level():
    from PIL import Image

    from snapcore.batch.task import _png

    rng = np.random.default_rng(0)
    image = np.repeat(rng.integers(0, 256, (40, 30, 3), dtype=np.uint8), 3, axis=1)
    data = _png(image)
    np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(data))), image)
    # the IDAT stream's zlib header: FLEVEL (bits 6-7 of its second byte) is 1 for
    # levels 2-5 ("fast"), 2 for the default 6
    at = data.index(b"IDAT") + 4
    assert (data[at + 1] >> 6) == 1
    assert zlib.decompress(data[at : at + int.from_bytes(data[at - 8 : at - 4], "big")])


def test_common_orthographic_cameras_are_the_fits_at_the_common_scale():
    """The panels' cameras at one scale are each panel's fit with ``half_height`` forced
    to the largest (as fit_camera makes them), field for field: only their half-height
    is set, the fits are not made twice."""
    from snapcore.render.camera import fit_camera
    from snapcore.render.composites import common_cameras

    rng = np.random.default_rng(0)
    for _ in range(100):
        pts = [
            rng.normal(size=(50, 3)) * rng.uniform(0.1, 3) + rng.normal(size=3) * 5
            for _ in range(4)
        ]
        views = [rng.normal(size=3) for _ in range(4)]
        size = (int(rng.integers(20, 400)), int(rng.integers(20, 400)))
        hh = max(fit_camera(p, v, size=size).half_height for p, v in zip(pts, views))
        for got, want in zip(
            common_cameras(pts, views, size=size),
            [fit_camera(p, v, size=size, half_height=hh) for p, v in zip(pts, views)],
        ):
            for name in ("position", "right", "up", "back"):
                np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
            for name in ("size", "projection", "half_height", "yfov", "znear", "zfar"):
                assert getattr(got, name) == getattr(want, name)
                assert type(getattr(got, name)) is type(getattr(want, name))


def test_renderers_of_human_bodies_share_their_vertex_colours():
    """Every scene's human body has the same colours (read-only, shared): the
    renderers' per-vertex colours are computed once, and equal a fresh computation."""
    import snapcore.render.renderer as renderer

    a = SceneRenderer(synth.synth_scene("walk"), size=(64, 72), body="human")
    b = SceneRenderer(synth.synth_scene("kick", seed=2), size=(64, 72), body="human")
    kept = a._vertex_colors(0)
    assert kept is b._vertex_colors(0)
    renderer._VERTEX_COLOURS.clear()
    fresh = b._vertex_colors(0)
    assert fresh is not kept
    np.testing.assert_array_equal(fresh, kept)
    np.testing.assert_array_equal(fresh, a._vcols)
