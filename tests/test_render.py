"""Rendering checked by geometry: silhouettes, depth, face ids, framing, stills, threads."""

from __future__ import annotations

import subprocess
import sys
import threading

import numpy as np
import pytest
import trimesh

from snapcore.errors import RenderError
from snapcore.motion import synth
from snapcore.render.buffers import face_id_camera, render_depth, render_face_ids
from snapcore.render.camera import Camera, default_view, fit_camera, motion_points, view_basis
from snapcore.render.renderer import SceneRenderer, render_still

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def walk():
    return synth.synth_scene("walk", fps=30)


def _subdivided_cube(n=8, size=1.0):
    """A closed cube whose every side is an n×n grid of quads (2n² triangles a side)."""
    m = trimesh.creation.box(extents=[size] * 3)
    for _ in range(int(np.log2(n))):
        m = m.subdivide()
    return m


# ----------------------------------------------------------------------------- cameras


@pytest.mark.parametrize(
    "view", [[0, 0, 1], [1, 2, 3], [0, 1, 0], [0, -1, 0], [0, 1, 1e-9], [-1, 0, 0]]
)
def test_view_basis_is_right_handed_and_orthonormal(view):
    """right × up = view for every view, including straight up and down."""
    r, u, b = view_basis(view)
    m = np.stack([r, u, b])
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.cross(r, u), b, atol=1e-12)
    np.testing.assert_allclose(b, np.asarray(view) / np.linalg.norm(view), atol=1e-12)
    if abs(b[1]) < 0.99:
        assert u[1] > 0  # world up stays up in the picture


def test_view_basis_rejects_zero_view():
    with pytest.raises(RenderError):
        view_basis([0, 0, 0])


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_fit_camera_keeps_every_point_inside_the_margin(projection):
    """Points projected by hand (independent of Camera.project) land inside the image,
    and the fit is tight: some point touches the margin."""
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(500, 3)) * [1.0, 0.5, 2.0] + [3, 1, -2]
    view = np.array([0.4, 0.5, 0.75])
    w, h = 320, 200
    cam = fit_camera(pts, view, size=(w, h), projection=projection, margin=0.1)
    r, u, b = view_basis(view)
    rel = pts - cam.position
    if projection == "orthographic":
        x = (rel @ r) / (cam.half_height * w / h)
        y = (rel @ u) / cam.half_height
    else:
        z = -(rel @ b)
        assert z.min() > cam.znear
        t = np.tan(cam.yfov / 2)
        x = (rel @ r) / (z * t * w / h)
        y = (rel @ u) / (z * t)
    lim = 1 - 2 * 0.1
    assert np.abs(x).max() <= lim + 1e-9 and np.abs(y).max() <= lim + 1e-9
    assert max(np.abs(x).max(), np.abs(y).max()) > lim - 1e-6


# ----------------------------------------------------------------------------- face ids


def test_silhouette_area_of_a_cube_matches_the_analytic_area():
    """A unit cube's shadow along an axis is 1 m²; along the diagonal (1,1,1) it is √3 m²
    (½ Σ A_f |n_f·v|, three faces of 1 m² at cos = 1/√3 each, twice). Pixel count ×
    pixel area matches to 2 %."""
    m = _subdivided_cube(4)
    views = np.array([[0, 0, 1], [1, 1, 1] / np.sqrt(3)])
    res = 256
    ids = render_face_ids(m.vertices, m.faces, views, resolution=res)
    cam = face_id_camera(m.vertices, views[0], resolution=res)
    px = cam.pixel_size**2
    areas = (ids > 0).sum(axis=(1, 2)) * px
    np.testing.assert_allclose(areas, [1.0, np.sqrt(3)], rtol=0.02)


def test_face_ids_find_every_face_seen_head_on_and_nothing_else():
    """Seen along +Z, a subdivided cube shows exactly its 128 triangles facing +Z."""
    m = _subdivided_cube(8)
    ids = render_face_ids(m.vertices, m.faces, [0, 0, 1], resolution=256)
    seen = set(np.unique(ids[ids > 0]) - 1)
    front = set(np.flatnonzero(m.face_normals @ [0, 0, 1] > 0.999))
    assert len(front) == 128
    assert seen == front


def test_face_ids_name_only_front_faces_of_a_closed_mesh():
    """On a sphere seen from 12 directions, every named face faces the camera
    (n·v > 0): back faces never win, not even at the silhouette."""
    m = trimesh.creation.icosphere(subdivisions=4)
    views = trimesh.creation.icosahedron().vertices
    ids = render_face_ids(m.vertices, m.faces, views, resolution=128)
    for v, im in zip(views, ids):
        named = np.unique(im[im > 0]) - 1
        assert named.size > 100
        assert np.all(m.face_normals[named] @ v > 0)


