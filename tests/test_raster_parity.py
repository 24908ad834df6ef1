"""The raw-GL scene renderer (:mod:`snapcore.render.raster`, issue 41) against pyrender.

``SceneRenderer`` draws with its own GL calls since issue 41 (no pyrender import on
``snapshot render``'s path). The reference (tests/render_reference.py) draws the same
meshes, lights and camera through pyrender as the renderer did before. Both use the
same shaders, uniforms and GL state on the same llvmpipe, so the tolerance is tight:
every pixel identical but at most :data:`MAX_CHANGED` per picture. Those few are exact
depth ties (a foot on the shadow's plane): which mesh wins one depends on the draw
order, and pyrender draws its meshes in the iteration order of a Python set, which
changes from run to run (measured: 0 differing pixels in most runs, 1 in some). Face-id and depth buffers are
not drawn by this renderer (:mod:`snapcore.render.buffers`), so they are unchanged.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from render_reference import pyrender_picture

from snapcore.render.camera import fit_camera
from snapcore.render.renderer import SceneRenderer
from tests.conftest import shared_scene

pytestmark = pytest.mark.slow

#: Pixels that may differ per picture (exact depth ties, see above).
MAX_CHANGED = 4

SCENES = {
    "salsa pair": (["two_person/60_01_scaled.bvh", "two_person/61_01_scaled.bvh"], 900),
    "dance 05_06": (["dance/05_06.bvh"], 400),
    "boxing": (["boxing_jump/Boxing_Toes.bvh"], 1500),
}
#: Views (from the scene to the camera), projections and floor styles: from above, level,
#: from below the floor (no grid or shadows), perspective, the "horizon" floor.
VIEWS = [
    ([0.6, 0.45, 1.0], "orthographic", "auto"),
    ([1.0, 0.02, 0.2], "orthographic", "auto"),
    ([-0.5, -0.4, -1.0], "orthographic", "auto"),
    ([0.3, 0.35, -1.0], "perspective", "auto"),
    ([-1.0, 0.25, 0.4], "orthographic", "horizon"),
]


def _load(motions_dir, files):
    return shared_scene(motions_dir, files)


def _agree(ours, ref):
    assert ours.shape == ref.shape and ours.dtype == ref.dtype == np.uint8
    diff = np.abs(ours.astype(int) - ref.astype(int)).max(axis=-1)
    assert np.count_nonzero(diff) <= MAX_CHANGED, np.sort(diff.ravel())[-10:]


@pytest.mark.parametrize("name", list(SCENES))
def test_stills_agree_with_pyrender(name, motions_dir):
    files, frame = SCENES[name]
    scene = _load(motions_dir, files)
    index = min(frame, scene.n_frames - 1)
    for view, projection, floor in VIEWS:
        sr = SceneRenderer(scene, size=(480, 270), floor=floor)
        cam = fit_camera(sr.body.vertices(index), view, size=sr.size, projection=projection)
        ours = sr.render(index, cam)
        ref = pyrender_picture(sr, cam, sr._full_camera())
        # the pictures show bodies, floor and (but from below) the sky or grid
        assert len(np.unique(ours.reshape(-1, 3), axis=0)) > 50
        _agree(ours, ref)


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_frames_drawn_in_their_rectangle_agree_with_pyrender(projection, motions_dir):
    """Frames after the first with one camera (a video's, or ``crop=True``) draw only
    their bodies' rectangle (a scissor) into a copy of the background: still the full
    picture, pixel for pixel, as pyrender draws it whole."""
    from snapcore.render.camera import motion_points

    files, frame = SCENES["salsa pair"]
    scene = _load(motions_dir, files)
    sr = SceneRenderer(scene, size=(640, 360))
    view = [0.6, 0.45, 1.0]
    cam = fit_camera(motion_points(scene, body=sr.body), view, size=sr.size, projection=projection)
    for i, index in enumerate((frame, frame + 40, frame + 80)):
        ours = sr.render(index, cam, crop=i == 1)
        drawn = [sr.body.vertices(index), sr.draw_list()[-1].positions]
        window = sr._crop_window(cam, drawn)
        assert window is not None  # the rectangle path is what this checks
        full = pyrender_picture(sr, cam, sr._full_camera())
        _agree(ours, full)
        if i == 0:  # the first frame with a camera is drawn whole, without a background
            assert sr._background is None
        else:
            x0, y0, w, h = window
            assert w * h < 0.7 * ours.shape[0] * ours.shape[1]
            outside = np.ones(ours.shape[:2], bool)
            outside[y0 : y0 + h, x0 : x0 + w] = False
            assert np.array_equal(ours[outside], sr._background[outside])


def test_render_does_not_load_pyrender(tmp_path, motions_dir):
    """``snapshot render FILE`` draws without pyrender, trimesh or networkx."""
    bvh = motions_dir / "walk_run/02_01.bvh"
    if not bvh.exists():
        pytest.skip("walk_run/02_01.bvh not in the shared data")
    out = tmp_path / "x.png"
    code = (
        "import sys\n"
        "from snapcore.cli.main import cli\n"
        f"cli.main(['render', {str(bvh)!r}, '-o', {str(out)!r}, '--size', '160x120'],"
        " standalone_mode=False)\n"
        "bad = [m for m in ('pyrender', 'trimesh', 'networkx') if m in sys.modules]\n"
        "print('LOADED', bad)\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "LOADED []" in res.stdout, res.stdout
    assert out.stat().st_size > 1000


def test_odd_sizes_and_the_face_id_pass_between_pictures(motions_dir):
    """An odd size (rows of 3 x 251 bytes: no padding may creep into the read-back)
    against pyrender, and the same picture again after the face-id pass has drawn in
    the same (bare) context: its GL state must not leak into the pictures."""
    from snapcore.render.bodies import posed_mesh
    from snapcore.render.buffers import render_face_ids
    from snapcore.render.gl import _THREAD, bare_gl_context, current_gl_context, release_renderer

    files, frame = SCENES["dance 05_06"]
    scene = _load(motions_dir, files)
    index = min(frame, scene.n_frames - 1)
    release_renderer()  # no pyrender renderer on this thread: one bare context for both
    sr = SceneRenderer(scene, size=(251, 167))
    cam = fit_camera(sr.body.vertices(index), [0.6, 0.45, 1.0], size=sr.size)
    first = sr.render(index, cam)
    assert getattr(_THREAD, "renderer", None) is None
    assert current_gl_context(8, 8) is bare_gl_context()  # the id pass draws in it too
    m = posed_mesh(scene, index, kind="human")
    ids = render_face_ids(m.vertices, m.faces, np.array([[0.0, 0.3, 1.0]]), resolution=64)
    assert (ids > 0).any()
    again = SceneRenderer(scene, size=(251, 167)).render(index, cam)
    assert np.array_equal(first, again)
    _agree(first, pyrender_picture(sr, cam, sr._full_camera()))