def test_face_ids_are_exact_at_every_pixel():
    """No blended ids: each pixel's face contains the pixel centre (barycentric test in
    the image plane, computed here without the renderer), away from the edges."""
    m = _subdivided_cube(2)
    view = np.array([0.3, 0.5, 0.8])
    res = 96
    im = render_face_ids(m.vertices, m.faces, view, resolution=res)
    cam = face_id_camera(m.vertices, view, resolution=res)
    r, u, _ = view_basis(view)
    s = cam.pixel_size
    jj, ii = np.meshgrid(np.arange(res), np.arange(res))
    px = np.stack([(jj + 0.5 - res / 2) * s, (res / 2 - ii - 0.5) * s], -1) + [
        cam.position @ r,
        cam.position @ u,
    ]
    hit = im > 0
    assert im.max() <= len(m.faces)
    tri = m.vertices[m.faces[im[hit] - 1]]
    t2 = np.stack([tri @ r, tri @ u], -1)  # (P, 3, 2)
    p = px[hit]
    a, b, c = t2[:, 0], t2[:, 1], t2[:, 2]

    def cross(o, x, y):
        return (x[:, 0] - o[:, 0]) * (y[:, 1] - o[:, 1]) - (x[:, 1] - o[:, 1]) * (y[:, 0] - o[:, 0])

    d1, d2, d3 = cross(a, b, p), cross(b, c, p), cross(c, a, p)
    tol = 1e-9
    inside = ((d1 >= -tol) & (d2 >= -tol) & (d3 >= -tol)) | (
        (d1 <= tol) & (d2 <= tol) & (d3 <= tol)
    )
    assert inside.mean() > 0.995  # the rest sit exactly on shared edges


def test_face_ids_input_errors():
    with pytest.raises(RenderError):
        render_face_ids(np.zeros((3, 3)), np.array([[0, 1, 5]]), [0, 0, 1])
    with pytest.raises(RenderError):
        render_face_ids(np.zeros((3, 2)), np.array([[0, 1, 2]]), [0, 0, 1])


# ----------------------------------------------------------------------------- depth


def test_depth_at_the_centre_of_a_box_is_the_analytic_distance():
    """A 1 × 2 × 3 m box at the origin seen from +Z: the centre pixel hits the front face
    z = +1.5 m; depth + the front face's z equals the image plane's z; the box is 1 m
    wide in pixels × pixel size."""
    m = trimesh.creation.box(extents=[1.0, 2.0, 3.0])
    d = render_depth(m.vertices, m.faces, [0, 0, 1], resolution=200)
    h, w = d.shape
    centre = d.depth[h // 2, w // 2]
    assert abs(d.origin[2] - centre - 1.5) < 1e-9
    np.testing.assert_allclose(
        d.points()[h // 2, w // 2],
        [d.pixel_centers()[h // 2, w // 2, 0], d.pixel_centers()[h // 2, w // 2, 1], 1.5],
        atol=1e-9,
    )
    assert np.allclose(d.depth[d.mask], centre)  # a flat face: one depth everywhere
    assert abs(d.mask.any(axis=0).sum() * d.pixel_size - 1.0) <= 2 * d.pixel_size
    assert abs(d.mask.any(axis=1).sum() * d.pixel_size - 2.0) <= 2 * d.pixel_size
    np.testing.assert_allclose(d.forward, [0, 0, -1], atol=1e-12)
    assert np.isnan(d.depth[~d.mask]).all()


def test_depth_of_a_tilted_plane_is_exact():
    """A square tilted 30° about x seen from +Z: depth grows by tan 30° per metre of y."""
    a = np.radians(30)
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    v = v @ rot.T
    f = np.array([[0, 1, 2], [0, 2, 3]])
    d = render_depth(v, f, [0, 0, 1], resolution=128)
    pts = d.points()[d.mask]
    # every surface point lies on the plane (independent check: the plane's normal)
    n = rot @ [0, 0, 1]
    np.testing.assert_allclose(pts @ n, 0, atol=1e-9)
    rows = np.flatnonzero(d.mask[:, d.shape[1] // 2])
    col = d.depth[rows, d.shape[1] // 2]
    slope = np.polyfit(-(rows * d.pixel_size), col, 1)[0]  # image up = +y
    assert abs(slope - (-np.tan(a))) < 1e-9  # higher y = nearer (z grows with y)


def test_depth_extent_and_resolution_give_square_pixels():
    m = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    d = render_depth(m.vertices, m.faces, [0, 0, 1], resolution=(100, 50), extent=(2.0, 1.0))
    assert d.shape == (50, 100) and abs(d.pixel_size - 0.04) < 1e-12
    assert abs(d.mask.sum() * d.pixel_size**2 - 1.0) < 0.05


# ----------------------------------------------------------------------------- stills


def test_still_shows_the_body_where_the_camera_projects_it(walk):
    """The still's silhouette (pixels unlike the plain background, no floor) covers the
    projected joints and fills the projected bounding box of the body, computed here by
    hand from the camera basis."""
    from snapcore.render.bodies import scene_body  # the body the renderer draws
    from snapcore.render.renderer import BACKGROUND

    size = (200, 160)
    frame = 12
    view = np.array([0.6, 0.25, 0.76])
    verts = scene_body(walk).vertices(frame)
    cam = fit_camera(verts, view, size=size)
    img = render_still(walk, frame, camera=cam, ground=False, size=size)
    assert img.shape == (160, 200, 3) and img.dtype == np.uint8
    bg = np.round(np.asarray(BACKGROUND) * 255)
    sil = np.abs(img.astype(int) - bg).sum(axis=2) > 12
    r, u, _ = view_basis(view)
    rel = verts - cam.position
    x = ((rel @ r) / (cam.half_height * 200 / 160) + 1) * 100
    y = (1 - (rel @ u) / cam.half_height) * 80
    cols, rows = np.flatnonzero(sil.any(axis=0)), np.flatnonzero(sil.any(axis=1))
    assert abs(cols.min() - x.min()) <= 2 and abs(cols.max() + 1 - x.max()) <= 2
    assert abs(rows.min() - y.min()) <= 2 and abs(rows.max() + 1 - y.max()) <= 2
    # joints, not end sites: the human body has its own crown and fingertips, which need
    # not reach the BVH's Head_End / Hand_End markers
    ch = walk.characters[0]
    j = cam.project(ch.positions[frame][~ch.skeleton.end_site])
    inside = sil[np.clip(j[:, 1].astype(int), 0, 159), np.clip(j[:, 0].astype(int), 0, 199)]
    assert inside.mean() > 0.9


def test_still_of_two_people_shows_both_colours():
    """The push scene: both characters' colours appear in the picture."""
    from snapcore.render.mannequin import CHARACTER_COLORS

    scene = synth.synth_scene("push", fps=30)
    img = render_still(scene, 20, size=(240, 180)).astype(float) / 255
    for rgb in CHARACTER_COLORS[:2]:
        # lit colours keep the hue: look for pixels whose chromaticity matches
        c = np.asarray(rgb) / np.sum(rgb)
        chrom = img / np.maximum(img.sum(axis=2, keepdims=True), 1e-6)
        assert (np.abs(chrom - c).sum(axis=2) < 0.04).sum() > 200


def test_motion_framing_is_the_same_for_every_frame(walk):
    """With fit='motion' the camera does not depend on the frame, and every posed
    vertex of every frame is inside the picture."""
    pts = motion_points(walk)
    view = default_view(walk)
    cam = fit_camera(pts, view, size=(320, 180))
    from snapcore.render.bodies import scene_body  # the body the renderer draws

    allv = scene_body(walk).vertices(np.arange(walk.n_frames)).reshape(-1, 3)
    p = cam.project(allv)
    assert p[:, 0].min() >= 0 and p[:, 0].max() <= 320
    assert p[:, 1].min() >= 0 and p[:, 1].max() <= 180


def test_default_view_is_a_front_three_quarter_view(walk):
    """The synthetic walker faces +Z: the default view is in front (z > 0), turned
    sideways and slightly from above."""
    v = default_view(walk)
    assert abs(np.linalg.norm(v) - 1) < 1e-12
    assert v[2] > 0.6 and 0.1 < v[1] < 0.5 and abs(v[0]) > 0.3
    turned = default_view(walk.transformed(yaw_deg=90))
    np.testing.assert_allclose(turned, [v[2], v[1], -v[0]], atol=0.05)


def test_renderer_is_bound_to_its_thread_and_threads_get_their_own(walk):
    """A SceneRenderer refuses another thread; face ids in a worker thread (its own EGL
    context) equal those of the main thread."""
    sr = SceneRenderer(walk, size=(64, 64))
    cam = fit_camera(sr.body.vertices(0), [0, 0, 1], size=(64, 64))
    errors, results = [], {}

    def worker():
        try:
            sr.render(0, cam)
        except RenderError as err:
            errors.append(err)
        m = _subdivided_cube(2)
        results["ids"] = render_face_ids(m.vertices, m.faces, [1, 1, 1], resolution=64)

    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert errors and "thread" in str(errors[0])
    m = _subdivided_cube(2)
    np.testing.assert_array_equal(
        results["ids"], render_face_ids(m.vertices, m.faces, [1, 1, 1], resolution=64)
    )


def test_camera_project_matches_fit(walk):
    cam = Camera(
        np.array([0, 0, 5.0]),
        np.array([1.0, 0, 0]),
        np.array([0, 1.0, 0]),
        np.array([0, 0, 1.0]),
        (100, 50),
        "orthographic",
        half_height=1.0,
    )
    np.testing.assert_allclose(cam.project([[0, 0, 0], [2, 1, 0]]), [[50, 25], [100, 0]])


def test_level_orthographic_view_puts_the_horizon_at_the_feet(walk):
    """Seen exactly level, the floor is a line: the sky (background colour) ends and the
    floor colour begins at the row where the camera projects the floor (y = ground),
    computed here by hand; the lowest body pixels touch that row."""
    from snapcore.render.bodies import scene_body  # the body the renderer draws
    from snapcore.render.renderer import BACKGROUND, FLOOR_COLOR

    size = (160, 200)
    frame = 0
    view = np.array([1.0, 0.0, 0.0])
    verts = scene_body(walk).vertices(frame)
    cam = fit_camera(verts, view, size=size)
    img = render_still(walk, frame, camera=cam, size=size, shadows=False).astype(int)
    _, u, _ = view_basis(view)
    row = (1 - ((np.array([0, walk.ground, 0]) - cam.position) @ u) / cam.half_height) * 100
    sky = np.round(np.asarray(BACKGROUND) * 255)
    floor = np.round(np.asarray(FLOOR_COLOR) * 255)
    col = img[:, 3]  # a column far from the character
    is_sky = np.abs(col - sky).sum(axis=1) <= 3
    is_floor = np.abs(col - floor).sum(axis=1) <= 3
    first_floor = np.flatnonzero(is_floor)[0]
    assert abs(first_floor - row) <= 1.5
    assert is_sky[: int(row) - 1].all() and is_floor[int(row) + 2 :].all()
    body = np.abs(img - sky).sum(axis=2) > 12
    body &= np.abs(img - floor).sum(axis=2) > 12
    lowest = np.flatnonzero(body.any(axis=1)).max()
    assert abs(lowest - row) <= 4  # the feet stand on the floor line (their soles ~2 cm)


def test_release_renderer_makes_a_fresh_context():
    """release_renderer frees this thread's context (the old renderer holds no GL
    platform, the registry forgets it); the next call makes a live one that renders."""
    import threading

    from snapcore.render.gl import _RENDERERS, gl_renderer, release_renderer

    a = gl_renderer(32, 32)
    assert _RENDERERS[threading.current_thread()] is a and a._platform is not None
    release_renderer()
    assert a._platform is None and a._renderer is None  # its context was deleted
    assert threading.current_thread() not in _RENDERERS
    b = gl_renderer(32, 32)
    assert b._platform is not None and _RENDERERS[threading.current_thread()] is b
    m = _subdivided_cube(2)
    assert render_face_ids(m.vertices, m.faces, [0, 0, 1], resolution=32).max() > 0


def test_many_threads_render_and_finish_without_breaking_the_others(walk):
    """Worker threads each get a context, finish, and are cleaned up by later threads;
    the main thread's renderer keeps working throughout (EGL displays are shared)."""
    import gc

    m = _subdivided_cube(2)
    expect = render_face_ids(m.vertices, m.faces, [0.2, 1, 0.4], resolution=48)
    out = []

    def worker():
        out.append(render_face_ids(m.vertices, m.faces, [0.2, 1, 0.4], resolution=48))

    for _ in range(2):
        ts = [threading.Thread(target=worker) for _ in range(3)]
        for t in ts:
            t.start()
        for t in ts:
            t.join()
        gc.collect()
        np.testing.assert_array_equal(
            render_face_ids(m.vertices, m.faces, [0.2, 1, 0.4], resolution=48), expect
        )
    assert len(out) == 6 and all(np.array_equal(o, expect) for o in out)
    assert render_still(walk, 3, size=(64, 48)).std() > 3


def test_a_camera_under_the_floor_draws_no_grid_or_shadows(walk):
    """Seen from 9 degrees below the floor, the floor would hide the feet: neither its
    grid nor the shadows are drawn through the legs. With the floor on, the only pixels
    that differ from the background are the figure's (the same ones as with the floor
    off); from above, the grid and shadows are there."""
    from snapcore.render.renderer import BACKGROUND, FLOOR_COLOR, render_still

    def figure_mask(img, colour):
        return np.abs(img.astype(float) - np.round(np.asarray(colour) * 255)).max(axis=-1) > 3

    below = np.array([1.0, -0.16, 0.3]) / np.linalg.norm([1.0, -0.16, 0.3])
    with_floor = render_still(walk, 20, below, size=(96, 128))
    without = render_still(walk, 20, below, size=(96, 128), ground=False)
    a, b = figure_mask(with_floor, FLOOR_COLOR), figure_mask(without, BACKGROUND)
    assert 0.05 < b.mean() and (a != b).mean() < 0.002
    above = np.array([1.0, 0.5, 0.3]) / np.linalg.norm([1.0, 0.5, 0.3])
    a = figure_mask(render_still(walk, 20, above, size=(96, 128)), FLOOR_COLOR)
    b = figure_mask(render_still(walk, 20, above, size=(96, 128), ground=False), BACKGROUND)
    assert (a & ~b).mean() > 0.01  # grid lines and shadow around the figure


def test_a_cropped_render_is_the_full_render(walk):
    """Videos draw only the rectangle the bodies cover (a scissor in the full view) and
    paste it into the picture without them: every frame must be the full render, pixel
    for pixel, for a view from above, a level view with a horizon, a perspective view,
    and after the camera changes. A frame after the first with one camera takes that
    path without being asked (``crop`` only makes the first frame take it too)."""
    from dataclasses import replace

    from snapcore.render.renderer import CROP_MAX_AREA

    sr = SceneRenderer(walk, size=(640, 360))
    ref = SceneRenderer(walk, size=(640, 360))
    pts = motion_points(walk)
    cams = [fit_camera(pts, v, size=(640, 360)) for v in ([1.0, 0.8, 2.0], [0.3, 0.02, 1.0])]
    cams.append(fit_camera(pts, [1.0, 0.8, 2.0], size=(640, 360), projection="perspective"))
    for cam in cams:
        for i, f in enumerate((0, walk.n_frames // 2, walk.n_frames - 1)):
            full = ref.render(f, replace(cam))  # a new camera: drawn whole
            window = sr._crop_window(cam, [sr.body.vertices(f)])
            assert window is not None  # one walker fills far less than the frame
            x0, y0, cw, ch = window
            assert cw * ch <= CROP_MAX_AREA * 640 * 360
            cropped = sr.render(f, cam, crop=i == 0)
            assert sr._background is not None  # the rectangle path was taken
            assert np.array_equal(full, cropped), f
            # the body really is in the picture, not only in the background
            diff = np.abs(full.astype(int) - sr._background_image().astype(int)).max(-1)
            assert (diff > 30).sum() > 500
    # a perspective camera among the bodies sees some points beside or behind it
    eye = replace(cams[2], position=np.asarray(walk.characters[0].positions[0, 0], float))
    assert sr._crop_window(eye, [sr.body.vertices(0)]) is None


def test_the_crop_box_of_an_orthographic_view_is_the_projected_points_box():
    """The rectangle of a video frame comes from a float32 shortcut of the orthographic
    projection (``ortho_box``); it must hold every point ``Camera.project`` puts on the
    picture, to well within the rectangle's margin, also for points far from the origin
    (float32 keeps ~7 digits) and for views from below."""
    from snapcore.render.camera import ortho_box
    from snapcore.render.renderer import CROP_PAD_PX

    rng = np.random.default_rng(3)
    for shift, view in (
        (0.0, [1.0, 0.8, 2.0]),
        (0.0, [0.3, -0.6, -1.0]),
        (500.0, [-1.0, 0.2, 0.4]),
    ):
        parts = [
            (rng.normal(size=(5000, 3)) + shift).astype(np.float32),
            rng.normal(size=(700, 3)) * 0.5 + shift,  # float64, like the shadows
        ]
        cam = fit_camera(np.vstack(parts), view, size=(1280, 720))
        lo, hi = ortho_box(cam, parts)
        xy = cam.project(np.vstack([np.asarray(p, float) for p in parts]))
        assert np.abs(lo - xy.min(axis=0)).max() < 0.01 * CROP_PAD_PX
        assert np.abs(hi - xy.max(axis=0)).max() < 0.01 * CROP_PAD_PX


def test_pipelined_frames_are_the_frames_rendered_one_by_one(walk):
    """``render_frames`` (videos: a frame posed while the one before rasterises) gives
    each frame exactly as a renderer drawing it alone, across a camera change."""
    from dataclasses import replace

    pts = motion_points(walk)
    cams = [fit_camera(pts, v, size=(320, 180)) for v in ([1.0, 0.8, 2.0], [-1.0, 0.3, 0.5])]
    indices = [0, 7, walk.n_frames // 2, walk.n_frames - 1]
    sr, ref = SceneRenderer(walk, size=(320, 180)), SceneRenderer(walk, size=(320, 180))
    for cam in cams:
        frames = list(sr.render_frames(indices, cam))
        assert len(frames) == len(indices)
        for f, img in zip(indices, frames):
            assert np.array_equal(img, ref.render(f, replace(cam))), f
        assert not np.array_equal(frames[0], frames[-1])  # the walker moved


def _elevated(azimuth_deg, elevation_deg):
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.array([np.cos(e) * np.sin(a), np.sin(e), np.cos(e) * np.cos(a)])


def _panel_edges(img, n, size, strip=6):
    """Per-row mean colour (H, 3) of the left and right ``strip`` columns of each of the
    ``n`` panels of an unlabelled one-row sheet (panels at x = 8 + i (w + 8), y = 8):
    the background beside the pose, whatever is drawn there."""
    from snapcore.render.composites import PANEL_GAP

    w, h = size
    out = []
    for i in range(n):
        x = PANEL_GAP + i * (w + PANEL_GAP)
        p = img[PANEL_GAP : PANEL_GAP + h, x : x + w].astype(float)
        out.append(np.concatenate([p[:, :strip], p[:, -strip:]], axis=1).mean(axis=1))
    return out


def test_candidate_views_share_one_background(walk):
    """Three views of one pose, 25° above, 2° above and 8° below the horizon (the view
    selector may pick views down to 10° under it): every panel shows the floor the same
    way, a horizon at the same row with floor colour below and sky above, no grid (it
    showed a grid in one, a strip in one and nothing in the third). Views all well above
    the horizon keep the grid."""
    from snapcore.render.composites import compare_views
    from snapcore.render.renderer import BACKGROUND, FLOOR_COLOR

    size = (160, 200)
    views = {"a": _elevated(40, 25), "b": _elevated(100, 2), "c": _elevated(-30, -8)}
    img = compare_views(walk, 40, views, size=size, labels=False)
    edges = _panel_edges(img, 3, size)
    for e in edges[1:]:
        assert np.abs(e - edges[0]).max() < 3.0  # the same background row by row
    sky = np.abs(edges[0] - np.array(BACKGROUND) * 255).max(axis=1) < 3
    floor = np.abs(edges[0] - np.array(FLOOR_COLOR) * 255).max(axis=1) < 3
    assert (~(sky | floor)).sum() <= 2  # sky, floor and the anti-aliased horizon only
    assert floor[-1] and sky[0] and floor.sum() > 5  # the horizon is in the picture
    above = compare_views(
        walk, 40, {"a": _elevated(40, 25), "b": _elevated(100, 35)}, size=size, labels=False
    )
    from snapcore.render.composites import PANEL_GAP
    from snapcore.render.renderer import GRID_COLOR

    w, h = size
    for i in range(2):  # grid lines in the far floor (the top quarter, above any shadow)
        x = PANEL_GAP + i * (w + PANEL_GAP)
        top = above[PANEL_GAP : PANEL_GAP + h // 4, x : x + w].astype(float)
        lines = np.abs(top - np.array(GRID_COLOR) * 255).max(axis=-1) < 25
        assert lines.sum() > 20, f"panel {i}: no grid"


def test_views_are_keyed_by_the_method_and_labelled_only_on_the_picture(walk):
    """pipeline_picks keys its views by ViewMethod (no display labels in the data), and
    compare_views draws an enum key under its label: the same pixels as the label
    written out as a free-form name, different from the stored identifier."""
    from snapcore.cli.render import pipeline_picks
    from snapcore.render.composites import compare_views
    from snapcore.select.view_methods import ViewMethod, view_label

    picks = pipeline_picks(walk, k=1, baselines=False)
    assert list(picks["views"]) == [ViewMethod.OURS]
    v = picks["views"][ViewMethod.OURS]
    by_enum = compare_views(walk, 40, {ViewMethod.MOTION_AREA: v}, size=(120, 140))
    by_label = compare_views(walk, 40, {"motion area": v}, size=(120, 140))
    by_value = compare_views(walk, 40, {"motion_area": v}, size=(120, 140))
    assert view_label(ViewMethod.MOTION_AREA) == "motion area"
    assert np.array_equal(by_enum, by_label)
    assert not np.array_equal(by_enum, by_value)  # the caption text differs


def test_the_body_option_reaches_the_picture_and_stays_out_of_the_scene(
    motions_dir, tmp_path, monkeypatch
):
    """`snapshot render --body mannequin` and `--body human` draw different pictures,
    each the one `render_still(..., body=...)` gives; the loaded scene is not told."""
    from click.testing import CliRunner
    from PIL import Image

    import snapcore.cli.render as cli_render
    from snapcore.cli.main import cli

    loaded = []
    load = cli_render.scene_from_options

    def spy(*args, **kwargs):
        loaded.append(load(*args, **kwargs))
        return loaded[-1]

    monkeypatch.setattr(cli_render, "scene_from_options", spy)
    clip = str(motions_dir / "walk_run" / "02_01.bvh")
    pictures = {}
    for body in ("mannequin", "human"):
        out = tmp_path / f"{body}.png"
        args = ["render", clip, "--body", body, "--frame", "40", "--view", "1,0.3,0.5"]
        res = CliRunner().invoke(cli, [*args, "--size", "160x120", "-o", str(out)])
        assert res.exit_code == 0, res.output
        pictures[body] = np.asarray(Image.open(out).convert("RGB")).astype(int)
        scene = loaded[-1]
        assert "body" not in scene.meta
        expected = render_still(
            scene, scene.internal_frame(40), [1, 0.3, 0.5], size=(160, 120), body=body
        )
        assert np.abs(pictures[body] - expected).max() <= 1
    assert np.abs(pictures["human"] - pictures["mannequin"]).mean() > 1.0


def test_an_unknown_body_kind_is_refused_naming_the_kinds(walk):
    """A typo in the body kind fails at once, naming the kinds (no silent default)."""
    from snapcore.errors import SceneError
    from snapcore.pipeline import ViewParams

    with pytest.raises(SceneError, match="human, mannequin.*'dummy'"):
        render_still(walk, 0, size=(64, 48), body="dummy")  # type: ignore[arg-type]
    with pytest.raises(SceneError, match="human, mannequin"):
        ViewParams(body="dummy")  # type: ignore[arg-type]


def test_a_long_sheet_title_is_wrapped_not_cut_off():
    """A title wider than the sheet (issue 40: a long ``sheet --title`` was cut at the
    right edge) is drawn whole: its ink, counted over the title band, is the same as
    the same title drawn on one line of a wide canvas in the same font, and no ink
    reaches the sheet's right margin."""
    from PIL import Image, ImageDraw

    from snapcore.render.composites import _INK, _PAPER, PANEL_GAP, _font, tile_panels

    panels = [np.full((120, 160, 3), 200, np.uint8)] * 2
    title = "A very long title for a comparison sheet of two dancers " * 3
    sheet = tile_panels(panels, title=title).astype(int)
    band = sheet[: sheet.shape[0] - 120 - 2 * PANEL_GAP]  # above the panels
    ink = band.sum(axis=-1) < 3 * 128
    assert not ink[:, -PANEL_GAP:].any(), "the title runs into the right margin"
    font = _font(int(max(int(120 * 0.045), 11) * 1.2))
    canvas = Image.new("RGB", (int(font.getlength(title)) + 40, 60), _PAPER)
    ImageDraw.Draw(canvas).text((10, 30), title, fill=_INK, font=font, anchor="lm")
    want = int((np.asarray(canvas).astype(int).sum(axis=-1) < 3 * 128).sum())
    assert abs(int(ink.sum()) - want) <= 0.03 * want, (int(ink.sum()), want)


def test_makehuman_dresses_a_skeleton_that_carries_its_own_mesh():
    """``body="makehuman"`` (``--body makehuman``) puts the MakeHuman body on a character
    that carries its own skinned mesh, where ``"human"`` draws that mesh (issue 40: no
    option dressed a glTF skeleton in the MakeHuman body); a BVH skeleton wears the
    MakeHuman body either way."""
    import dataclasses

    from scipy import sparse

    from snapcore.motion.skinning import SkinnedMesh
    from snapcore.motion.synth import synth_scene
    from snapcore.render.bodies import SkinnedBody, character_body
    from snapcore.render.human import HumanBody

    bvh = synth_scene("walk").characters[0]
    own = SkinnedMesh(  # one triangle on the root: a character's own mesh
        rest=np.eye(3),
        faces=np.array([[0, 1, 2]]),
        weights=sparse.csr_matrix(np.ones((3, 1))),
        slot_joint=np.array([0]),
        inverse_bind=np.eye(4)[None],
        joint_scale=np.ones(len(bvh.joint_names)),
    )
    dressed = dataclasses.replace(bvh, mesh=own)
    assert isinstance(character_body(dressed, kind="human"), SkinnedBody)
    assert isinstance(character_body(dressed, kind="makehuman"), HumanBody)
    assert isinstance(character_body(bvh, kind="makehuman"), HumanBody)
    assert isinstance(character_body(bvh, kind="human"), HumanBody)


def test_body_pictures_name_a_gltf_characters_own_mesh(motions_dir):
    """The README's body pictures caption a glTF character's own mesh as its own, not
    "human body" (issue 40: docs/images/body_gltf.png said "human body" under the
    BrainStem robot); a BVH skeleton's is the human body."""
    import warnings

    from snapcore.cli.readme_images import body_caption
    from snapcore.motion.load import load_scene
    from snapcore.motion.synth import synth_scene

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gltf = load_scene(motions_dir / "gltf" / "CesiumMan.glb")
    assert body_caption(gltf, "human") == "its own mesh"
    assert body_caption(synth_scene("walk"), "human") == "human body"
    assert body_caption(gltf, "makehuman") == "human body"
    assert body_caption(gltf, "mannequin") == "mannequin"


def test_gl_matrices_equal_pyrender_s_bit_for_bit():
    """The face-id pass computes its view and projection matrices without pyrender: they
    must equal pyrender's (a scene node's pose, the camera's projection) exactly, or ids
    at face edges would change."""
    import pyrender

    from snapcore.render.camera import Camera, gl_camera_pose, gl_projection, view_basis

    rng = np.random.default_rng(7)
    for i in range(400):
        v = rng.normal(size=3)
        if i % 10 == 0:  # near the poles, where view_basis switches its reference axis
            v = np.array([0.0, rng.choice([-1.0, 1.0]), 0.0]) + rng.normal(size=3) * 1e-9
        right, up, back = view_basis(v / np.linalg.norm(v))
        size = (int(rng.integers(1, 2000)), int(rng.integers(1, 2000)))
        cam = Camera(
            rng.normal(size=3) * 5,
            right,
            up,
            back,
            size,
            "orthographic" if i % 2 else "perspective",
            half_height=float(rng.uniform(0.1, 5)),
            yfov=float(rng.uniform(0.2, 2)),
            znear=float(rng.uniform(0.01, 1)),
            zfar=float(rng.uniform(2, 100)),
        )
        assert np.array_equal(gl_camera_pose(cam), pyrender.Node(matrix=cam.pose).matrix)
        expected = cam.pyrender_camera().get_projection_matrix(width=size[0], height=size[1])
        assert np.array_equal(gl_projection(cam), expected)


def test_release_renderer_frees_the_bare_id_context():
    """Without a pyrender renderer on the thread, the id pass runs in a bare EGL context;
    release_renderer frees it and the next pass makes a new one that still draws."""
    import threading

    from snapcore.render import gl
    from snapcore.render.buffers import render_face_ids

    def work(box):
        tri = (np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
        a = render_face_ids(*tri, [[0.0, 0.0, 1.0]], resolution=16)
        box["ctx"] = gl._THREAD.raw_context
        box["registered"] = gl._RAW_CONTEXTS.get(threading.current_thread()) is box["ctx"]
        gl.release_renderer()
        box["released"] = getattr(gl._THREAD, "raw_context", None) is None
        b = render_face_ids(*tri, [[0.0, 0.0, 1.0]], resolution=16)
        box["fresh"] = gl._THREAD.raw_context is not box["ctx"]
        box["same_ids"] = np.array_equal(a, b) and (np.asarray(a) == 1).any()
        gl.release_renderer()

    box: dict = {}
    t = threading.Thread(target=work, args=(box,))  # a thread without a pyrender renderer
    t.start()
    t.join()
    assert box == {**box, "registered": True, "released": True, "fresh": True, "same_ids": True}


def test_pyrender_loads_without_its_interactive_viewer():
    """load_pyrender gives a working pyrender without importing pyglet, tkinter or
    imageio (its viewer's imports: start-up time of ``snapshot render``)."""
    code = (
        "import sys\n"
        "from snapcore.render.gl import load_pyrender\n"
        "pyrender = load_pyrender()\n"
        "assert pyrender.OffscreenRenderer and pyrender.Scene and pyrender.Mesh\n"
        "print([m for m in ('pyglet', 'tkinter', 'imageio') if m in sys.modules])\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "[]"
